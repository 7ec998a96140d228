"""Episodes of ``MarineFDI-v0``: a concrete scenario (:class:`ScenarioSpec`) and the documented
distribution they are drawn from (:class:`ScenarioConfig`, with named presets).

Sampling (:meth:`ScenarioConfig.sample`) takes one integer of entropy (the environment draws it
from ``self.np_random``) and spawns one :class:`numpy.random.SeedSequence` child per random
component, in this fixed order:

====  ==============  ==========================================================
 #    component       draws
====  ==============  ==========================================================
 0    profile         profile family and its parameters (fuel settings, times)
 1    fault count     0, 1 or 2 faults
 2    fault ids       which faults (without replacement)
 3    sensor kind     offset / drift / stuck / gain / precision per sensor fault
 4    onsets          onset of the first fault, gap to the second
 5    magnitudes      magnitude relative to the detectability limit, and its sign
 6    noise           the seed of the sensor-noise stream
====  ==============  ==========================================================

so changing how one component is drawn (say, the profile families) leaves every other component
of every episode unchanged.

Magnitudes are drawn log-uniformly in ``magnitude_range`` times the fault's *detectability
limit* (:mod:`marine_fdi_env.envs.detectability`: the smallest magnitude the reference diagnoser
detects within the run at nominal load, floored at 2 % of the thesis table magnitude; see
``sampling_scale``), so "1.0" means "just detectable by the reference" for every fault, whatever
its unit.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from ..engine.faults import FAULT_IDS, PROCESS_FAULT_IDS, SENSOR_FAULT_KINDS, FaultSpec, fault_class
from ..engine.profiles import make_profile
from ..engine.sensors import SENSOR_IDS

__all__ = [
    "ScenarioSpec",
    "ScenarioConfig",
    "PRESETS",
    "get_preset",
    "with_noise_scale",
    "SAMPLER_COMPONENTS",
    "SAMPLER_PROFILES",
    "HELD_OUT_PROFILES",
    "fault_at_scale",
]

# the profile families a ScenarioConfig can draw; ``harbour`` and ``seastate`` are held out for the
# transfer-v2 suite, ``slowsteaming`` for transfer-v3 (built by their own code in
# :mod:`marine_fdi_env.benchmark.suites`), so no training configuration can draw them
SAMPLER_PROFILES = ("constant", "step", "ramp", "random", "manoeuvring")
HELD_OUT_PROFILES = ("harbour", "seastate", "slowsteaming")

SAMPLER_COMPONENTS = ("profile", "fault_count", "fault_ids", "sensor_kind", "onsets", "magnitudes", "noise")
_MAX_SEED = 2**63 - 1


def _fault_to_dict(f: FaultSpec) -> dict:
    d = {"fault_id": f.fault_id, "onset_s": float(f.onset_s)}
    for k in ("magnitude", "kind", "kappa", "end_s", "period_s", "duty"):
        v = getattr(f, k)
        if v is not None:
            d[k] = v
    return d


def _fault_from(obj) -> FaultSpec:
    if isinstance(obj, FaultSpec):
        return obj
    if isinstance(obj, str):
        from ..engine.faults import parse_fault_spec

        return parse_fault_spec(obj)
    if isinstance(obj, dict):
        allowed = {"fault_id", "onset_s", "magnitude", "kind", "kappa", "end_s", "period_s", "duty"}
        bad = set(obj) - allowed - {"class"}
        if bad:
            raise ValueError(f"scenario field 'faults': unknown keys {sorted(bad)}; allowed: {sorted(allowed)}")
        if "fault_id" not in obj or "onset_s" not in obj:
            raise ValueError("scenario field 'faults': every fault needs 'fault_id' and 'onset_s'")
        kw = {k: obj[k] for k in allowed if k in obj}
        if kw.get("kind") == "process":
            kw.pop("kind")
        return FaultSpec(**kw)
    raise ValueError(f"scenario field 'faults': a fault must be a FaultSpec, a spec string or a dict, got {obj!r}")


@dataclass(frozen=True)
class ScenarioSpec:
    """One episode: fault schedule, fuel-setting profile, noise.

    faults : scheduled faults (at most one per fault id; onsets before ``duration_s``).
    profile : fuel-setting profile spec (:func:`marine_fdi_env.engine.profiles.make_profile`).
    noise_seed : seed of the engine's sensor-noise stream.
    noise_scale : multiplier of the table 6.3 noise bounds.
    duration_s : episode length [s].
    scenario_id : a name (suites use it as the key of a result).
    magnitude_scales : magnitude of each fault relative to its detectability limit (information).
    """

    faults: tuple[FaultSpec, ...] = ()
    profile: str = "constant"
    noise_seed: int = 0
    noise_scale: float = 1.0
    duration_s: float = 300.0
    scenario_id: str = ""
    magnitude_scales: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        faults = tuple(_fault_from(f) for f in _as_tuple("scenario", "faults", self.faults))
        object.__setattr__(self, "faults", faults)
        object.__setattr__(self, "magnitude_scales", _as_tuple("scenario", "magnitude_scales", self.magnitude_scales))
        if not (isinstance(self.duration_s, (int, float)) and math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(
                f"scenario field 'duration_s' must be a positive number of seconds, got {self.duration_s!r}"
            )
        if not (
            isinstance(self.noise_scale, (int, float)) and math.isfinite(self.noise_scale) and self.noise_scale >= 0
        ):
            raise ValueError(f"scenario field 'noise_scale' must be a finite number >= 0, got {self.noise_scale!r}")
        if (
            not isinstance(self.noise_seed, (int, np.integer))
            or isinstance(self.noise_seed, bool)
            or not 0 <= int(self.noise_seed) <= _MAX_SEED
        ):
            raise ValueError(f"scenario field 'noise_seed' must be an integer in [0, 2**63), got {self.noise_seed!r}")
        ids = [f.fault_id for f in faults]
        if len(set(ids)) != len(ids):
            raise ValueError(f"scenario field 'faults': each fault id at most once, got {ids}")
        for f in faults:
            if f.onset_s >= self.duration_s:
                raise ValueError(
                    f"scenario field 'faults': onset of {f.fault_id} ({f.onset_s} s) must be before "
                    f"the end of the episode ({self.duration_s} s)"
                )
        make_profile(self.profile, self.duration_s)  # raises ValueError for a bad profile

    @property
    def fault_ids(self) -> tuple[str, ...]:
        return tuple(f.fault_id for f in self.faults)

    def truth(self) -> list[dict]:
        """Ground truth in the metrics' record format (id, class, onset, magnitude, end)."""
        return [
            {
                "id": f.fault_id,
                "class": fault_class(f.fault_id),
                "onset_s": float(f.onset_s),
                "magnitude": float(f.resolved_magnitude) if math.isfinite(f.resolved_magnitude) else 0.0,
                "end_s": None if f.end_s is None else float(f.end_s),
            }
            for f in self.faults
        ]

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.scenario_id,
            "profile": self.profile,
            "noise_seed": int(self.noise_seed),
            "noise_scale": float(self.noise_scale),
            "duration_s": float(self.duration_s),
            "faults": [_fault_to_dict(f) for f in self.faults],
            "magnitude_scales": [float(x) for x in self.magnitude_scales],
        }

    @classmethod
    def from_dict(cls, d: dict) -> "ScenarioSpec":
        if not isinstance(d, dict):
            raise ValueError(f"a scenario must be a dict, got {type(d).__name__}")
        allowed = {"scenario_id", "profile", "noise_seed", "noise_scale", "duration_s", "faults", "magnitude_scales"}
        bad = set(d) - allowed
        if bad:
            raise ValueError(f"unknown scenario fields {sorted(bad)}; allowed: {sorted(allowed)}")
        kw = dict(d)
        return cls(**kw)


def _as_tuple(what: str, name: str, v) -> tuple:
    if isinstance(v, (str, bytes, dict)) or not isinstance(v, Iterable):
        raise ValueError(f"{what} field {name!r} must be a sequence, got {v!r}")
    return tuple(v)


def _check_pair(name: str, v, lo: float = 0.0) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in v)
    except (TypeError, ValueError):
        raise ValueError(f"scenario config field {name!r} must be a pair of numbers, got {v!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < lo or b < a:
        raise ValueError(f"scenario config field {name!r} must be a pair lo <= hi, both >= {lo}, got {v!r}")
    return a, b


def _check_weights(name: str, pairs, allowed) -> tuple[tuple[str, float], ...]:
    out = []
    for item in _as_tuple("scenario config", name, pairs):
        try:
            k, w = item
            w = float(w)
        except (TypeError, ValueError):
            raise ValueError(f"scenario config field {name!r} must hold (name, weight) pairs, got {item!r}") from None
        if k not in allowed:
            raise ValueError(f"scenario config field {name!r}: unknown {k!r}; allowed: {', '.join(allowed)}")
        if not (math.isfinite(w) and w >= 0):
            raise ValueError(f"scenario config field {name!r}: weight of {k!r} must be >= 0, got {w!r}")
        out.append((k, w))
    if not out or sum(w for _, w in out) <= 0:
        raise ValueError(f"scenario config field {name!r} needs at least one positive weight")
    return tuple(out)


@dataclass(frozen=True)
class ScenarioConfig:
    """The distribution of episodes (a preset name or a custom config; all fields validated).

    duration_s : episode length [s].
    profiles : (family, weight) pairs; families: constant, step, ramp, random, manoeuvring
        (``harbour`` and ``seastate`` are held out for the ``transfer-v2`` suite, ``slowsteaming`` for
        ``transfer-v3``).
    load_range : fuel settings [-] of the profiles are drawn uniformly in this range.
    fault_count_weights : weights of 0, 1 and 2 faults.
    fault_ids : the faults that may be drawn.
    sensor_kinds : (kind, weight) pairs for sensor faults (offset, drift, stuck, gain, precision).
    onset_range_s : the first onset is uniform in this range [s].
    second_onset_gap_s : the second onset follows the first after a gap uniform in this range [s].
    magnitude_range : magnitude / detectability limit, drawn log-uniformly.
    noise_scale : multiplier of the table 6.3 noise bounds.
    """

    name: str = "custom"
    duration_s: float = 300.0
    profiles: tuple[tuple[str, float], ...] = (("constant", 0.4), ("step", 0.3), ("ramp", 0.3))
    load_range: tuple[float, float] = (0.6, 1.0)
    fault_count_weights: tuple[float, float, float] = (0.2, 0.5, 0.3)
    fault_ids: tuple[str, ...] = FAULT_IDS
    sensor_kinds: tuple[tuple[str, float], ...] = (("offset", 1.0),)
    onset_range_s: tuple[float, float] = (20.0, 200.0)
    second_onset_gap_s: tuple[float, float] = (0.0, 60.0)
    magnitude_range: tuple[float, float] = (1.0, 4.0)
    noise_scale: float = 1.0

    def __post_init__(self) -> None:
        if not (isinstance(self.duration_s, (int, float)) and math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"scenario config field 'duration_s' must be > 0, got {self.duration_s!r}")
        for item in _as_tuple("scenario config", "profiles", self.profiles):
            if isinstance(item, (tuple, list)) and item and item[0] in HELD_OUT_PROFILES:
                raise ValueError(
                    f"scenario config field 'profiles': {item[0]!r} is held out for the transfer suites "
                    f"(never drawn by a scenario config); allowed: {', '.join(SAMPLER_PROFILES)}"
                )
        object.__setattr__(self, "profiles", _check_weights("profiles", self.profiles, SAMPLER_PROFILES))
        object.__setattr__(self, "sensor_kinds", _check_weights("sensor_kinds", self.sensor_kinds, SENSOR_FAULT_KINDS))
        lr = _check_pair("load_range", self.load_range)
        if lr[0] <= 0 or lr[1] > 1.2:
            raise ValueError(f"scenario config field 'load_range' must lie in (0, 1.2], got {self.load_range!r}")
        object.__setattr__(self, "load_range", lr)
        try:
            w = tuple(float(x) for x in _as_tuple("scenario config", "fault_count_weights", self.fault_count_weights))
        except (TypeError, ValueError):
            w = ()
        if len(w) != 3 or not all(math.isfinite(x) and x >= 0 for x in w) or sum(w) <= 0:
            raise ValueError(
                "scenario config field 'fault_count_weights' must be 3 weights >= 0 (0, 1, 2 faults) "
                f"with a positive sum, got {self.fault_count_weights!r}"
            )
        object.__setattr__(self, "fault_count_weights", w)
        ids = _as_tuple("scenario config", "fault_ids", self.fault_ids)
        for f in ids:
            if f not in FAULT_IDS:
                raise ValueError(f"scenario config field 'fault_ids': unknown fault id {f!r}")
        if len(set(ids)) != len(ids):
            raise ValueError("scenario config field 'fault_ids' lists a fault twice")
        max_count = max(i for i, x in enumerate(w) if x > 0)
        if len(ids) < max_count:
            raise ValueError(
                f"scenario config field 'fault_ids' has {len(ids)} faults but up to {max_count} "
                "faults per episode are asked for"
            )
        object.__setattr__(self, "fault_ids", ids)
        onset = _check_pair("onset_range_s", self.onset_range_s)
        if onset[1] >= self.duration_s:
            raise ValueError(
                f"scenario config field 'onset_range_s' must end before duration_s ({self.duration_s} s),"
                f" got {self.onset_range_s!r}"
            )
        object.__setattr__(self, "onset_range_s", onset)
        object.__setattr__(self, "second_onset_gap_s", _check_pair("second_onset_gap_s", self.second_onset_gap_s))
        mr = _check_pair("magnitude_range", self.magnitude_range)
        if mr[0] <= 0:
            raise ValueError(f"scenario config field 'magnitude_range' must be > 0, got {self.magnitude_range!r}")
        object.__setattr__(self, "magnitude_range", mr)
        if not (
            isinstance(self.noise_scale, (int, float)) and math.isfinite(self.noise_scale) and self.noise_scale >= 0
        ):
            raise ValueError(
                f"scenario config field 'noise_scale' must be a finite number >= 0, got {self.noise_scale!r}"
            )

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ScenarioConfig":
        allowed = set(cls.__dataclass_fields__)
        bad = set(d) - allowed
        if bad:
            raise ValueError(f"unknown scenario config fields {sorted(bad)}; allowed: {sorted(allowed)}")
        return cls(**d)

    # ------------------------------------------------------------------------------- sampling
    def sample(self, entropy: int, scenario_id: str = "") -> ScenarioSpec:
        """Draw one episode from ``SeedSequence(entropy)`` (one child per component, see module doc)."""
        children = np.random.SeedSequence(int(entropy)).spawn(len(SAMPLER_COMPONENTS))
        rng = {name: np.random.default_rng(c) for name, c in zip(SAMPLER_COMPONENTS, children)}
        profile = self._profile(rng["profile"])
        w = np.asarray(self.fault_count_weights)
        count = int(rng["fault_count"].choice(3, p=w / w.sum()))
        ids = [self.fault_ids[i] for i in rng["fault_ids"].choice(len(self.fault_ids), size=count, replace=False)]
        kinds_names = [k for k, _ in self.sensor_kinds]
        kw = np.asarray([x for _, x in self.sensor_kinds])
        kinds = [kinds_names[int(rng["sensor_kind"].choice(len(kinds_names), p=kw / kw.sum()))] for _ in ids]
        r_on = rng["onsets"]
        onsets = []
        t = float(r_on.uniform(*self.onset_range_s))
        for i in range(count):
            if i > 0:
                t = max(0.0, min(t + float(r_on.uniform(*self.second_onset_gap_s)), self.duration_s - 10.0))
            onset = round(t, 2)
            onsets.append(onset if onset < self.duration_s else t)
        r_mag = rng["magnitudes"]
        lo, hi = self.magnitude_range
        faults, scales = [], []
        for fid, kind, onset in zip(ids, kinds, onsets):
            scale = float(math.exp(r_mag.uniform(math.log(lo), math.log(hi))))
            sign = 1.0 if r_mag.random() < 0.5 else -1.0
            faults.append(fault_at_scale(fid, kind, onset, scale, sign))
            scales.append(scale)
        order = np.argsort([f.onset_s for f in faults], kind="stable")
        noise_seed = int(rng["noise"].integers(0, _MAX_SEED))
        return ScenarioSpec(
            faults=tuple(faults[i] for i in order),
            profile=profile,
            noise_seed=noise_seed,
            noise_scale=self.noise_scale,
            duration_s=self.duration_s,
            scenario_id=scenario_id,
            magnitude_scales=tuple(scales[i] for i in order),
        )

    def _profile(self, r: np.random.Generator) -> str:
        names = [k for k, _ in self.profiles]
        w = np.asarray([x for _, x in self.profiles])
        fam = names[int(r.choice(len(names), p=w / w.sum()))]
        lo, hi = self.load_range
        D = self.duration_s
        u0, u1 = (round(float(x), 4) for x in r.uniform(lo, hi, size=2))
        if fam == "constant":
            return f"constant:u0={u0}"
        if fam == "step":
            return f"step:u0={u0},u1={u1},t={round(float(r.uniform(0.1, 0.9) * D), 2)}"
        if fam == "ramp":
            a, b = sorted(float(x) for x in r.uniform(0.05, 0.95, size=2) * D)
            return f"ramp:u0={u0},u1={u1},t0={round(a, 2)},t1={round(max(b, a + 10.0), 2)}"
        if fam == "random":
            return f"random:seed={int(r.integers(0, 2**31))},u_min={lo},u_max={hi}"
        return f"manoeuvring:scale={round(float(r.uniform(0.9, 1.05)), 4)}"


def fault_at_scale(fault_id: str, kind: str, onset: float, scale: float, sign: float) -> FaultSpec:
    """A fault whose size is ``scale`` times its detectability limit (sign for sensor faults)."""
    from .detectability import sampling_scale

    limit = sampling_scale(fault_id)
    if fault_class(fault_id) == "process":
        return FaultSpec(fault_id, onset, magnitude=scale * limit)
    if kind == "offset":
        return FaultSpec(fault_id, onset, magnitude=sign * scale * limit)
    if kind == "drift":  # reaches the scaled offset limit after 60 s
        return FaultSpec(fault_id, onset, magnitude=sign * scale * limit / 60.0, kind="drift")
    if kind == "gain":  # relative error giving the scaled offset limit at the nominal reading
        return FaultSpec(fault_id, onset, magnitude=sign * scale * limit / abs(nominal_reading(fault_id)), kind="gain")
    if kind == "precision":  # extra noise bound
        return FaultSpec(fault_id, onset, magnitude=scale * limit, kind="precision")
    return FaultSpec(fault_id, onset, kind="stuck")


@lru_cache(maxsize=None)
def _nominal_readings() -> np.ndarray:
    from ..engine.simulator import Simulator

    return Simulator("thesis-12v28", noise_scale=0.0).y[0].copy()


def nominal_reading(sensor_id: str) -> float:
    """Noise-free reading of a sensor at the thesis engine's nominal point (fuel setting 1)."""
    from ..engine.sensors import sensor_index

    return float(_nominal_readings()[sensor_index(sensor_id)])


PRESETS: dict[str, ScenarioConfig] = {
    c.name: c
    for c in (
        # training distribution: constant, step and ramp profiles; 0-2 faults of every id
        ScenarioConfig(name="default"),
        ScenarioConfig(name="single", fault_count_weights=(0.0, 1.0, 0.0)),
        ScenarioConfig(name="multi", fault_count_weights=(0.0, 0.0, 1.0)),
        ScenarioConfig(name="nominal", fault_count_weights=(1.0, 0.0, 0.0)),
        # process faults near their detectability limit
        ScenarioConfig(
            name="incipient",
            fault_count_weights=(0.0, 1.0, 0.0),
            fault_ids=PROCESS_FAULT_IDS,
            magnitude_range=(0.5, 1.5),
        ),
        # operating profiles the training presets never use
        ScenarioConfig(name="transfer", profiles=(("manoeuvring", 0.5), ("random", 0.5))),
        # every sensor fault kind, not only offsets
        ScenarioConfig(
            name="sensor-kinds",
            fault_ids=SENSOR_IDS,
            fault_count_weights=(0.0, 1.0, 0.0),
            sensor_kinds=tuple((k, 1.0) for k in SENSOR_FAULT_KINDS),
        ),
    )
}


def with_noise_scale(env_kwargs: dict, noise_scale: float) -> dict:
    """``env_kwargs`` whose scenario config has sensor-noise scale ``noise_scale`` (a batched engine set
    shares one scale, so episodes of another scale run in batches of their own)."""
    cfg = get_preset(env_kwargs.get("scenario_config", "default"))
    if float(cfg.noise_scale) == float(noise_scale):
        return dict(env_kwargs)
    from dataclasses import replace

    return dict(env_kwargs, scenario_config=replace(cfg, noise_scale=float(noise_scale)))


def get_preset(name: "str | ScenarioConfig | dict") -> ScenarioConfig:
    """A preset by name, a config passed through, or a config built from a dict."""
    if isinstance(name, ScenarioConfig):
        return name
    if isinstance(name, dict):
        return ScenarioConfig.from_dict(name)
    from ..suggest import lookup

    return lookup(PRESETS, name, "scenario preset")
