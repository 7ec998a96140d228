"""The explanations in the validation report: the set the data do not decide between (:mod:`.explanations`), the
measurement that would decide (:mod:`.deciding`) and, with a hold-out, each explanation's prediction of it.

:func:`explain` computes them for a selection; :func:`explanations_json` gives the report's keys ``explanations``
(ranked, best first: name, causes, per-point valve states, fitted values with profile intervals, per-channel
residuals, evidence relative to the best), ``explanations_outside`` (what was tried and why it is not in the set)
and ``deciding``; :func:`summary_lines` and :func:`markdown_lines` say it in words: "the data do not decide between:
A, B".
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence

from ..fit.problem import FitProblem
from .deciding import deciding_measurements
from .explanations import BAND, EXCLUDE_ALPHA, Explanation, ExplanationSet, explanation_set_of, nested_in

__all__ = [
    "DECIDE_TOP",
    "compared",
    "explain",
    "explanation_name",
    "explanations_json",
    "interval",
    "markdown_lines",
    "summary_lines",
]

#: how many of the best-ranked explanations the deciding measurement compares (the set's, else the set's only
#: member and the best admissible structure outside it)
DECIDE_TOP = 2


def explanation_name(problem: FitProblem, e: Explanation) -> str:
    """Causes in words, each valve with the loads where it acts: ``waste_gate (open at 100/110 %) + ...``."""
    load = problem.load_axis()
    parts = []
    for m in e.fit.combination.mechanisms:
        if m.pointwise:
            pts = sorted(e.fit.support.get(m.id, ()), key=lambda i: load[i])
            parts.append(f"{m.label} (open at {'/'.join(f'{100 * load[i]:.0f}' for i in pts)} %)")
        else:
            parts.append(m.label)
    return " + ".join(parts) or "nothing (the calibrated base model)"


def compared(es: ExplanationSet) -> list[Explanation]:
    """The explanations the deciding measurement compares: the set's best :data:`DECIDE_TOP` with a cause, else its
    only one and the best admissible structure outside it."""
    top = [e for e in es.members if e.fit.combination.mechanisms][:DECIDE_TOP]
    if len(top) < DECIDE_TOP and (r := es.runner_up()) is not None and r.fit.combination.mechanisms:
        top.append(r)
    return top


def explain(
    sel,
    *,
    holdout: Callable[[Any, str], Mapping[str, Any]] | None = None,
    profiles: bool = True,
    deciding: bool = True,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The explanation set of a :class:`~.select.selection.Selection` (stored in ``sel.explanations``), the deciding
    measurements between its best explanations, and with ``holdout`` (``holdout(fit, conditions)``: a hold-out
    evaluation of a fit at ``"parameter_set"`` or ``"fit"`` conditions, as :func:`~.report.build.holdout_evaluation`)
    each member's.  Returns the report's keys (:func:`explanations_json`)."""
    es = explanation_set_of(sel, profiles=profiles, say=say)
    sel.explanations = es
    pr = sel.problem
    names = {id(e): explanation_name(pr, e) for e in es.tried}
    dec = []
    if deciding:
        cmp_ = compared(es)
        if len(cmp_) >= 2:
            dec = deciding_measurements(pr, [(f"#{i + 1} {names[id(e)]}", e.fit) for i, e in enumerate(cmp_)])
    holdouts: dict[int, dict[str, Any]] = {}
    if holdout is not None:
        for e in es.members:
            holdouts[id(e)] = {cond: holdout(e.fit, cond) for cond in ("parameter_set", "fit")}
    return explanations_json(pr, es, names, dec, holdouts)


def _holdout_summary(h: Mapping[str, Any]) -> dict[str, Any]:
    out = {}
    for cond, r in h.items():
        out[cond] = {
            c: {
                k: v.get(k)
                for k in (
                    "holdout_rmse_base",
                    "holdout_rmse_extended",
                    "holdout_rmse_base_without_suspect",
                    "holdout_rmse_extended_without_suspect",
                )
            }
            for c, v in r["channels"].items()
        }
        if r.get("conditions", {}).get("filled") == [] and cond == "fit":
            out[cond] = None
    return out


def _why_outside(e: Explanation, best: Explanation) -> str:
    if e.why_not:
        return "not admissible: " + e.why_not
    if nested_in(e, best):
        return "#1 without some of its causes, which each earn their place by the selection's test"
    return (
        f"ΔAIC {e.delta_aic:.1f} > {BAND:g}, worse point by point (paired p = {e.p_worse:.2g} < "
        f"{EXCLUDE_ALPHA:g}) and in sample (ΔAICc {e.delta_aicc_in:.1f} > {BAND:g})"
    )


def explanations_json(
    problem: FitProblem,
    es: ExplanationSet,
    names: Mapping[int, str],
    deciding: Sequence[Any],
    holdouts: Mapping[int, Any],
) -> dict[str, Any]:
    members = []
    for i, e in enumerate(es.members):
        d = e.as_dict(problem, i + 1)
        d["name"] = names[id(e)]
        if id(e) in holdouts:
            d["holdout"] = _holdout_summary(holdouts[id(e)])
        members.append(d)
    best = es.members[0]
    outside = []
    for e in es.outside():
        outside.append(
            {
                "name": names[id(e)],
                "labels": list(e.labels),
                "k": e.fit.k,
                "origin": e.structure.origin,
                "in_sample_score": e.in_sample_score,
                "cv_score": e.cv_score,
                "delta_aic": e.delta_aic,
                "p_worse": e.p_worse,
                "delta_aicc_in_sample": e.delta_aicc_in,
                "why": _why_outside(e, best),
                "parameters": e.fit.values(),
                "support": {k: [int(i) + 1 for i in v] for k, v in e.fit.support.items()},
            }
        )
    return {
        "explanations": members,
        "explanations_outside": outside,
        "deciding": list(deciding),
        "explanation_rule": {
            "rule": es.rule,
            "band_delta_aic": BAND,
            "exclude_alpha": EXCLUDE_ALPHA,
            "n_cells": es.n_cells,
            "structures_tried": len(es.tried),
            "seconds": es.seconds,
        },
    }


def _evidence(d: Mapping[str, Any]) -> str:
    if d["rank"] == 1:
        return "best"
    return f"ΔAIC {d['delta_aic']:.1f}, paired p = {d['p_worse']:.2g}, in-sample ΔAICc {d['delta_aicc_in_sample']:.1f}"


def summary_lines(rep: Mapping[str, Any]) -> list[str]:
    """The command line's words on the explanations of a report."""
    ex = rep.get("explanations")
    if not ex:
        return []
    lines = []
    if len(ex) > 1:
        lines.append(
            "  the data do not decide between: " + "; ".join(f"#{d['rank']} {d['name']} ({_evidence(d)})" for d in ex)
        )
    else:
        lines.append(f"  the data decide for: {ex[0]['name']}")
    out = rep.get("explanations_outside") or []
    if out:
        o = out[0]
        lines.append(f"  closest outside the set: {o['name']} ({o['why']})")
    for p in rep.get("deciding") or []:
        if p["measurements"]:
            lines.append("  deciding measurement: " + p["measurements"][0]["text"])
    return lines


def interval(p: Mapping[str, Any]) -> str:
    """A profile interval for Markdown: ``value [lo, hi]``, an end at the plausible range's bound marked."""
    lo = f"{p['lower']:.3g}" + (" (bound)" if p["lower_open"] else "")
    hi = f"{p['upper']:.3g}" + (" (bound)" if p["upper_open"] else "")
    return f"{p['value']:.3g} [{lo}, {hi}]" + ("" if p["identified"] else " not identified")


def markdown_lines(rep: Mapping[str, Any]) -> list[str]:
    """Markdown: the set, what lies outside it and why, the deciding measurements."""
    ex = rep.get("explanations")
    if not ex:
        return []
    rule = rep["explanation_rule"]
    L = [
        "Explanations (every model structure the data do not decide against; structures tried: "
        f"{rule['structures_tried']}; {rule['rule']}):",
        "",
    ]
    if len(ex) > 1:
        L += ["**The data do not decide between:** " + "; ".join(f"#{d['rank']} {d['name']}" for d in ex) + ".", ""]
    L += [
        "| # | explanation | named by the selection | k | in-sample score | CV score | evidence vs #1 | parameters "
        "(value [95 % profile interval]) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for d in ex:
        prof = d.get("profiles") or {}
        params = "; ".join(f"`{k}` {interval(v)}" for k, v in prof.items()) or "–"
        L.append(
            f"| {d['rank']} | {d['name']} | {'yes' if d['named'] else 'no'} | {d['k']} | "
            f"{d['in_sample_score']:.3g} | {d['cv_score']:.3g} | {_evidence(d)} | {params} |"
        )
    L.append("")
    vs = [(d, v, pts) for d in ex for v, pts in (d.get("valve_states") or {}).items()]
    if vs:
        L += [
            "Valve states per measured point (load; diverted flow fraction where open):",
            "",
            "| # | valve | " + " | ".join(f"{100 * p['load']:.0f} %" for p in vs[0][2]) + " |",
            "|---|---|" + "---|" * len(vs[0][2]),
        ]
        for d, v, pts in vs:
            L.append(
                f"| {d['rank']} | {v} | "
                + " | ".join(f"open {p['fraction']:.3f}" if p["open"] else "shut" for p in pts)
                + " |"
            )
        L.append("")
    ho = [(d, d["holdout"]) for d in ex if d.get("holdout")]
    if ho:
        L += [
            "Hold-out prediction of each explanation (RMSE base → explanation; in brackets without the readings "
            "the "
            "loader flags):",
            "",
            "| # | conditions | " + " | ".join(f"`{c}`" for c in ho[0][1]["parameter_set"]) + " |",
            "|---|---|" + "---|" * len(ho[0][1]["parameter_set"]),
        ]
        for d, h in ho:
            for cond, chans in h.items():
                if not chans:
                    continue
                L.append(
                    f"| {d['rank']} | {cond} | "
                    + " | ".join(
                        f"{_g(v['holdout_rmse_base'])} → {_g(v['holdout_rmse_extended'])} "
                        f"({_g(v['holdout_rmse_base_without_suspect'])} → "
                        f"{_g(v['holdout_rmse_extended_without_suspect'])})"
                        for v in chans.values()
                    )
                    + " |"
                )
        L.append("")
    out = rep.get("explanations_outside") or []
    if out:
        L += [
            "Tried and outside the set:",
            "",
            "| explanation | k | in-sample score | CV score | ΔAIC | paired p | in-sample ΔAICc | why |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for o in out:
            L.append(
                f"| {o['name']} | {o['k']} | {o['in_sample_score']:.3g} | {o['cv_score']:.3g} | "
                f"{o['delta_aic']:.1f} | {o['p_worse']:.2g} | {o['delta_aicc_in_sample']:.1f} | {o['why']} |"
            )
        L.append("")
    for p in rep.get("deciding") or []:
        if p["measurements"]:
            L += [
                f"The measurement that decides between {p['a']} and {p['b']} (where their fitted engines differ "
                f"most in tolerances; at the measured points at most {p['at_measured_loads']:.1f}):",
                "",
            ]
            L += [f"* {m['text']}" for m in p["measurements"]]
            L.append("")
    return L


def _g(x) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.4g}"
