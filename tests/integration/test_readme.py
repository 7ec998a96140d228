"""Every command of README.md runs verbatim from an empty folder outside the clone.

The commands are read from README.md itself (its ```bash and ```python blocks, in the order they
appear; nothing here is a copy of them), and run in a real empty temporary folder: no link to the
repository, so a command that needs the clone's folders (``training/``, ``docs/``) fails here.
``marine-fdi`` commands run in-process (``marine_fdi_env.cli.main``, which the console script's
entry point ``console_main`` calls, checked below), with the current directory set to that folder;
the Python blocks run with ``exec`` there.

What is not run, and why:

* ``python -m venv``, ``python -m pip install ...`` (the install CI has just done) and ``python -m
  pytest ...`` (this test suite);
* commands in running text (backticks outside code blocks): synopses with placeholders such as
  ``--agent path/to/file.py:Class`` and the 20-minute ``python -m studies.agents.compare``.

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
  ``test_scale_out.py``);
* in the Python blocks, ``total_timesteps=N`` becomes ``MINI_TIMESTEPS`` and ``num_envs=N``
  becomes ``MINI_ENVS`` (the README's PPO trains for minutes: ``benchmarks/sb3_readme.py`` runs
  it verbatim and scores the policy).
"""

from __future__ import annotations

import glob
import json
import re
import shlex
from importlib import metadata
from pathlib import Path

from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite
from marine_fdi_env.cli import main as cli_main
from tests.paths import ROOT

README = ROOT / "README.md"
MINI_DURATION_S = 20.0
MINI_EPISODES = 3
MINI_TIMESTEPS = 512
MINI_ENVS = 16  # 16 engines x the block's 64-step rollout = its mini-batch of 1024: no truncated mini-batch
SKIP = ("python -m venv", "python -m pip install", "python -m pytest")
OUTPUT_OPTIONS = ("--out",)


def code_blocks(text: str, lang: str | None = None) -> list[tuple[str, str]]:
    """``(language, body)`` of the fenced blocks of ``text`` in document order (only ``lang`` if given)."""
    blocks = re.findall(r"^```(\w*)\n(.*?)^```", text, flags=re.S | re.M)
    return [(la, body) for la, body in blocks if lang is None or la == lang]


def python_substituted(block: str) -> str:
    """A Python block with the documented substitutions (module docstring)."""
    block = re.sub(r"total_timesteps=[\d_]+", f"total_timesteps={MINI_TIMESTEPS}", block)
    return re.sub(r"num_envs=\d+", f"num_envs={MINI_ENVS}", block)


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


def test_the_console_script_is_the_cli_entry_point():
    eps = metadata.entry_points(group="console_scripts")
    assert [e.value for e in eps if e.name == "marine-fdi"] == ["marine_fdi_env.cli:console_main"]


def run_command(argv: list[str], minis: Path, capsys) -> tuple[list[str], str]:
    """One README command, substituted, in-process; (the argv run, its stdout)."""
    line = shlex.join(argv)
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
    return args, out


def test_readme_commands_run_verbatim_in_an_empty_folder(tmp_path, monkeypatch, capsys):
    text = README.read_text(encoding="utf-8")
    blocks = code_blocks(text)
    commands = [c for la, b in blocks if la == "bash" for c in bash_commands(b)]
    assert sum(c[0] == "marine-fdi" for c in commands) >= 10, "README's bash blocks were not found"
    assert any("SB3VecEnv" in b for la, b in blocks if la == "python"), "README's SB3 block was not found"
    here = tmp_path / "elsewhere"
    here.mkdir()
    minis = tmp_path / "mini-suites"
    monkeypatch.chdir(here)
    ran = []
    for lang, body in blocks:
        if lang == "python":
            namespace: dict = {"__name__": "__readme__"}
            exec(compile(python_substituted(body), "README.md", "exec"), namespace)  # noqa: S102 - the README's own code
            continue
        if lang != "bash":
            continue
        for argv in bash_commands(body):
            if shlex.join(argv).startswith(SKIP):
                continue
            run_command(argv, minis, capsys)
            ran.append(shlex.join(argv))
    assert len(ran) >= 10
    # the outputs the README promises
    assert (here / "results" / "reference_thesis-v1.json").is_file()
    assert (here / "runs" / "run.npz").is_file()
    assert (here / "report" / "report.md").is_file()
    assert (here / "runs" / "sweep" / "episodes.parquet").is_file()
    assert (here / "my_ppo" / "agent.json").is_file()  # the SB3 block's agent folder
    # the main job again: it shows the results it wrote instead of failing
    _, out = run_command(["marine-fdi", "evaluate"], minis, capsys)
    assert "computed before" in out


def test_the_readme_is_short_and_its_links_resolve():
    text = README.read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) <= 12 * 1024, "README.md over 12 KB: move detail to docs/"
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert len(links) >= 10
    missing = [t for t in links if not t.startswith("http") and not (ROOT / t).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"
    for _, body in code_blocks(text, "bash"):  # no command that works only from the clone's root
        assert "training/models" not in body and "docs/examples" not in body
