"""The Markdown summary of a validation report (:mod:`.build`, ``marine-fdi validate --markdown FILE.md``)."""

from __future__ import annotations

import math
from typing import Any, Mapping

from ..explain.summary import interval as explanation_interval
from ..explain.summary import markdown_lines as explanation_markdown
from .conclusion import lead_markdown, selection_path_markdown

__all__ = ["markdown_summary"]


def _g(x, fmt=".4g") -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def _holdout_lines(h: Mapping[str, Any], how: str) -> list[str]:
    """Markdown: a hold-out's RMSE base → fitted engine per channel (all points, and without the readings the
    loader flagged), and per engine."""
    pe = h.get("per_engine") or {}
    L = [
        f"Hold-out `{h['dataset']}` ({how}), RMSE base → fitted engine; in brackets without the "
        f"{len(h.get('suspect_readings') or [])} reading(s) the loader flags as suspect:",
        "",
        "| engine | " + " | ".join(f"`{c}`" for c in h["channels"]) + " |",
        "|---|" + "---|" * len(h["channels"]),
    ]

    def cell(v):
        b, e = v.get("holdout_rmse_base"), v.get("holdout_rmse_extended")
        bc, ec = v.get("holdout_rmse_base_without_suspect"), v.get("holdout_rmse_extended_without_suspect")
        out = f"{_g(b)} → {_g(e)}"
        if (bc, ec) != (b, e) and bc is not None and ec is not None:
            out += f" ({_g(bc)} → {_g(ec)})"
        return out

    for e, v in pe.items():
        L.append(f"| {e} | " + " | ".join(cell(v[c]) for c in h["channels"]) + " |")
    L.append("| all | " + " | ".join(cell(v) for v in h["channels"].values()) + " |")
    return L + [""]


def markdown_summary(rep: Mapping[str, Any], title: str | None = None) -> str:
    """The report as Markdown tables (what docs/validation.md quotes)."""
    ds, ch = rep["dataset"], rep["channels"]
    L = [f"#### {title or ds['name']}", ""]
    L.append(
        f"Parameter set `{rep['model']['params']}`, {ds['n_points']} points"
        + (f", engines {', '.join(ds['engines'])}" if ds["engines"] else "")
        + f"; operating points matched on {rep['model']['target']} ({', '.join(rep['model']['target_columns'])}); "
        f"cross-validation: {rep['cv']['scheme']} ({rep['cv']['n_folds']} folds)."
    )
    L.append("")
    L.append(lead_markdown(rep))
    L.append("")
    nc = rep.get("not_compared") or []
    if nc:
        L.append("Columns not compared (every column of the file is either a channel below or listed here):")
        L.append("")
        L.append("| column | role | why |")
        L.append("|---|---|---|")
        for r in nc:
            L.append(f"| `{r['column']}` | {r['role']} | {r['what']} |")
        L.append("")
    for o in ds.get("boundary_outliers") or []:
        L.append(
            f"* Recording error left out: `{o['column']}` row {o['row']} reads {_g(o['value'])} (robust z = "
            f"{_g(o['robust_z'], '.1f')}); the row runs at {_g(o['replacement'])}."
        )
    if ds.get("boundary_outliers"):
        L.append("")
    L.append(
        "Base model errors (residual = model - measured, column units; tolerance = the residual scale of the fit):"
    )
    L.append("")
    L.append("| channel | n | tolerance | bias | RMSE | mean rel. error |")
    L.append("|---|---|---|---|---|---|")
    for c, v in ch.items():
        rel = v["mean_abs_rel_error_base"]
        L.append(
            f"| `{c}` | {v['n']} | {_g(v['tolerance'], '.3g')} | {_g(v['bias_base'], '+.4g')} | "
            f"{_g(v['rmse_base'])} | {_g(100 * rel if rel is not None else None, '.1f')} % |"
        )
    L.append("")
    fam = [d for d in rep["discrepancies"] if d["family_significant"]]
    L.append(
        f"Significant discrepancies of the base model ({len(fam)} after the correction for the number of "
        f"channels; {len(rep['discrepancies'])} at p < {rep['settings']['alpha']} per test):"
    )
    L.append("")
    if fam:
        L.append("| channel | kind | region | magnitude | score (x tolerance) | p |")
        L.append("|---|---|---|---|---|---|")
        for d in fam:
            L.append(
                f"| `{d['channel']}` | {d['kind']} | {d['region']} | {_g(d['magnitude'], '+.4g')} "
                f"{d.get('unit', '')} | {_g(d['score'], '.1f')} | {_g(d['p_value'], '.2g')} |"
            )
    else:
        L.append("none")
    L.append("")
    L.append(
        "Candidates (S = mean robust loss per measured cell, about the mean squared error in tolerances; p = "
        "F-test of the cross-validated gain, to be compared with alpha / number of candidates; every fit "
        "includes the calibration of the base within ±6 %):"
    )
    L.append("")
    L.append("| step | combination | free parameters | S in-sample | S cross-validated | gain vs current | p | note |")
    L.append("|---|---|---|---|---|---|---|---|")
    L.append(f"| 0 | base model, calibrated | 0 | | {_g(rep['cv']['score_base'])} | | | |")
    for c in sorted(
        rep["candidates"], key=lambda c: (c["step"], c["cv_score"] if c["cv_score"] is not None else 1e300)
    ):
        if c["cv_score"] is None and not str(c.get("screened", "")).startswith("not eligible"):
            continue
        L.append(
            f"| {c['step']} | {' + '.join(f'`{x}`' for x in c['combination'])} | {c['n_params']} | "
            f"{_g(c['in_sample_score'])} | {_g(c['cv_score'])} | "
            f"{_g(100 * c['gain_vs_current'] if c['gain_vs_current'] is not None else None, '+.1f')} % | "
            f"{_g(c['p_value'], '.2g')} | {c.get('screened', '')} |"
        )
    L.append("")
    L.append(
        "(Candidates whose in-sample fit could not beat the current model by 10 % were not cross-validated; "
        "all are in the JSON report.)"
    )
    L.append("")
    for s in rep["steps"]:
        best = f"best `{s['best']}`" if s.get("best") else "no eligible candidate"
        L.append(f"* step {s['step']}: {best}, {s['decision']}")
    L.append("")
    L.append(selection_path_markdown(rep))
    L.append("")
    for lab, alts in (rep.get("alternatives") or {}).items():
        if alts:
            L.append(
                f"* `{lab}`: the data hardly tell it from "
                + ", ".join(f"`{a['mechanism']}` ({a['why']})" for a in alts)
                + "."
            )
    for lab, notes in (rep.get("cause_notes") or {}).items():
        for n in notes:
            L.append(f"* `{lab}`: {n}.")
    if any(rep.get("alternatives", {}).values()) or rep.get("cause_notes"):
        L.append("")
    if rep["parameters"]:
        prof = next((e.get("profiles") or {} for e in rep.get("explanations") or () if e["named"]), {})
        L.append("| cause | parameter | value | 95 % profile interval | standard error (Fisher) | unit |")
        L.append("|---|---|---|---|---|---|")
        for lab, ps in rep["parameters"].items():
            for k, v in ps.items():
                p = prof.get(f"{lab}.{k}")
                L.append(
                    f"| `{lab}` | `{k}` | {_g(v['value'])} | {explanation_interval(p) if p else '–'} | "
                    f"{_g(v['stderr'], '.2g')} | {v['unit']} |"
                )
        L.append("")
    if rep.get("activity"):
        L.append(
            "Where the valve-type causes act (diverted flow fraction per measured point, file row order; 0 = shut):"
        )
        L.append("")
        L.append("| cause | " + " | ".join(f"point {i + 1}" for i in range(ds["n_points"])) + " |")
        L.append("|---|" + "---|" * ds["n_points"])
        for mid, a in rep["activity"].items():
            L.append(f"| `{mid}` | " + " | ".join(_g(x, ".3f") for x in a) + " |")
        L.append("")
    L += explanation_markdown(rep)
    nuis = rep.get("nuisance", {}).get("extended") or {}
    if nuis:
        L.append(
            "Calibration within the base model's uncertainty (multipliers, prior 1 ± 0.03, box ±0.06): "
            + ", ".join(f"{k} {_g(v, '.3f')}" for k, v in nuis.items())
            + "."
        )
        L.append("")
    ho = "holdout" in rep
    L.append(
        "RMSE per channel (column units): base model as it is; base calibrated within ±6 %, cross-validated; "
        "extended, cross-validated" + ("; and on the hold-out data" if ho else "") + ":"
    )
    L.append("")
    L.append(
        "| channel | touched by a cause | base | base calibrated (CV) | extended (CV) | gain vs base |"
        + (" hold-out base | hold-out extended |" if ho else "")
    )
    L.append("|---|---|---|---|---|---|" + ("---|---|" if ho else ""))
    for c, v in ch.items():
        row = (
            f"| `{c}` | {'yes' if v['touched_by_selected'] else ''} | {_g(v['rmse_base'])} | "
            f"{_g(v['cv_rmse_base'])} | {_g(v['cv_rmse_extended'])} | "
            f"{_g(100 * v['cv_gain'] if v['cv_gain'] is not None else None, '+.0f')} % |"
        )
        if ho:
            row += f" {_g(v.get('holdout_rmse_base'))} | {_g(v.get('holdout_rmse_extended'))} |"
        L.append(row)
    L.append("")
    if ho:
        L += _holdout_lines(rep["holdout"], "at the parameter set's conditions where it recorded none")
    if "holdout_at_fit_conditions" in rep:
        h = rep["holdout_at_fit_conditions"]
        L += _holdout_lines(
            h,
            "assuming " + h["conditions"]["assumption"] + " (an assumption that favours the "
            "fitted engine, which was calibrated at those conditions)",
        )
    if rep["cv"]["folds"]:
        cs = [c for c, v in ch.items() if v["touched_by_selected"]] or list(ch)
        L.append("Per left-out engine (model fitted on the other engines), RMSE base → extended:")
        L.append("")
        L.append("| left out | " + " | ".join(f"`{c}`" for c in cs) + " |")
        L.append("|---|" + "---|" * len(cs))
        for f in rep["cv"]["folds"]:
            L.append(
                f"| {f['fold']} | "
                + " | ".join(
                    f"{_g(f['channels'][c]['rmse_base'])} → {_g(f['channels'][c]['rmse_extended'])}" for c in cs
                )
                + " |"
            )
        L.append("")
    if rep["unexplained"]:
        a_u = rep["settings"].get("alpha_unexplained", rep["settings"]["alpha"])
        left = (
            f"; what a named sensor calibration leaves: p < {a_u} over the calibrated channels"
            if any(u.get("left_by") == "sensor_calibration" for u in rep["unexplained"])
            else ""
        )
        L.append(
            f"Unexplained (family-wise p < {a_u} over the channels{left}, judged against the model refitted "
            "without each channel):"
        )
        L.append("")
        for u in rep["unexplained"]:
            L.append(f"* {u['text']}" + (f" — {u['note']}" if u.get("note") else ""))
        L.append("")
    if rep.get("calibration_scans"):
        L.append(
            "What each named sensor calibration leaves on its channel (the largest step, kink or window beyond its "
            "gain and offset; reported as unexplained when p < the level and it departs by a tolerance):"
        )
        L.append("")
        for col, sc in rep["calibration_scans"].items():
            lo, hi = sc["load_range"]
            p_txt = f"p < {sc['p']:.2g}" if sc.get("p_at_floor") else f"p = {sc['p']:.2g}"
            verdict = "nothing significant left"
            if sc["p"] < sc.get("level", 0.0) and abs(sc["d"]) >= sc["tolerance"]:
                local = [u for u in rep["unexplained"] if u["channel"] == col and u["kind"] == "local"]
                verdict = (
                    "structure left, reported above"
                    if any(u.get("left_by") for u in local)
                    else "structure left; the channel's local finding above already reports it"
                    if local
                    else "structure left"
                )
            L.append(
                f"* `{col}`: a {sc['kind']} at load {lo:.3g}-{hi:.3g}, {sc['d']:+.4g} {sc.get('unit', '')} "
                f"(tolerance {sc['tolerance']:.3g}), {p_txt}, level {sc.get('level', float('nan')):.2g}: {verdict}"
            )
        L.append("")
    if rep["outliers"]:
        L.append("Single-reading outliers (kept in the data; the robust fit down-weights them):")
        L.append("")
        for o in rep["outliers"]:
            L.append(f"* {o['text']}")
        L.append("")
    if rep.get("replicas"):
        from ..select.replicas import markdown_table

        r = rep["replicas"]
        L.append(
            f"Would data like these name the same causes again? {r['settings']['replicas']} replicas per "
            f"hypothesis at this dataset's design (noise: {r['settings']['noise']}; each hypothesis fitted on "
            "the data and taken as the truth, the whole pipeline run on each replica):"
        )
        L.append("")
        L.append(markdown_table(r))
        L.append("")
    return "\n".join(L)


# --------------------------------------------------------------------------------------- CLI
