"""Condition (f) of the open-world study: data that two model structures explain within the band, by construction.

A trial draws the true structure A from one of :data:`PAIRS` (by ``seed % 2``: a waste gate against gate and map
with the gate at other points; a map change against a turbine efficiency falling off with the blade-speed ratio)
with parameters from the ranges of :data:`DRAWS`,
solves it without noise at the study's stratified loads, and fits the other structure B to those clean readings
(the pipeline's fit: valve points by relaxation, nuisance included).  The draw is kept only when B fits A within
the explanation set's band at the study's noise, i.e. when the sum over the cells of B's squared misfit in noise
standard deviations is at most ``BAND + 2 max(0, k_A - k_B)`` (the in-sample ΔAIC of B against A on the clean
data is then at most the band when B has no more parameters than A; a B with more parameters is held to the band
on its misfit alone, which admits more draws than the AIC would); else it is drawn again, up to :data:`ATTEMPTS`
times (deterministic in the seed).  Two other pairs are not drawn, because on the development seeds 0-23 no draw
falls within the band at the study's eleven channels and 1 % noise: a charge-air bypass at part load against
a map change (either way; the exhaust temperatures tell them apart: B's misfit 40-1000 noise variances), and gate
and map against the gate alone (the gate alone opens at seven of eight points, misfit 100-360).  The
noisy data are then A's, as every study trial's (:func:`~.synthesize.synthesize`, the same loads and seed).
"""

from __future__ import annotations

import functools
from typing import Any, Callable

import numpy as np

from marine_fdi_env.validation.explain.explanations import BAND
from marine_fdi_env.validation.fit.fitting import Combination, fit_combination, predict_setting
from marine_fdi_env.validation.fit.mechanisms import get_mechanism
from marine_fdi_env.validation.fit.problem import FitProblem

__all__ = ["ATTEMPTS", "DRAWS", "PAIRS", "ambiguous_draw"]

#: (true structure, the structure that fits its data within the band) by ``seed % 2``
PAIRS = ((("waste_gate",), ("waste_gate", "turbocharger_map")), (("turbocharger_map",), ("turbine_efficiency_bsr",)))
#: parameter ranges of the true structures (uniform): effects a few noise levels large, where the pairs overlap
DRAWS = {
    "waste_gate": {"above": (0.7, 0.9), "opening": (0.08, 0.2), "turbine_area_scale": (0.8, 0.95)},
    "turbocharger_map": {"eta_scale": (0.95, 1.05), "curvature": (0.0, 0.3)},
}
#: draws tried per seed before the trial is skipped
ATTEMPTS = 20


def _specs(mechs: tuple[str, ...], rng: np.random.Generator) -> list[str]:
    return [m + ":" + ",".join(f"{k}={rng.uniform(*r):.4f}" for k, r in DRAWS[m].items()) for m in mechs]


def _k(truth: list[dict[str, Any]]) -> int:
    """Free parameters of the true structure as the pipeline counts them (globals + open points)."""
    k = 0
    for t in truth:
        m = get_mechanism(t["id"])
        k += len(m.params) + (sum(1 for o in t.get("openings", ()) if o > 0) if m.pointwise else 0)
    return k


@functools.lru_cache(maxsize=64)
def ambiguous_draw(
    seed: int, load: Callable[[Any], Any], *, params: str = "wartsila-6l46", points: int = 8, noise: float = 0.01
) -> dict[str, Any] | None:
    """The (f) draw of ``seed``: ``{specs, truth, alternative, misfit, bound, attempt}`` (``specs`` for
    :func:`~.synthesize.synthesize`; ``misfit``: the alternative's sum of squared misfit on the clean data in noise
    standard deviations), or None when no draw of :data:`ATTEMPTS` is ambiguous.  ``load``: the study's round trip
    of a synthesis through a CSV file and the loader (:func:`~.study.loaded`).  Cached (a trial asks twice)."""
    from marine_fdi_env.validation.fit.synthesize import synthesize

    truth_ids, alt_ids = PAIRS[int(seed) % len(PAIRS)]
    for attempt in range(ATTEMPTS):
        rng = np.random.default_rng([int(seed), attempt, ord("f"), 7919])
        specs = _specs(truth_ids, rng)
        try:
            clean = synthesize(params, specs, points=points, noise=0.0, seed=int(seed) * 31 + 7)
            pr = FitProblem(load(clean))
        except ValueError:
            continue
        comb = Combination(tuple(get_mechanism(m) for m in alt_ids))
        fit = fit_combination(pr, comb, uncertainty=False)
        if any(not fit.support.get(m.id) for m in comb.valves):
            continue
        pred = predict_setting(pr, fit, np.arange(pr.n_points))
        sd = np.array([noise * float(np.mean(np.abs(clean.clean[c]))) for c in pr.channels])
        misfit = float(np.nansum(((pred - pr.Y) / sd) ** 2))
        bound = BAND + 2.0 * max(0, _k(clean.truth) - fit.k)
        if misfit <= bound:
            return {
                "specs": specs,
                "truth": sorted(t["label"] for t in clean.truth),
                "alternative": sorted(alt_ids),
                "alternative_fit": fit.values(),
                "alternative_support": {k: [i + 1 for i in v] for k, v in fit.support.items()},
                "misfit": misfit,
                "bound": bound,
                "attempt": attempt,
            }
    return None
