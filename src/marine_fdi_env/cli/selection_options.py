"""The command-line options of the selection's valve rules, shared by ``marine-fdi validate``, ``marine-fdi
replicas`` and the open-world study, and the :class:`~marine_fdi_env.validation.select.rules.SelectionRules` they
give."""

from __future__ import annotations

import argparse
import dataclasses

from ..errors import UsageError
from ..validation.fit.problem import HELD_OUT_VALVES
from ..validation.select.evidence import BESIDE_VALVE, BESIDE_VALVE_DEFAULT
from ..validation.select.rules import RuleError, SelectionRules

__all__ = ["add_valve_options", "rules_from_args"]


def rules_from_args(args: argparse.Namespace) -> SelectionRules:
    """The :class:`SelectionRules` of the parsed options: each rule a command has as an option (``--max-causes``
    for ``max_causes``) takes the option's value, the others their defaults.  The rules check themselves; a rule
    out of its range is a :class:`~marine_fdi_env.errors.UsageError` naming the option."""
    given = {f.name: getattr(args, f.name) for f in dataclasses.fields(SelectionRules) if hasattr(args, f.name)}
    try:
        return SelectionRules(**given)
    except RuleError as e:
        raise UsageError(f"--{e.rule.replace('_', '-')} {e.requirement}") from None


def add_valve_options(ap: argparse.ArgumentParser) -> None:
    """``--held-out-valves`` and ``--beside-valve``: how valves are cross-validated and how a cause beside a valve
    earns its place (:class:`~marine_fdi_env.validation.select.rules.SelectionRules`)."""
    ap.add_argument(
        "--held-out-valves",
        default="schedule",
        choices=HELD_OUT_VALVES,
        help="how cross-validation predicts a valve's opening at a left-out point: the schedule through "
        "the other points (default), or where the fit on all points opens it, "
        "interpolated among the open points (support: an ablation; it names a second mechanism "
        "beside a valve too often; docs/figures/validation/held_out_valves/), or estimated as a "
        "state from the left-out point's other channels, each channel predicted without its own "
        "reading (state: an ablation; it lets model error in as a valve or beside one; "
        "docs/figures/validation/held_out_state/)",
    )
    ap.add_argument(
        "--beside-valve",
        default=BESIDE_VALVE_DEFAULT,
        choices=BESIDE_VALVE,
        help="how a cause joining a model with a valve earns its place: a physical mechanism by its "
        "in-sample gain and F-test, the exchange step's swap of a physical cause for a sensor "
        "calibration by its in-sample gain, and a pair holding the step's best single valve by its "
        "second member's in-sample evidence beside the valve (in_sample_pairs, the default: the "
        "valve's held-out openings dilute and scatter the cross-validated score); as that but with "
        "a cross-validated score that must be lower at all and pairs by their penalised score "
        "(in_sample_exchange); the physical mechanism only (in_sample); or by the cross-validated gain "
        "and F-test as every other candidate (cross_validated); which rule made which study file: "
        "docs/validation.md",
    )
