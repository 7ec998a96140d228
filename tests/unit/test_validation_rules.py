"""The selection's rules in one object (validation/select/rules.py): checked on construction, shared by validate, the
replicas and the study, and consistent with the problem they select on."""

from __future__ import annotations

import dataclasses

import pytest

from marine_fdi_env.cli.validate import validate_main
from marine_fdi_env.validation.select.evidence import BESIDE_VALVE_DEFAULT
from marine_fdi_env.validation.select.rules import SelectionRules
from marine_fdi_env.validation.select.selection import select_causes


def test_the_defaults_are_the_pipelines():
    r = SelectionRules()
    assert (r.max_causes, r.alpha, r.min_gain, r.penalty, r.max_folds) == (4, 0.01, 0.10, 2.0, None)
    assert r.pairs and r.prune and r.exchange and not r.cv_all
    assert r.beside_valve == BESIDE_VALVE_DEFAULT and r.held_out_valves == "schedule"
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.alpha = 0.05  # type: ignore[misc]


@pytest.mark.parametrize(
    "bad, field",
    [
        ({"beside_valve": "leave_one_out"}, "beside_valve"),
        ({"held_out_valves": "median"}, "held_out_valves"),
        ({"alpha": 0.0}, "alpha"),
        ({"alpha_unexplained": 1.5}, "alpha_unexplained"),
        ({"max_causes": -1}, "max_causes"),
        ({"max_folds": 1}, "max_folds"),
    ],
)
def test_a_bad_rule_is_refused_by_name(bad, field):
    with pytest.raises(ValueError, match=field):
        SelectionRules(**bad)
    with pytest.raises(ValueError, match=field):
        SelectionRules().replace(**bad)


def test_an_unknown_rule_is_refused():
    with pytest.raises(TypeError, match="unknown selection rule"):
        SelectionRules().replace(alhpa=0.05)
    with pytest.raises(TypeError, match="unknown selection rule"):
        select_causes(None, alhpa=0.05)


class _Problem:
    held_out_valves = "support"


def test_rules_must_agree_with_the_problems_held_out_valves():
    """The problem is built with the valve rule; rules that say otherwise are refused before any fit."""
    with pytest.raises(ValueError, match="held_out_valves"):
        select_causes(_Problem(), rules=SelectionRules(held_out_valves="schedule"))


def test_validate_refuses_a_bad_level_with_exit_code_2(capsys):
    assert validate_main(["--data", "man_12v32_40_fpp_iso", "--out", "x.json", "--alpha", "2"]) == 2
    assert "--alpha must lie in (0, 1)" in capsys.readouterr().err


@pytest.mark.parametrize(
    "option, value, said",
    [
        ("--max-causes", "-1", "--max-causes must be >= 0, got -1"),
        ("--max-folds", "1", "--max-folds must be >= 2 (unset: leave one point out), got 1"),
        ("--alpha-unexplained", "0", "--alpha-unexplained must lie in (0, 1), got 0.0"),
    ],
)
def test_the_rules_check_the_options_once_and_the_line_names_the_option(capsys, option, value, said):
    """validate keeps no copy of the rules' bounds: SelectionRules refuses, the command says which option, before any
    data is read."""
    assert validate_main(["--data", "no-such-file.csv", "--out", "x.json", option, value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"marine-fdi validate: error: {said}"]


def test_the_marine_fdi_command_parses_validate_once(monkeypatch, capsys):
    """The dispatcher parses validate's options and hands them to the command: one parse per run."""
    from marine_fdi_env.cli import validate
    from marine_fdi_env.cli.main import main

    calls = []
    build = validate.build_parser

    def counted(prog):
        ap = build(prog)
        parse_args = ap.parse_args
        ap.parse_args = lambda argv: calls.append(list(argv)) or parse_args(argv)
        return ap

    monkeypatch.setattr(validate, "build_parser", counted)
    assert main(["validate", "--columns"]) == 0
    assert calls == [["--columns"]] and "speed_<unit>" in capsys.readouterr().out
    assert main(["validate", "--data", "man_12v32_40_fpp_iso", "--out", "x.json", "--alpha", "2"]) == 2
    assert len(calls) == 2 and "--alpha must lie in (0, 1)" in capsys.readouterr().err
    assert main(["validate", "--no-such-option"]) == 2
    assert len(calls) == 3 and "unrecognized arguments: --no-such-option" in capsys.readouterr().err
