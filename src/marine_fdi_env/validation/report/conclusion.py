"""What the data allow: the lead of a validation report (JSON key ``what_the_data_allow``, the Markdown's first
bold line, the command's first output line).

The forward selection adds one cause per step and stops; its end (the report's ``selected_causes`` /
``selected_labels``, kept under those names for existing readers) is one path through the candidates, not
the answer.  The answer is the set of explanations the data do not decide between (:mod:`.explain.summary`):
how many there are, the first-ranked one, and the measurement that would decide between the first two.  This
module reads them from a report and says them first.
"""

from __future__ import annotations

from typing import Any, Mapping

__all__ = ["what_the_data_allow", "lead_markdown", "lead_line", "selection_path_markdown"]


def what_the_data_allow(rep: Mapping[str, Any]) -> dict[str, Any]:
    """The lead of a report (its ``explanations`` and ``deciding`` already in it): ``explanations`` (how many
    the data do not decide between; None when they were not searched, ``--no-explanations``),
    ``first_ranked`` (rank, name, causes), ``deciding_measurement`` (the first measurement that decides
    between #1 and #2, or None), ``selection_path`` (the forward selection's causes and its rank among the
    explanations, None when it is not one of them) and ``text`` (all of it in one sentence)."""
    ex = rep.get("explanations")
    path = list(rep.get("selected_labels") or [])
    if not ex:
        return {
            "explanations": None,
            "first_ranked": None,
            "deciding_measurement": None,
            "selection_path": {"causes": path, "rank": None},
            "text": "explanations not searched (--no-explanations): the forward selection's path names "
            + (" + ".join(path) or "nothing")
            + "; it is one path through the candidates, not a ranking of what the data allow",
        }
    first = ex[0]
    named = next((d for d in ex if d.get("named")), None)
    deciding = None
    for p in rep.get("deciding") or ():
        if p.get("measurements") and str(p.get("a", "")).startswith("#1 "):
            deciding = p["measurements"][0]
            break
    n = len(ex)
    if n > 1:
        text = f"{n} explanations the data do not decide between; first-ranked: #1 {first['name']}"
    else:
        text = f"one explanation, which the data decide for: #1 {first['name']}"
    if deciding is not None:
        text += f"; the measurement that decides between #1 and #2: {_measurement(deciding)}"
    if named is None:
        text += "; the forward selection's path (" + (" + ".join(path) or "nothing") + ") is not among them"
    elif named["rank"] != 1:
        text += f"; the forward selection's path ends at #{named['rank']}"
    else:
        text += "; the forward selection's path ends at #1"
    return {
        "explanations": n,
        "first_ranked": {"rank": 1, "name": first["name"], "causes": list(first.get("labels") or [])},
        "deciding_measurement": deciding,
        "selection_path": {"causes": path, "rank": named["rank"] if named is not None else None},
        "text": text,
    }


def _measurement(m: Mapping[str, Any]) -> str:
    """``CHANNEL at L % load: #1 predicts A, #2 B UNIT (K tolerances apart)``."""
    return (
        f"{m['channel']} at {100 * m['load']:.0f} % load: #1 predicts {m['a_value']:.4g}, #2 {m['b_value']:.4g} "
        f"{m['unit']} ({m['n_tolerances']:.1f} tolerances apart)"
    )


def lead_markdown(rep: Mapping[str, Any]) -> str:
    """The report's first bold line: what the data allow."""
    lead = rep.get("what_the_data_allow") or what_the_data_allow(rep)
    return f"**What the data allow: {lead['text']}.**"


def lead_line(rep: Mapping[str, Any]) -> str:
    """The command's first output line: the dataset, how it was matched, what the data allow."""
    lead = rep.get("what_the_data_allow") or what_the_data_allow(rep)
    return (
        f"{rep['dataset']['name']} ({rep['model']['params']}, matched on {rep['model']['target']}, "
        f"{rep['cv']['scheme']}): what the data allow: {lead['text']}"
    )


def selection_path_markdown(rep: Mapping[str, Any]) -> str:
    """Where the forward selection ended, said as its path (the JSON's ``selected_causes``), not as the answer."""
    lead = rep.get("what_the_data_allow") or what_the_data_allow(rep)
    causes = ", ".join(f"`{x}`" for x in rep.get("selected_labels") or []) or "no cause"
    rank, n = lead["selection_path"]["rank"], lead["explanations"]
    if n is None:
        where = "explanations not searched"
    elif rank is None:
        where = "not among the explanations the data allow"
    elif n == 1:
        where = "the one explanation the data allow"
    else:
        where = f"#{rank} of the {n} explanations the data allow"
    return f"The forward selection's path ends at {causes} ({where}; the JSON's `selected_causes`)."
