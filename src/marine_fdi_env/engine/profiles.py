"""Operating profiles: the fuel setting u(t) as a piecewise-linear function of time.

A profile is a list of breakpoints ``(t_i, u_i)``; between breakpoints u is linear, and two
breakpoints at the same time make a step (u is right-continuous).  The fixed-step solver is exact
for u linear between samples, so step times are rounded to the sample grid by the simulator.

Named profiles (``make_profile``), with optional ``key=value`` overrides, e.g.
``step:u0=0.8,u1=1.0,t=100``:

``constant``     u = u0 (default 1.0), as in the thesis.
``step``         u0 -> u1 at t (defaults 0.8 -> 1.0 at 100 s).
``ramp``         u0 -> u1 linearly between t0 and t1 (defaults 0.6 -> 1.0, 50 s -> 150 s).
``manoeuvring``  a harbour-manoeuvring sequence: full ahead, slow down, dead slow, half ahead,
                 full ahead (ramps at 2 %/s, a governor-like rate limit), repeating every 300 s.
``random``       seeded random piecewise-linear setpoints (``seed``, ``u_min``, ``u_max``,
                 ``dwell`` mean seconds between setpoint changes, ``rate`` limit per second).
``harbour``      harbour manoeuvring as random engine-telegraph orders: seeded steps between the
                 telegraph levels (dead slow 0.3, slow 0.45, half 0.6, full 0.8, navigation full
                 1.0) that lie in [``u_min``, ``u_max``], held ``dwell`` seconds on average
                 (exponential, at least 5 s), each reached at ``rate`` per second (default 0.1/s:
                 five times the governor rate of ``manoeuvring`` and ``random``).
``seastate``     sea-state load fluctuation around a mean: u = ``u_mean`` (1 + e(t)), e the sum of
                 five seeded sinusoids with periods in [0.6, 1.6] x ``period`` s (wave encounter)
                 and random phases, scaled to peak relative amplitude ``amplitude``; breakpoints
                 every 0.5 s.
``slowsteaming`` slow-speed steaming at part load in a seaway: u = m(t) (1 + e(t)), the mean m(t)
                 moving linearly from ``u_mean`` (1 - ``drift``) to ``u_mean`` (1 + ``drift``) over
                 the run (speed adjustments; ``drift`` may be negative) and e(t) the waves of
                 ``seastate`` (peak relative ``amplitude``, ``period``); breakpoints every 0.5 s.

``harbour`` and ``seastate`` belong to the ``transfer-v2`` suite only, ``slowsteaming`` to
``transfer-v3`` only: no scenario preset and no training configuration draws them (tested).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._jit import jit
from .steady_state import check_fuel_setting

__all__ = ["Profile", "make_profile", "PROFILE_NAMES", "ProfileTable"]

PROFILE_NAMES = ("constant", "step", "ramp", "manoeuvring", "random", "harbour", "seastate", "slowsteaming")
TELEGRAPH_LEVELS = (0.3, 0.45, 0.6, 0.8, 1.0)  # dead slow, slow, half, full, navigation full


@dataclass(frozen=True)
class Profile:
    """Piecewise-linear fuel setting; ``times`` non-decreasing, ``values`` in [0, 1.2]."""

    name: str
    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        if len(t) == 0 or len(t) != len(self.values):
            raise ValueError("profile needs equally many breakpoint times and values (at least one)")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or t[0] < 0:
            raise ValueError(f"profile {self.name!r}: breakpoint times must be finite, >= 0 and non-decreasing")
        check_fuel_setting(self.values, f"profile {self.name!r} fuel_setting")

    @cached_property
    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.times, dtype=float), np.asarray(self.values, dtype=float)

    def __call__(self, t) -> np.ndarray:
        """u at time(s) t (right-continuous at steps)."""
        t = np.asarray(t, dtype=float)
        times, vals = self._arrays
        # right-continuity: among equal times take the last value
        idx = np.searchsorted(times, t, side="right")
        last = len(times) - 1
        left = np.maximum(np.minimum(idx - 1, last), 0)
        right = np.minimum(idx, last)
        t0, t1 = times[left], times[right]
        v0, v1 = vals[left], vals[right]
        dt = t1 - t0
        w = np.where(dt > 0, (t - t0) / np.where(dt > 0, dt, 1.0), 0.0)
        return np.where(t < times[0], vals[0], v0 + np.minimum(np.maximum(w, 0.0), 1.0) * (v1 - v0))

    def left_limit(self, t) -> np.ndarray:
        """u just before time(s) t (differs from ``self(t)`` only at a step)."""
        t = np.asarray(t, dtype=float)
        times, vals = self._arrays
        idx = np.searchsorted(times, t, side="left")
        j = np.minimum(idx, len(times) - 1)
        # the segment that ends at a breakpoint ends at the value of its first occurrence
        at_break = (idx < len(times)) & (times[j] == t)
        return np.where(at_break, vals[j], self(t))

    @property
    def breakpoints(self) -> np.ndarray:
        return np.unique(np.asarray(self.times, dtype=float))

    def snapped(self, dt: float) -> "Profile":
        """Breakpoints rounded to multiples of dt (so steps fall on sample instants)."""
        t = tuple(float(np.round(x / dt) * dt) for x in self.times)
        return Profile(self.name, t, self.values)

    def to_dict(self) -> dict:
        return {"name": self.name, "times": list(self.times), "values": list(self.values)}


@jit
def _value_right(times, vals, L, t):
    """:meth:`Profile.__call__` at one time, same operations (right-continuous)."""
    lo, hi = 0, L  # searchsorted(times[:L], t, side="right")
    while lo < hi:
        mid = (lo + hi) // 2
        if times[mid] <= t:
            lo = mid + 1
        else:
            hi = mid
    last = L - 1
    left = max(min(lo - 1, last), 0)
    right = min(lo, last)
    t0, t1 = times[left], times[right]
    v0, v1 = vals[left], vals[right]
    dt = t1 - t0
    w = (t - t0) / dt if dt > 0 else 0.0
    if t < times[0]:
        return vals[0]
    return v0 + min(max(w, 0.0), 1.0) * (v1 - v0)


@jit
def _table_values(t, times, vals, lens, engines, u_right, u_left):
    """u (right limits) and left limits at times t[:, j] of the profile of engine engines[j]."""
    for jj in range(len(engines)):
        e = engines[jj]
        L = lens[e]
        for r in range(t.shape[0]):
            tt = t[r, jj]
            u = _value_right(times[e], vals[e], L, tt)
            u_right[r, jj] = u
            lo, hi = 0, L  # searchsorted(times[:L], t, side="left")
            while lo < hi:
                mid = (lo + hi) // 2
                if times[e, mid] < tt:
                    lo = mid + 1
                else:
                    hi = mid
            j = min(lo, L - 1)
            u_left[r, jj] = vals[e, j] if (lo < L and times[e, j] == tt) else u


class ProfileTable:
    """The profiles of N engines as padded breakpoint arrays, evaluated in one compiled call
    (equal, bit for bit, to :meth:`Profile.__call__` and :meth:`Profile.left_limit`; tested)."""

    def __init__(self, profiles: list[Profile]) -> None:
        self.n = len(profiles)
        width = max(len(p.times) for p in profiles)
        self.times = np.zeros((self.n, width))
        self.vals = np.zeros((self.n, width))
        self.lens = np.zeros(self.n, dtype=np.int64)
        for i, p in enumerate(profiles):
            self.set(i, p)

    def set(self, i: int, profile: Profile) -> None:
        """Replace engine i's profile (the padding grows if needed)."""
        m = len(profile.times)
        if m > self.times.shape[1]:
            pad = m - self.times.shape[1]
            self.times = np.pad(self.times, ((0, 0), (0, pad)))
            self.vals = np.pad(self.vals, ((0, 0), (0, pad)))
        times, vals = profile._arrays
        self.times[i, :m] = times
        self.vals[i, :m] = vals
        self.lens[i] = m

    def values(self, t: np.ndarray, engines: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(u, left limits of u) at times t (rows, len(engines)) of the engines (default all)."""
        engines = np.arange(self.n, dtype=np.int64) if engines is None else np.asarray(engines, dtype=np.int64)
        t = np.ascontiguousarray(t, dtype=np.float64)
        u_right = np.empty(t.shape)
        u_left = np.empty(t.shape)
        _table_values(t, self.times, self.vals, self.lens, engines, u_right, u_left)
        return u_right, u_left


def _opts(text: str) -> tuple[str, dict[str, float]]:
    name, _, rest = text.partition(":")
    opts = {}
    for item in filter(None, rest.split(",")):
        k, eq, v = item.partition("=")
        if not eq:
            raise ValueError(f"profile option {item!r} must be key=value")
        try:
            opts[k.strip()] = float(v)
        except ValueError:
            raise ValueError(f"profile option {k!r}: {v!r} is not a number") from None
    return name.strip(), opts


def make_profile(spec: "str | Profile | float", duration_s: float = 300.0) -> Profile:
    """Build a profile from a name with options (module docstring), a constant or a Profile."""
    if isinstance(spec, Profile):
        return spec
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        return Profile("constant", (0.0,), (float(spec),))
    if not isinstance(spec, str):
        raise ValueError(f"profile must be a name, a number or a Profile, got {spec!r}")
    name, o = _opts(spec)
    allowed = {
        "constant": {"u0"},
        "step": {"u0", "u1", "t"},
        "ramp": {"u0", "u1", "t0", "t1"},
        "manoeuvring": {"scale"},
        "random": {"seed", "u_min", "u_max", "dwell", "rate"},
        "harbour": {"seed", "u_min", "u_max", "dwell", "rate"},
        "seastate": {"seed", "u_mean", "amplitude", "period"},
        "slowsteaming": {"seed", "u_mean", "drift", "amplitude", "period"},
    }
    if name not in allowed:
        raise ValueError(f"unknown profile {name!r}; allowed: {', '.join(PROFILE_NAMES)}")
    bad = set(o) - allowed[name]
    if bad:
        raise ValueError(f"profile {name!r} does not take {sorted(bad)}; allowed options: {sorted(allowed[name])}")
    if name == "constant":
        return Profile(name, (0.0,), (o.get("u0", 1.0),))
    if name == "step":
        t = o.get("t", 100.0)
        return Profile(name, (0.0, t, t), (o.get("u0", 0.8), o.get("u0", 0.8), o.get("u1", 1.0)))
    if name == "ramp":
        t0, t1 = o.get("t0", 50.0), o.get("t1", 150.0)
        if t1 < t0:
            raise ValueError("profile 'ramp': t1 must not precede t0")
        return Profile(name, (0.0, t0, t1), (o.get("u0", 0.6), o.get("u0", 0.6), o.get("u1", 1.0)))
    if name == "manoeuvring":
        s = o.get("scale", 1.0)
        setpoints = [
            (0, 1.0),
            (40, 1.0),
            (65, 0.5),
            (110, 0.5),
            (125, 0.3),
            (170, 0.3),
            (190, 0.7),
            (240, 0.7),
            (255, 1.0),
            (300, 1.0),
        ]
        times, vals = [], []
        period = 300.0
        k = 0
        while True:
            for t, v in setpoints:
                tt = k * period + t
                if times and tt <= times[-1]:
                    continue
                times.append(tt)
                vals.append(min(v * s, 1.2))
            k += 1
            if k * period > duration_s:
                break
        return Profile(name, tuple(float(x) for x in times), tuple(vals))
    if name == "harbour":
        return _harbour(o, duration_s)
    if name == "seastate":
        return _seastate(o, duration_s)
    if name == "slowsteaming":
        return _slowsteaming(o, duration_s)
    # random
    rng = np.random.default_rng(int(o.get("seed", 0)))
    lo, hi = o.get("u_min", 0.4), o.get("u_max", 1.05)
    dwell, rate = o.get("dwell", 40.0), o.get("rate", 0.02)
    t, u = 0.0, float(rng.uniform(lo, hi))
    times, vals = [0.0], [u]
    while t < duration_s:
        t += float(rng.exponential(dwell))
        times.append(t)
        vals.append(u)
        u_new = float(rng.uniform(lo, hi))
        t += abs(u_new - u) / rate
        u = u_new
        times.append(t)
        vals.append(u)
    return Profile(name, tuple(times), tuple(vals))


def _harbour(o: dict[str, float], duration_s: float) -> Profile:
    """Random engine-telegraph orders (module docstring, ``harbour``)."""
    rng = np.random.default_rng(int(o.get("seed", 0)))
    lo, hi = o.get("u_min", 0.3), o.get("u_max", 1.0)
    dwell, rate = o.get("dwell", 30.0), o.get("rate", 0.1)
    levels = [v for v in TELEGRAPH_LEVELS if lo - 1e-9 <= v <= hi + 1e-9]
    if len(levels) < 2 or rate <= 0 or dwell <= 0:
        raise ValueError(
            f"profile 'harbour' needs at least two telegraph levels {TELEGRAPH_LEVELS} in "
            f"[u_min, u_max] = [{lo}, {hi}] and dwell, rate > 0"
        )
    u = float(levels[int(rng.integers(len(levels)))])
    t, times, vals = 0.0, [0.0], [u]
    while t < duration_s:
        t += max(5.0, float(rng.exponential(dwell)))
        times.append(t)
        vals.append(u)
        u_new = float(rng.choice([v for v in levels if v != u]))
        t += abs(u_new - u) / rate
        u = u_new
        times.append(t)
        vals.append(u)
    return Profile("harbour", tuple(times), tuple(vals))


def _waves(rng: np.random.Generator, amp: float, period: float, t: np.ndarray, name: str) -> np.ndarray:
    """Relative wave load e(t): five seeded sinusoids, periods in [0.6, 1.6] x ``period``, peak ``amp``."""
    if period <= 0 or not 0 <= amp < 1:
        raise ValueError(f"profile {name!r} needs period > 0 and 0 <= amplitude < 1, got {period}, {amp}")
    periods = rng.uniform(0.6, 1.6, size=5) * period
    phases = rng.uniform(0.0, 2 * np.pi, size=5)
    weights = rng.uniform(0.5, 1.0, size=5)
    e = (weights[:, None] * np.sin(2 * np.pi * t[None, :] / periods[:, None] + phases[:, None])).sum(axis=0)
    return e * (amp / weights.sum())


def _seastate(o: dict[str, float], duration_s: float) -> Profile:
    """Wave-induced load fluctuation around a mean (module docstring, ``seastate``)."""
    rng = np.random.default_rng(int(o.get("seed", 0)))
    mean, amp, period = o.get("u_mean", 0.8), o.get("amplitude", 0.05), o.get("period", 9.0)
    t = np.arange(0.0, duration_s + 0.5, 0.5)
    e = _waves(rng, amp, period, t, "seastate")
    return Profile("seastate", tuple(float(x) for x in t), tuple(float(x) for x in mean * (1.0 + e)))


def _slowsteaming(o: dict[str, float], duration_s: float) -> Profile:
    """Part-load steaming with a drifting mean and waves (module docstring, ``slowsteaming``)."""
    rng = np.random.default_rng(int(o.get("seed", 0)))
    mean, drift = o.get("u_mean", 0.4), o.get("drift", 0.0)
    amp, period = o.get("amplitude", 0.08), o.get("period", 9.0)
    if not abs(drift) < 1:
        raise ValueError(f"profile 'slowsteaming' needs -1 < drift < 1, got {drift}")
    t = np.arange(0.0, duration_s + 0.5, 0.5)
    level = mean * (1.0 + drift * (2.0 * t / max(duration_s, 1e-9) - 1.0))
    e = _waves(rng, amp, period, t, "slowsteaming")
    return Profile("slowsteaming", tuple(float(x) for x in t), tuple(float(x) for x in level * (1.0 + e)))
