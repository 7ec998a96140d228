"""``marine-fdi score-raw``: score per-sample diagnoses in the LiU-ICE / DX'25 layout
(:mod:`.rawdata`) with the benchmark's metrics and the DX per-sample ones.

    marine-fdi score-raw --suite thesis-v1 --predictions PRED [--data RAW] [--out results.json]

**Checks.**  Every scenario of the suite needs ``PRED/output_<scenario>.csv`` with exactly the
columns of :data:`~.rawdata.OUTPUT_COLUMNS` (any order; ``fx_rank``, the kits' name, is accepted
for ``unknown_rank``), one row per data sample with the data's ``sample_time`` (to 1e-6 s, the
kits' ``%f`` output), finite numbers, ``detection`` 0 or 1, ``computation_time`` >= 0, ranks
>= 0 summing to 1 when ``detection`` = 1 and to 0 when it is 0, within 1e-4 (27 ranks printed
with 6 decimals, as the kits do, are off by up to 27 x 5e-7 = 1.4e-5).  A violation is an
error naming the file, the line and row, and the column.  Without ``--data`` every scenario is
expected to run its whole duration (no engine failure; true of every shipped suite).

**DX metrics** (the DX'25 LiU-ICE definitions, pooled over the samples of all scenarios):

* ``true_detection_rate`` (TDR): share of the samples with a fault active at which
  ``detection`` = 1;
* ``false_alarm_rate`` (FAR): share of the samples with no fault active at which ``detection`` =
  1 (also after a fault that ended: literally "no fault in the system");
* ``fault_isolation_accuracy`` (FIA): mean, over the samples with a fault active and ``detection``
  = 1, of the rank given to the true diagnosis (the sum of the ranks of the active faults when
  several are active).

**Benchmark metrics** (:mod:`.metrics`) from an episode record per scenario: every sample is a
decision (``decision_period_s`` = the sample time), the alarm is ``detection``, the declared set
is the faults whose rank is at least half the row's largest rank (over the faults and
``unknown``), and ``belief_on_truth`` is the mean over the samples with a fault active of the
ranks on the active faults.  Documented differences from ``marine-fdi evaluate`` for the same
agent (whose per-decision beliefs ``predict-raw`` writes as per-sample ranks):

1. resolution: delays are measured on the 0.01 s sample grid, not on the decision grid.  An
   alarm raised at a decision is the same sample, so the delays agree exactly, except when an
   alarm already on at a fault's onset counts from the onset sample instead of the next decision
   (earlier by less than one decision period);
2. ``belief_on_truth`` averages over samples, not decisions: the samples between an onset and the
   next decision hold the previous declaration (at most one decision period per onset), and the
   ranks are normalised over the faults and ``unknown`` only (a belief on ``no_fault`` is lost,
   and so is any belief below the alarm threshold: the ranks are 0 without detection);
3. the declared set equals the environment's (beliefs >= 0.5) whenever the agent's largest belief
   is 1, as for every shipped agent's declarations; otherwise it is scale free (>= half the largest);
4. ``compute_s_per_sample`` is the diagnoser's own ``computation_time``; ``mean_return`` is 0 (no
   reward without the environment);
5. the data include the sample at t = 0, which the environment's first decision does not use.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from .._version import __version__
from ..engine.faults import FAULT_IDS, fault_class, window_time
from ..errors import DataFileError
from .metrics import compute_metrics
from .rawdata import OUTPUT_COLUMNS, RANK_COLUMNS, read_manifest, scenario_stem
from .records import episode_record
from .suites import load_suite

__all__ = ["score_raw", "read_predictions", "dx_metrics", "RANK_SUM_TOL", "TIME_TOL_S"]

RANK_SUM_TOL = 1e-4
TIME_TOL_S = 1e-6
_N_FAULTS = len(FAULT_IDS)
_ALIASES = {"fx_rank": "unknown_rank"}
_MAX_ERRORS = 10


def _where(path: Path, r: int, t: float | None = None) -> str:
    tt = "" if t is None else f", sample_time {t:.6g}"
    return f"{path}: line {r + 2} (sample row {r}{tt})"


def read_predictions(path: Path, n_expected: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(computation_time (n,), detection (n,) int, ranks (n, 27)) of one output file, validated."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise DataFileError(f"{path}: not readable ({e})") from None
    lines = text.splitlines()
    if not lines:
        raise DataFileError(f"{path}: line 1: empty file, expected the header {','.join(OUTPUT_COLUMNS)}")
    header = [_ALIASES.get(h.strip(), h.strip()) for h in lines[0].split(",")]
    missing = [c for c in OUTPUT_COLUMNS if c not in header]
    extra = [h for h in header if h not in OUTPUT_COLUMNS]
    dup = sorted({h for h in header if header.count(h) > 1})
    if missing or extra or dup:
        what = "; ".join(
            x
            for x in (
                f"missing column(s) {', '.join(repr(c) for c in missing[:5])}" if missing else "",
                f"unexpected column(s) {', '.join(repr(c) for c in extra[:5])}" if extra else "",
                f"repeated column(s) {', '.join(repr(c) for c in dup)}" if dup else "",
            )
            if x
        )
        raise DataFileError(
            f"{path}: line 1 (header): {what}; the columns are {', '.join(OUTPUT_COLUMNS[:4])}, ..., "
            f"{OUTPUT_COLUMNS[-1]} (see docs/raw_data.md)"
        )
    body = [ln for ln in lines[1:]]
    while body and not body[-1].strip():
        body.pop()
    try:
        arr = np.loadtxt(io.StringIO("\n".join(body)), delimiter=",", ndmin=2) if body else np.zeros((0, len(header)))
        if arr.shape[1] != len(header):
            raise ValueError("field count")
    except ValueError:
        arr = _parse_slowly(path, body, header)
    order = [header.index(c) for c in OUTPUT_COLUMNS]
    arr = arr[:, order]
    n = len(arr)
    if n != n_expected:
        raise DataFileError(
            f"{path}: line {min(n, n_expected) + 2}: has {n} sample rows, the data have {n_expected} "
            "(one output row per data sample)"
        )
    _check_values(path, arr, dt)
    return arr[:, 1], arr[:, 2].astype(np.int64), arr[:, 3:]


def _parse_slowly(path: Path, body: list[str], header: list[str]) -> np.ndarray:
    out = np.empty((len(body), len(header)))
    for r, ln in enumerate(body):
        fields = ln.split(",")
        if len(fields) != len(header):
            raise DataFileError(f"{_where(path, r)}: has {len(fields)} fields, the header has {len(header)}")
        for j, f in enumerate(fields):
            try:
                out[r, j] = float(f)
            except ValueError:
                raise DataFileError(f"{_where(path, r)}, column {header[j]!r}: not a number ({f.strip()!r})") from None
    return out


def _check_values(path: Path, arr: np.ndarray, dt: float) -> None:
    n = len(arr)
    if not n:
        return
    t_exp = dt * np.arange(n)
    bad_rows: list[tuple[int, str, str]] = []  # (row, column, what): the first of each check
    fin = np.isfinite(arr)
    if not fin.all():
        r, j = np.argwhere(~fin)[0]
        bad_rows.append((r, OUTPUT_COLUMNS[j], f"not a finite number ({arr[r, j]!r})"))
    a = np.where(fin, arr, 0.0)
    checks = [
        (
            np.abs(a[:, 0] - t_exp) > TIME_TOL_S,
            "sample_time",
            lambda r: f"{a[r, 0]!r}, the data sample is at {t_exp[r]:.6f} s",
        ),
        (a[:, 1] < 0, "computation_time", lambda r: f"must be >= 0, got {a[r, 1]!r}"),
        (~np.isin(a[:, 2], (0.0, 1.0)), "detection", lambda r: f"must be 0 or 1, got {a[r, 2]!r}"),
    ]
    for mask, col, msg in checks:
        m = mask & fin.all(axis=1)
        if m.any():
            r = int(np.argmax(m))
            bad_rows.append((r, col, msg(r)))
    ranks = a[:, 3:]
    neg = (ranks < 0) & fin[:, 3:]
    if neg.any():
        r, j = np.argwhere(neg)[0]
        bad_rows.append((r, RANK_COLUMNS[j], f"ranks must be >= 0, got {ranks[r, j]!r}"))
    s = ranks.sum(axis=1)
    want = np.where(a[:, 2] == 1.0, 1.0, 0.0)
    m = (np.abs(s - want) > RANK_SUM_TOL) & fin.all(axis=1) & np.isin(a[:, 2], (0.0, 1.0))
    if m.any():
        r = int(np.argmax(m))
        bad_rows.append(
            (
                r,
                f"{RANK_COLUMNS[0]} ... {RANK_COLUMNS[-1]}",
                f"the ranks sum to {s[r]:.6g}, must be {want[r]:g} when detection = {int(a[r, 2])} "
                f"(tolerance {RANK_SUM_TOL:g})",
            )
        )
    if bad_rows:
        r, col, what = min(bad_rows, key=lambda x: x[0])
        raise DataFileError(f"{_where(path, int(r), float(t_exp[r]))}, column {col!r}: {what}")


def _active(faults, t: np.ndarray) -> np.ndarray:
    """(n, 26) faults active at the sample times (the simulator's activity windows)."""
    act = np.zeros((len(t), _N_FAULTS), dtype=bool)
    col = {f: j for j, f in enumerate(FAULT_IDS)}
    inf = np.inf
    for f in faults:
        w = window_time(
            t,
            f.onset_s,
            inf if f.end_s is None else f.end_s,
            inf if f.period_s is None else f.period_s,
            1.0 if f.duty is None else f.duty,
        )
        act[:, col[f.fault_id]] |= ~np.isnan(w)
    return act


def _declared(det: np.ndarray, ranks: np.ndarray) -> np.ndarray:
    top = ranks.max(axis=1, keepdims=True)
    return (det[:, None] == 1) & (ranks[:, :_N_FAULTS] > 0) & (ranks[:, :_N_FAULTS] >= 0.5 * top)


def _record(sc, entry: dict, suite: str, agent: str, dt: float, comp, det, ranks, act) -> dict:
    n = len(det)
    t = dt * np.arange(n)
    decl = _declared(det, ranks)
    key = np.concatenate([det[:, None].astype(bool), decl], axis=1)
    change = np.flatnonzero(np.concatenate([[True], (key[1:] != key[:-1]).any(axis=1)]))
    trace = [[float(t[k]), [FAULT_IDS[j] for j in np.flatnonzero(decl[k])], bool(det[k])] for k in change]
    on = act.any(axis=1)
    bot = []
    if on.any():
        share = (ranks[:, :_N_FAULTS] * act).sum(axis=1)[on]
        bot = [[float(t[np.argmax(on)]), float(share.mean())]]
    return episode_record(
        sc,
        suite,
        agent,
        duration_s=float(t[-1]) if n else 0.0,
        decision_period_s=dt,
        n_samples=n,
        declared_changes=trace,
        belief_on_truth=bot,
        failure=entry.get("engine_failure"),
        compute_s=float(comp.sum()),
    )


def dx_metrics(parts: list[dict]) -> dict:
    """TDR, FAR, FIA pooled over samples (module docstring), from per-scenario sample counts."""
    tot = {k: sum(p[k] for p in parts) for k in ("fault", "fault_detected", "free", "free_alarm", "rank_true")}
    r = lambda a, b: (a / b) if b else None  # noqa: E731
    return {
        "true_detection_rate": r(tot["fault_detected"], tot["fault"]),
        "false_alarm_rate": r(tot["free_alarm"], tot["free"]),
        "fault_isolation_accuracy": r(tot["rank_true"], tot["fault_detected"]),
        "n_fault_samples": tot["fault"],
        "n_fault_free_samples": tot["free"],
    }


def _dx_counts(det, ranks, act) -> dict:
    on = act.any(axis=1)
    alarm = det == 1
    return {
        "fault": int(on.sum()),
        "fault_detected": int((on & alarm).sum()),
        "free": int((~on).sum()),
        "free_alarm": int((~on & alarm).sum()),
        "rank_true": float((ranks[:, :_N_FAULTS] * act).sum(axis=1)[on & alarm].sum()),
    }


def score_raw(
    suite_name: str,
    pred_dir: "str | Path",
    *,
    data_dir: "str | Path | None" = None,
    agent: str | None = None,
    progress: bool = True,
) -> dict:
    """Validate and score a predictions folder; returns a results object (as evaluate's, plus
    ``dx_metrics``)."""
    from ..progress import progress_bar

    suite = load_suite(suite_name)
    pred = Path(pred_dir)
    if not pred.is_dir():
        raise ValueError(f"--predictions: no such folder {str(pred)!r}")
    dt = float(suite["env"].get("dt", 0.01))
    entries: dict[str, dict] = {}
    seed_offset = 0
    if data_dir is not None:
        man = read_manifest(data_dir)
        if man["suite"] != suite.name:
            raise ValueError(f"--data {data_dir} holds suite {man['suite']!r}, not {suite.name!r}")
        dt = float(man["sample_time_s"])
        seed_offset = int(man.get("seed_offset", 0))
        gt = json.loads((Path(data_dir) / "ground_truth.json").read_text())
        entries = {e["scenario_id"]: e for e in gt["scenarios"]}
    meta_file = pred / "predictions.json"
    meta = json.loads(meta_file.read_text()) if meta_file.is_file() else {}
    agent = agent or meta.get("agent") or pred.name
    if data_dir is None:
        seed_offset = int(meta.get("seed_offset", 0))
    from .evaluate import offset_scenario

    scenarios = [offset_scenario(s, seed_offset) for s in suite.scenarios]
    files = {s.scenario_id: pred / f"output_{scenario_stem(s.scenario_id)}.csv" for s in scenarios}
    missing = [f.name for f in files.values() if not f.is_file()]
    if missing:
        more = f" and {len(missing) - _MAX_ERRORS} more" if len(missing) > _MAX_ERRORS else ""
        raise ValueError(
            f"{pred}: {len(missing)} of {len(files)} scenarios have no predictions file: "
            f"{', '.join(missing[:_MAX_ERRORS])}{more}"
        )
    errors: list[str] = []
    records, parts = [], []
    bar = progress_bar(len(scenarios), 0, "score-raw", progress, "scenario")
    try:
        for sc in scenarios:
            e = entries.get(sc.scenario_id, {})
            n = int(e.get("n_samples", int(round(sc.duration_s / dt)) + 1))
            try:
                comp, det, ranks = read_predictions(files[sc.scenario_id], n, dt)
            except DataFileError as err:
                errors.append(str(err))
                bar.advance(1)
                continue
            act = _active(sc.faults, dt * np.arange(n))
            records.append(_record(sc, e, suite.name, agent, dt, comp, det, ranks, act))
            c = _dx_counts(det, ranks, act)
            classes = {fault_class(f.fault_id) for f in sc.faults}
            c["class"] = "none" if not classes else (classes.pop() if len(classes) == 1 else "mixed")
            parts.append(c)
            bar.advance(1)
    finally:
        bar.close()
    if errors:
        more = f"\n... and {len(errors) - _MAX_ERRORS} more files" if len(errors) > _MAX_ERRORS else ""
        raise ValueError(f"{len(errors)} bad predictions file(s):\n" + "\n".join(errors[:_MAX_ERRORS]) + more)
    by_class: dict[str, list] = {}
    for p in parts:
        by_class.setdefault(p["class"], []).append(p)
    dx = dx_metrics(parts)
    dx["by_class"] = {k: dx_metrics(v) for k, v in by_class.items()}
    return {
        "agent": agent,
        "agent_spec": f"predictions:{pred}",
        "suite": suite.name,
        "suite_version": suite["version"],
        "seed_offset": seed_offset,
        "env": suite["env"],
        "package_version": __version__,
        "scored_by": "marine-fdi score-raw",
        "n_scenarios": len(records),
        "metrics": compute_metrics(records),
        "dx_metrics": dx,
        "episodes": records,
    }


def dx_table(results: list[dict]) -> str:
    """Markdown table of the DX metrics."""
    pct = lambda v: "–" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    lines = [
        "| Suite | Agent | TDR | FAR | FIA | fault samples | fault-free samples |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in results:
        m = r["dx_metrics"]
        lines.append(
            f"| {r['suite']} | {r['agent']} | {pct(m['true_detection_rate'])} | {pct(m['false_alarm_rate'])} | "
            f"{pct(m['fault_isolation_accuracy'])} | {m['n_fault_samples']} | {m['n_fault_free_samples']} |"
        )
    return "\n".join(lines) + "\n"
