"""Simulate engines in batches and diagnose them as they run (the driver of the KPI and certainty
measurements): the readings stream from :class:`~marine_fdi_env.engine.simulator.Simulator` into a
diagnoser block by block, so memory does not grow with the run length.

Diagnosers by name (:data:`DIAGNOSERS`): ``reference`` (the thesis's scheme,
:class:`~marine_fdi_env.diagnosis.agent.ReferenceDiagnoser`) and ``sequential`` (CUSUM tests on
the same residuals, :class:`~marine_fdi_env.diagnosis.sequential.SequentialDiagnoser`).
"""

from __future__ import annotations

import numpy as np

from ..engine.simulator import Simulator
from .agent import ReferenceDiagnoser
from .sequential import SequentialDiagnoser

__all__ = ["diagnose_batch", "make_diagnoser", "DIAGNOSERS", "BATCH"]

PARAMS = "thesis-12v28"
DURATION_S = 300.0
BATCH = 256  # engines per simulated batch (two threads from 256 on)
DIAGNOSERS = ("reference", "sequential")


def make_diagnoser(name: str, params: str, n_engines: int, dt: float, **options):
    """A diagnoser by name (see module docstring); ``options`` go to its constructor."""
    if name == "reference":
        return ReferenceDiagnoser(params, n_engines=n_engines, dt=dt, **options)
    if name == "sequential":
        return SequentialDiagnoser(params, n_engines=n_engines, dt=dt, **options)
    raise ValueError(f"unknown diagnoser {name!r}; allowed: {', '.join(DIAGNOSERS)}")


def diagnose_batch(
    schedules,
    seeds,
    profile="constant",
    duration_s=DURATION_S,
    exoneration="sure",
    block_samples: int = 1000,
    params: str = PARAMS,
    diagnoser: str = "reference",
    on_block=None,
    **options,
):
    """Simulate and diagnose engines in batches; returns one report dict per engine (the keys of
    :meth:`ReferenceDiagnoser.report` plus ``failures``).

    schedules : per engine a list of FaultSpec; seeds : per engine; profile : one profile spec for
    all or one per engine.  Streams the readings (the t = 0 reading, then blocks of
    ``block_samples``) from the simulator into the diagnoser; the same numbers as diagnosing a
    recorded ``Simulator.run`` (both stream equalities are tested).  ``on_block(agent, engines,
    block)``, if given, is called after every block (engines: the batch's slice of the inputs).
    """
    if len(schedules) != len(seeds):
        raise ValueError(f"{len(schedules)} schedules but {len(seeds)} seeds")
    profiles = [profile] * len(seeds) if isinstance(profile, str) else list(profile)
    if len(profiles) != len(seeds):
        raise ValueError(f"{len(profiles)} profiles but {len(seeds)} seeds")
    reports = []
    for a in range(0, len(schedules), BATCH):
        sch = schedules[a : a + BATCH]
        sd = seeds[a : a + BATCH]
        sim = Simulator(params, len(sch), seeds=sd, faults=sch, profiles=profiles[a : a + BATCH])
        agent = make_diagnoser(diagnoser, params, len(sch), sim.dt, exoneration=exoneration, **options)
        agent.observe(sim.y[:, None, :], sim.u[:, None])
        steps, done = int(round(duration_s / sim.dt)), 0
        while done < steps:
            m = min(block_samples, steps - done)
            blk = sim.advance(m)
            agent.observe(blk.measurements, blk.u)
            done += m
            if on_block is not None:
                on_block(agent, slice(a, a + len(sch)), blk)
        for i in range(len(sch)):
            rep = agent.report(i)
            rep["failures"] = [f.to_dict() for f in sim.failures if f.engine == i]
            reports.append(rep)
    return reports


def as_array(reports, key: str = "module_detection_times_s", module_ids=None) -> np.ndarray:
    """(runs, 19) first firing times from a list of reports (NaN: never)."""
    from .modules import MODULE_IDS

    ids = MODULE_IDS if module_ids is None else module_ids
    return np.array([[np.nan if r[key][m] is None else r[key][m] for m in ids] for r in reports], dtype=float)
