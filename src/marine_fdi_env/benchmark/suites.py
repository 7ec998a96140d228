"""Frozen, versioned evaluation suites: scenario lists stored as data.

A suite is a JSON file ``data/suites/NAME.json``::

    {"name": "single-v1", "version": 1, "description": ..., "built_with": "<command>",
     "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": false},
     "scenarios": [ScenarioSpec.to_dict(), ...]}           # each with a unique scenario_id

Once published a suite file never changes: results on it are comparable across versions of the
code that keep the simulator's numbers.  A change of content is a new name (``-v2``).  The files
were made by :func:`build_suite` (the repository's suite builder, docs/environment.md); the test
suite checks that the builders still reproduce them, so a change of the sampler or of the
detectability table (which sets the magnitudes) cannot silently alter a published suite: such a
change needs new suite versions.

=================  =========================================================================
suite              content
=================  =========================================================================
``thesis-v1``      the four multiple-fault examples of thesis section 6.4 (tables 6.3, 6.4
                   magnitudes, constant full load) x 5 noise seeds
``single-v1``      each of the 26 faults alone at 1x, 2x and 4x its detectability limit x 2
                   seeds (sensor offsets with random sign), random training-type profiles
``multi-v1``       48 random pairs of faults (1-4x limits), training-type profiles
``incipient-v1``   each process fault at 0.5x, 1x and 1.5x its limit x 3 seeds
``transfer-v1``    60 episodes of the ``transfer`` preset: manoeuvring and random profiles,
                   which no training preset uses
``nominal-v1``     48 fault-free episodes over all profile families (4 fault-free hours)
``transfer-v2``    64 episodes in operating conditions no training or calibration data
                   contains: the held-out profile families ``harbour`` (random engine-telegraph
                   steps) and ``seastate`` (wave load fluctuation around a mean), and sensor
                   noise at 0.7x table 6.3 (everything else is drawn at 1.0x); 0-2 faults as
                   the ``default`` preset; scored with the ``MarineFDI-v1`` reward
``transfer-v3``    128 episodes in conditions no training or calibration config can draw: the
                   held-out part-load family ``slowsteaming`` (mean fuel setting 0.3-0.5,
                   drifting by up to 10 %, waves of 5-12 % peak) at sensor noise 1.3x (even
                   indices) and 0.6x (odd), neither on the learned agents' training grid;
                   0-2 faults at 1-3x their detectability limit; scored with ``MarineFDI-v1``
=================  =========================================================================

``transfer-v2``'s noise is *below* the table bounds because the reference diagnoser's adaptive
thresholds are worst-case bounds over exactly that noise: at 1.05x it raised a false alarm in 16 of
16 fault-free harbour and sea-state episodes (0 of 16 at 1.0x and at 0.75x; measured when the suite
was made), so a noisier suite would only measure that broken assumption.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from ..engine.fault_registry import suite_fault_ids
from ..envs.scenario_sampler import PRESETS, ScenarioConfig, ScenarioSpec, fault_at_scale
from ..jsonfile import read_json
from ..scenarios import get_scenario

__all__ = ["SUITE_NAMES", "load_suite", "build_suite", "single_fault_suite", "Suite"]

SUITE_NAMES = (
    "thesis-v1",
    "single-v1",
    "multi-v1",
    "incipient-v1",
    "transfer-v1",
    "nominal-v1",
    "transfer-v2",
    "transfer-v3",
)
_ENV = {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False}


class Suite(dict):
    """A loaded suite: the JSON object, with ``scenarios`` as :class:`ScenarioSpec` objects."""

    @property
    def scenarios(self) -> list[ScenarioSpec]:
        return self["scenarios"]

    @property
    def name(self) -> str:
        return self["name"]


def _validate(data: dict, where: str) -> Suite:
    for k in ("name", "version", "env", "scenarios"):
        if k not in data:
            raise ValueError(f"{where}: suite lacks {k!r}")
    scs = []
    for i, d in enumerate(data["scenarios"]):
        try:
            scs.append(ScenarioSpec.from_dict(d))
        except ValueError as e:
            raise ValueError(f"{where}: scenario {i}: {e}") from None
    ids = [s.scenario_id for s in scs]
    if len(set(ids)) != len(ids) or any(not x for x in ids):
        raise ValueError(f"{where}: scenario ids must be unique and non-empty")
    out = Suite(data)
    out["scenarios"] = scs
    return out


@lru_cache(maxsize=None)
def _load_builtin(name: str) -> Suite:
    text = resources.files("marine_fdi_env").joinpath(f"data/suites/{name}.json").read_text()
    return _validate(json.loads(text), f"suite {name}")


def load_suite(name_or_path: str) -> Suite:
    """A shipped suite by name (``single-v1``) or a suite JSON file by path."""
    if name_or_path in SUITE_NAMES:
        return _load_builtin(name_or_path)
    p = Path(name_or_path)
    if not p.is_file():
        from ..suggest import did_you_mean

        raise ValueError(
            f"unknown suite {name_or_path!r}{did_you_mean(name_or_path, SUITE_NAMES)}; shipped: "
            f"{', '.join(SUITE_NAMES)} (or a JSON path)"
        )
    data = read_json(p, "suite file")
    return _validate(data, str(p))


# ----------------------------------------------------------------------------------- builders
def _seeds(name: str, n: int) -> list[int]:
    """n reproducible 63-bit seeds belonging to one suite."""
    ss = np.random.SeedSequence(list(name.encode()))
    return [int(x) for x in np.random.default_rng(ss).integers(0, 2**63 - 1, size=n)]


def _thesis() -> list[ScenarioSpec]:
    seeds = _seeds("thesis-v1", 20)
    out = []
    for k, name in enumerate(("thesis-6.4.1", "thesis-6.4.2", "thesis-6.4.3", "thesis-6.4.4")):
        sc = get_scenario(name)
        for j in range(5):
            out.append(
                ScenarioSpec(
                    faults=tuple(sc.fault_specs()),
                    profile=sc.profile,
                    noise_seed=seeds[5 * k + j],
                    duration_s=sc.duration_s,
                    scenario_id=f"{name}/seed{j}",
                )
            )
    return out


def _profile_of(config: ScenarioConfig, entropy: int) -> str:
    return config.sample(entropy).profile


def _grid(name: str, fault_ids, scales, reps: int, signed: bool) -> list[ScenarioSpec]:
    """Every fault alone at every scale, ``reps`` times: training-type profile, onset in the
    default range, random sign for sensor offsets if ``signed``; three seeds per episode."""
    base = PRESETS["default"]
    seeds = _seeds(name, len(fault_ids) * len(scales) * reps * 3)
    out, k = [], 0
    for fid in fault_ids:
        for scale in scales:
            for rep in range(reps):
                s_prof, s_onset, s_noise = seeds[k : k + 3]
                k += 3
                r = np.random.default_rng(s_onset)
                onset = round(float(r.uniform(*base.onset_range_s)), 2)
                sign = (1.0 if r.random() < 0.5 else -1.0) if signed else 1.0
                f = fault_at_scale(fid, "offset", onset, scale, sign)
                out.append(
                    ScenarioSpec(
                        faults=(f,),
                        profile=_profile_of(base, s_prof),
                        noise_seed=s_noise,
                        scenario_id=f"{fid}/x{scale:g}/r{rep}",
                        magnitude_scales=(scale,),
                    )
                )
    return out


# The published suites draw from the faults of their version (a fault declared later joins newer suites only).
_V1_FAULTS = suite_fault_ids(1)


def _single() -> list[ScenarioSpec]:
    return _grid("single-v1", _V1_FAULTS, (1.0, 2.0, 4.0), 2, signed=True)


def _incipient() -> list[ScenarioSpec]:
    return _grid("incipient-v1", suite_fault_ids(1, "process"), (0.5, 1.0, 1.5), 3, signed=False)


def _sampled(name: str, preset: str, n: int) -> list[ScenarioSpec]:
    cfg = replace(PRESETS[preset], fault_ids=_V1_FAULTS)
    return [cfg.sample(e, scenario_id=f"{name}/{i:03d}") for i, e in enumerate(_seeds(name, n))]


def _nominal() -> list[ScenarioSpec]:
    cfg = ScenarioConfig(
        name="nominal-all-profiles",
        fault_ids=_V1_FAULTS,
        fault_count_weights=(1.0, 0.0, 0.0),
        profiles=tuple((p, 1.0) for p in ("constant", "step", "ramp", "random", "manoeuvring")),
    )
    return [cfg.sample(e, scenario_id=f"nominal-v1/{i:03d}") for i, e in enumerate(_seeds("nominal-v1", 48))]


TRANSFER_V2_NOISE_SCALE = 0.7


def _transfer_v2() -> list[ScenarioSpec]:
    """64 episodes: faults as the ``default`` preset draws them, the profile from a held-out family
    (``harbour`` for even, ``seastate`` for odd indices), noise at 0.7x."""
    faults = ScenarioConfig(name="transfer-v2", fault_ids=_V1_FAULTS, noise_scale=TRANSFER_V2_NOISE_SCALE)
    seeds = _seeds("transfer-v2", 2 * 64)
    out = []
    for i in range(64):
        sc = faults.sample(seeds[2 * i], scenario_id=f"transfer-v2/{i:03d}")
        r = np.random.default_rng(seeds[2 * i + 1])
        if i % 2 == 0:
            prof = (
                f"harbour:seed={int(r.integers(0, 2**31))},u_min=0.3,u_max=1.0,"
                f"dwell={round(float(r.uniform(15.0, 45.0)), 1)}"
            )
        else:
            prof = (
                f"seastate:seed={int(r.integers(0, 2**31))},u_mean={round(float(r.uniform(0.6, 0.95)), 3)},"
                f"amplitude={round(float(r.uniform(0.03, 0.08)), 3)},period={round(float(r.uniform(6.0, 12.0)), 2)}"
            )
        out.append(replace(sc, profile=prof))
    return out


TRANSFER_V3_NOISE_SCALES = (1.3, 0.6)


def _transfer_v3() -> list[ScenarioSpec]:
    """128 episodes: 0-2 faults as the ``default`` preset draws them but at 1-3x their detectability
    limit, a ``slowsteaming`` profile, noise 1.3x for even and 0.6x for odd indices."""
    faults = ScenarioConfig(name="transfer-v3", fault_ids=_V1_FAULTS, magnitude_range=(1.0, 3.0))
    seeds = _seeds("transfer-v3", 2 * 128)
    out = []
    for i in range(128):
        sc = faults.sample(seeds[2 * i], scenario_id=f"transfer-v3/{i:03d}")
        r = np.random.default_rng(seeds[2 * i + 1])
        prof = (
            f"slowsteaming:seed={int(r.integers(0, 2**31))},u_mean={round(float(r.uniform(0.3, 0.5)), 3)},"
            f"drift={round(float(r.uniform(-0.1, 0.1)), 3)},amplitude={round(float(r.uniform(0.05, 0.12)), 3)},"
            f"period={round(float(r.uniform(6.0, 12.0)), 2)}"
        )
        out.append(replace(sc, profile=prof, noise_scale=TRANSFER_V3_NOISE_SCALES[i % 2]))
    return out


_BUILDERS = {
    "thesis-v1": (_thesis, "the four multiple-fault examples of thesis section 6.4 x 5 noise seeds"),
    "single-v1": (_single, "each of the 26 faults alone at 1x, 2x, 4x its detectability limit x 2 seeds"),
    "multi-v1": (lambda: _sampled("multi-v1", "multi", 48), "48 random fault pairs at 1-4x their limits"),
    "incipient-v1": (_incipient, "each process fault at 0.5x, 1x, 1.5x its detectability limit x 3 seeds"),
    "transfer-v1": (
        lambda: _sampled("transfer-v1", "transfer", 60),
        "manoeuvring and random profiles (never used by the training presets), 0-2 faults",
    ),
    "nominal-v1": (_nominal, "48 fault-free episodes over all profile families"),
    "transfer-v2": (
        _transfer_v2,
        "held-out profile families (harbour telegraph steps, sea-state load fluctuation) "
        "and sensor noise 0.7x, never in training or calibration data; 0-2 faults",
    ),
    "transfer-v3": (
        _transfer_v3,
        "held-out part-load family (slow steaming at 0.3-0.5 with waves) at sensor noise "
        "1.3x and 0.6x, never in training or calibration data; 0-2 faults at 1-3x their limits",
    ),
}
# the env block of a suite; transfer-v2 and -v3 also fix the reward they are scored with
_SUITE_ENV = {"transfer-v2": dict(_ENV, reward="v1"), "transfer-v3": dict(_ENV, reward="v1")}


def single_fault_suite(name: str, fault_ids, built_with: str = "") -> dict:
    """The JSON object of a suite like ``single-v1`` for some faults (e.g. a fault of a plugin): each fault
    alone at 1x, 2x and 4x its detectability limit x 2 seeds (sensor offsets with random sign), training-type
    profiles; ``name`` ends in ``-vN``.  The faults' detectability limits must exist."""
    if "-v" not in name or not name.rsplit("-v", 1)[1].isdigit():
        raise ValueError(f"a suite name ends in -vN (N the version), got {name!r}")
    fault_ids = tuple(fault_ids)
    return {
        "name": name,
        "version": int(name.rsplit("-v", 1)[1]),
        "description": f"each of {', '.join(fault_ids)} alone at 1x, 2x, 4x its detectability limit x 2 seeds",
        "built_with": built_with,
        "env": dict(_ENV),
        "scenarios": [s.to_dict() for s in _grid(name, fault_ids, (1.0, 2.0, 4.0), 2, signed=True)],
    }


def build_suite(name: str) -> dict:
    """The JSON object of a shipped suite, rebuilt from its builder."""
    if name not in _BUILDERS:
        raise ValueError(f"unknown suite {name!r}; allowed: {', '.join(_BUILDERS)}")
    fn, desc = _BUILDERS[name]
    return {
        "name": name,
        "version": int(name.rsplit("-v", 1)[1]),
        "description": desc,
        "built_with": f"python -m studies.benchmark.build_suites {name}",
        "env": dict(_SUITE_ENV.get(name, _ENV)),
        "scenarios": [s.to_dict() for s in fn()],
    }
