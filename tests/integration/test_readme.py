"""Every command of README.md runs from a fresh clone in a fresh folder.

The commands are read from README.md itself (its ```bash and ```python blocks; nothing here is a
copy of them), and run in order in a temporary folder that looks like a fresh clone: symlinks to
the repository's tracked top-level entries (``training/``, ``docs/``, ...) and nothing else, so
the output folders the commands name (``runs/``, ``results/``, ``report/``, ``data/``) do not
exist yet.  ``marine-fdi`` commands run in-process (``marine_fdi_env.cli.main``, which the console
script's entry point ``console_main`` calls, checked below), with the current directory set to that folder; the
Python blocks run with ``exec``.

What is not run, and why:

* ``python -m pip install ...`` (the install CI has just done) and ``python -m pytest ...`` (this
  test suite);
* commands in running text (backticks outside code blocks): synopses with placeholders such as
  ``--data FILE.csv`` and the 20-minute ``python -m studies.agents.compare``.

To keep the test within about a minute in CI, the arguments below are substituted (nothing
else is changed):

* every shipped suite name after ``--suite``/``--suites`` (and ``all`` there) becomes a *mini
  suite* file: two of the suite's scenarios (the first and the middle one) with the episode
  shortened to ``MINI_DURATION_S`` and the fault onsets and ends scaled into it; the file keeps
  the suite's name, so tables and default output names are those of the real suite;
* ``marine-fdi evaluate`` without ``--suite`` gets ``--suite <mini thesis-v1>`` (its default);
* ``--episodes N`` becomes ``--episodes MINI_EPISODES``;
* ``--backend ray`` becomes ``--backend process`` (the Ray backend starts a Ray instance for
  each command; it is tested, with the same numbers as the process backend, in
  ``test_scale_out.py``).
"""

from __future__ import annotations

import glob
import json
import re
import shlex
import subprocess
from importlib import metadata
from pathlib import Path

from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite
from tests.paths import ROOT

README = ROOT / "README.md"
MINI_DURATION_S = 20.0
MINI_EPISODES = 3
SKIP = ("python -m pip install", "python -m pytest")
OUTPUT_OPTIONS = ("--out",)


def code_blocks(text: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def bash_commands(block: str) -> list[list[str]]:
    """The commands of a bash block as argv lists: continuation lines joined, comments dropped."""
    out = []
    for line in block.replace("\\\n", " ").splitlines():
        argv = shlex.split(line, comments=True)
        if argv:
            out.append(argv)
    return out


def mini_suite(name: str, folder: Path) -> Path:
    """Two scenarios of a shipped suite, shortened (module docstring)."""
    path = folder / f"{name}.json"
    if path.exists():
        return path
    suite = load_suite(name)
    picks = [suite.scenarios[0], suite.scenarios[len(suite.scenarios) // 2]]
    scenarios = []
    for sc in picks:
        d = sc.to_dict()
        k = MINI_DURATION_S / d["duration_s"]
        for f in d["faults"]:
            f["onset_s"] = round(f["onset_s"] * k, 2)
            if f.get("end_s") is not None:
                f["end_s"] = round(f["end_s"] * k, 2)
        d["duration_s"] = MINI_DURATION_S
        scenarios.append(d)
    data = {k: v for k, v in suite.items() if k != "scenarios"}
    data.update(description=f"test subset of {name}: 2 scenarios of {MINI_DURATION_S:g} s", scenarios=scenarios)
    folder.mkdir(exist_ok=True)
    path.write_text(json.dumps(data, indent=1))
    return path


def substitute(argv: list[str], minis: Path) -> list[str]:
    """The documented substitutions (module docstring); globs expanded as the shell does."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in ("--suite", "--suites"):
            out.append(a)
            i += 1
            while i < len(argv) and not argv[i].startswith("--"):
                names = SUITE_NAMES if argv[i] == "all" else [argv[i]]
                out += [str(mini_suite(n, minis)) if n in SUITE_NAMES else n for n in names]
                i += 1
                if a == "--suite":
                    break
            continue
        if a == "--episodes":
            out += [a, str(MINI_EPISODES)]
            i += 2
            continue
        if a == "--backend" and i + 1 < len(argv) and argv[i + 1] == "ray":
            out += [a, "process"]
            i += 2
            continue
        if any(c in a for c in "*?[") and not a.startswith("-"):
            out += sorted(glob.glob(a)) or [a]
        else:
            out.append(a)
        i += 1
    if out[:2] == ["marine-fdi", "evaluate"] and "--suite" not in out:
        out += ["--suite", str(mini_suite("thesis-v1", minis))]
    return out


def fresh_clone(folder: Path) -> None:
    """``folder`` as a fresh clone: links to the tracked top-level entries only."""
    try:
        tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True,
                                 timeout=30).stdout.split()
        names = sorted({t.split("/")[0] for t in tracked})
    except (OSError, subprocess.SubprocessError):  # no git: everything but outputs of earlier runs
        names = [p.name for p in ROOT.iterdir()
                 if not p.name.startswith(".") and p.name not in ("runs", "results", "report", "data")]
    for n in names:
        (folder / n).symlink_to(ROOT / n)


def test_the_console_script_is_the_cli_entry_point():
    eps = metadata.entry_points(group="console_scripts")
    assert [e.value for e in eps if e.name == "marine-fdi"] == ["marine_fdi_env.cli:console_main"]


def test_readme_commands_run_from_a_fresh_clone(tmp_path, monkeypatch, capsys):
    text = README.read_text(encoding="utf-8")
    commands = [c for b in code_blocks(text, "bash") for c in bash_commands(b)]
    assert sum(c[0] == "marine-fdi" for c in commands) >= 15, "README's bash blocks were not found"
    clone = tmp_path / "clone"
    clone.mkdir()
    fresh_clone(clone)
    minis = tmp_path / "mini-suites"
    monkeypatch.chdir(clone)
    ran = []
    for argv in commands:
        line = shlex.join(argv)
        if line.startswith(SKIP):
            continue
        assert argv[0] in ("marine-fdi", "python"), f"README command not covered by this test: {line}"
        assert argv[0] == "marine-fdi", f"README command not covered by this test: {line}"
        args = substitute(argv, minis)
        rc = cli_main(args[1:])
        out, err = capsys.readouterr()
        assert rc == 0, f"README command failed (exit {rc}): {line}\nran: {shlex.join(args)}\n{err[-3000:]}"
        assert "Traceback" not in err, f"{line}\n{err[-3000:]}"
        for opt in OUTPUT_OPTIONS:
            if opt in args:
                target = Path(args[args.index(opt) + 1])
                assert target.exists(), f"{line}: {opt} {target} was not written"
        ran.append(line)
    assert len(ran) >= 15
    # the outputs the README promises
    assert (clone / "runs" / "run.npz").is_file()
    assert (clone / "report" / "report.md").is_file()
    assert (clone / "runs" / "sweep" / "episodes.parquet").is_file()

    # the Python blocks, verbatim, in the same folder
    for block in code_blocks(text, "python"):
        namespace: dict = {"__name__": "__readme__"}
        exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102 - the README's own code
