"""The classifier trained from Minari datasets alone beside the shipped one, on single-v1.

    python benchmarks/minari_classifier.py [--seed 0] [--minari-root runs/minari/data]
        [--model runs/minari/classifier-minari] [--npz-model DIR] [--suite single-v1] [--write]

1. trains the classifier with the shipped training config (``--hyperparams robust``, seed ``--seed``) from
   Minari datasets only, unless ``--model`` already holds a model::

       marine-fdi train --algo classifier --hyperparams robust --seed 0 \\
           --params data_source=minari minari_root=ROOT --out MODEL

   (every training and calibration set is exported as a Minari dataset under ``ROOT`` and read back with
   ``minari.load_dataset``: about 16 CPU min, most of it simulating the 7168 + 640 episodes);
2. evaluates it and the shipped ``classifier`` of the same training seed on ``--suite`` in lockstep (one
   simulation, the same episodes) and prints one JSON object: each one's isolation accuracy, detection rate
   and false-alarm episodes with the results tables' 95 % intervals (stratified bootstrap), the paired
   difference of isolation accuracy with its interval, whether the two models' weights are equal and
   whether the two agents declared the same at every decision, and the shipped one's isolation accuracy as
   its leaderboard entry holds it (leaderboard/entries/classifier-seedK);
3. ``--npz-model DIR``: a model of the same command trained from the npz datasets with this installation,
   whose weights are compared with both (does reading through Minari change anything; does this
   installation reproduce the shipped weights);
4. ``--write`` keeps the output in ``docs/data/minari_classifier.json`` and writes the result into
   docs/minari.md between its ``minari-result`` markers.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "minari.md"
DATA = ROOT / "docs" / "data" / "minari_classifier.json"
BEGIN, END = "<!-- minari-result:begin", "<!-- minari-result:end -->"


def train(model: Path, minari_root: Path, seed: int) -> dict:
    cmd = [
        sys.executable,
        "-m",
        "marine_fdi_env.cli",
        "train",
        "--algo",
        "classifier",
        "--hyperparams",
        "robust",
        "--seed",
        str(seed),
        "--params",
        "data_source=minari",
        f"minari_root={minari_root}",
        "--out",
        str(model),
    ]
    subprocess.run(cmd, check=True)
    return {"command": " ".join(["marine-fdi"] + cmd[3:])}


def same_weights(a: Path, b: Path) -> bool:
    import torch

    sa = torch.load(a / "model.pt", map_location="cpu", weights_only=False)
    sb = torch.load(b / "model.pt", map_location="cpu", weights_only=False)

    def flat(x, pre=""):
        if isinstance(x, dict):
            for k, v in x.items():
                yield from flat(v, f"{pre}.{k}")
        elif isinstance(x, torch.Tensor):
            yield pre, x

    fa, fb = dict(flat(sa)), dict(flat(sb))
    return fa.keys() == fb.keys() and all(torch.equal(fa[k], fb[k]) for k in fa)


def compare_curves(a: Path, b: Path) -> dict:
    """The two training runs' learning curves (learning_curve.csv): the last epoch through which their
    training and validation losses are equal to 4 significant digits, and the final validation losses."""
    import csv

    def rows(d: Path) -> list[dict]:
        with open(d / "learning_curve.csv", newline="") as f:
            return list(csv.DictReader(f))

    ra, rb = rows(a), rows(b)
    same = 0
    for x, y in zip(ra, rb):
        if any(f"{float(x[k]):.4g}" != f"{float(y[k]):.4g}" for k in ("train_loss", "val_loss")):
            break
        same = int(x["epoch"])
    return {
        "epochs": [len(ra), len(rb)],
        "equal_to_4_digits_through_epoch": same,
        "final_val_loss": [float(ra[-1]["val_loss"]), float(rb[-1]["val_loss"])],
    }


def pct(e: dict) -> str:
    return f"{100 * e['value']:.1f} % ({100 * e['low']:.1f}-{100 * e['high']:.1f})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--minari-root", type=Path, default=ROOT / "runs" / "minari" / "data")
    ap.add_argument("--model", type=Path, default=ROOT / "runs" / "minari" / "classifier-minari")
    ap.add_argument(
        "--npz-model",
        type=Path,
        default=None,
        help="a model of the same command from the npz datasets (marine-fdi train --algo classifier --hyperparams "
        "robust --seed 0 --out DIR), trained with this installation: its weights compared with both",
    )
    ap.add_argument("--suite", default="single-v1")
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--json", action="store_true", help="one JSON line (default: one line per field)")
    args = ap.parse_args()

    from marine_fdi_env.benchmark.evaluate import evaluate_agents
    from marine_fdi_env.benchmark.uncertainty import difference, interval, outcomes

    shipped = ROOT / "training" / "models" / "classifier" / f"seed{args.seed}"
    argv = [a for a in sys.argv[1:] if a != "--json"]
    out: dict = {"command": " ".join(["python", "benchmarks/minari_classifier.py"] + argv), "suite": args.suite}
    out["seed"] = args.seed
    if not (args.model / "agent.json").is_file():
        out["trained"] = train(args.model, args.minari_root, args.seed)
    cfg = json.loads((args.model / "config.json").read_text())
    src = cfg.get("data_source") or {}
    if src.get("format") != "minari":
        raise SystemExit(f"{args.model}: not trained from Minari datasets (its config.json has no data_source minari)")
    out["minari_model"] = {
        "command": cfg.get("command"),
        "dataset_ids": src.get("dataset_ids"),
        "training_episodes": cfg.get("training_episodes"),
        "cpu_minutes": cfg.get("cpu_minutes"),
        "shipped_cpu_minutes": json.loads((shipped / "config.json").read_text()).get("cpu_minutes"),
    }
    out["same_weights_as_shipped"] = same_weights(args.model, shipped)
    out["learning_curves"] = compare_curves(args.model, shipped)
    if args.npz_model is not None:
        npz_cfg = json.loads((args.npz_model / "config.json").read_text())
        if npz_cfg.get("data_source") or npz_cfg.get("seed") != args.seed:
            raise SystemExit(f"{args.npz_model}: not a seed {args.seed} model trained from the npz datasets")
        out["npz_model"] = {
            "command": npz_cfg.get("command"),
            "same_weights_as_minari": same_weights(args.npz_model, args.model),
            "same_weights_as_shipped": same_weights(args.npz_model, shipped),
        }
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        results = evaluate_agents(
            [str(args.model), str(shipped)],
            args.suite,
            [Path(tmp) / "minari.json", Path(tmp) / "shipped.json"],
            progress=False,
        )
    out["evaluate_wall_s"] = round(time.perf_counter() - t0, 1)
    o = [outcomes([r["episodes"]]) for r in results]
    for name, oc, res in zip(("minari", "shipped"), o, results):
        out[name] = {
            m: interval(oc, m).to_dict() for m in ("isolation_accuracy", "detection_rate", "false_alarm_episode_rate")
        }
        out[name]["n_episodes"] = len(res["episodes"])
    out["isolation_difference"] = difference(o[0], o[1], "isolation_accuracy").to_dict()
    out["same_declarations"] = all(
        a["declared_changes"] == b["declared_changes"] for a, b in zip(results[0]["episodes"], results[1]["episodes"])
    )
    entry = ROOT / "leaderboard" / "entries" / f"classifier-seed{args.seed}" / "entry.json"
    if entry.is_file():  # the shipped classifier's result as its leaderboard entry holds it
        block = next(b for b in json.loads(entry.read_text())["suites"] if b["name"] == args.suite)
        out["shipped_entry_isolation"] = block["intervals"]["isolation_accuracy"]
    lo, hi = out["shipped"]["isolation_accuracy"]["low"], out["shipped"]["isolation_accuracy"]["high"]
    out["within_shipped_interval"] = bool(lo <= out["minari"]["isolation_accuracy"]["value"] <= hi)
    emit(out, args.json)
    if args.write:
        DATA.parent.mkdir(parents=True, exist_ok=True)
        DATA.write_text(json.dumps(out, indent=1) + "\n")
        write_doc(out)
    return 0


def write_doc(out: dict) -> None:
    m, s, d, lc = out["minari"], out["shipped"], out["isolation_difference"], out["learning_curves"]
    same = (
        "The two models' weights are equal and they declare the same at every decision of the suite: the Minari "
        "datasets hold the arrays the npz datasets hold, so training from them gives the same model."
        if out["same_weights_as_shipped"] and out["same_declarations"]
        else f"The weights are {'equal' if out['same_weights_as_shipped'] else 'not equal'} and the declarations "
        f"{'the same' if out['same_declarations'] else 'not the same'} at every decision: the two runs' training "
        f"and validation losses agree to 4 digits through epoch {lc['equal_to_4_digits_through_epoch']} of "
        f"{lc['epochs'][1]} and then part (final validation loss {lc['final_val_loss'][0]:.4f} from Minari, "
        f"{lc['final_val_loss'][1]:.4f} shipped).  The Minari datasets decode to the arrays of the npz datasets "
        "bit for bit (tests/integration/test_minari.py)."
        + (
            ""
            if out.get("npz_model")
            else "  Whether the shipped npz run itself still reproduces with this installation (a second 16 CPU "
            "min training, --npz-model) is not measured here."
        )
    )
    npz = out.get("npz_model")
    if npz:
        same += (
            "  The same command from the npz datasets, run with this installation "
            f"(`{npz['command']}`), gives weights "
            + (
                "equal to the Minari run's, bit for bit"
                if npz["same_weights_as_minari"]
                else "not equal to the Minari run's"
            )
            + (" and to the shipped model's" if npz["same_weights_as_shipped"] else ", and not the shipped model's")
            + (
                ": reading the data through Minari changes nothing; the shipped weights are not reproduced on this "
                "CPU (MKL's kernels differ by CPU vendor: training/NOTES.md)."
                if npz["same_weights_as_minari"] and not npz["same_weights_as_shipped"]
                else "."
            )
        )
    e = out.get("shipped_entry_isolation")
    entry_note = (
        f"The shipped one's isolation accuracy as its leaderboard entry holds it "
        f"([classifier-seed{out['seed']}](../leaderboard/entries/classifier-seed{out['seed']}/entry.json)): "
        f"{pct(e)}.  "
        if e
        else ""
    )
    block = (
        f"{BEGIN} (python benchmarks/minari_classifier.py --write) -->\n"
        f"Measured with `{out['command']}` (training seed {out['seed']}; "
        f"[data/minari_classifier.json](data/minari_classifier.json)), on {out['suite']} "
        f"({m['n_episodes']} episodes, both evaluated in lockstep on one simulation; "
        "95 % intervals, the results tables' stratified bootstrap):\n\n"
        "| classifier, seed {0} | isolation accuracy | detection rate | episodes with a false alarm |\n".format(
            out["seed"]
        )
        + "|---|---|---|---|\n"
        + f"| from Minari datasets alone | {pct(m['isolation_accuracy'])} | {pct(m['detection_rate'])} | "
        f"{pct(m['false_alarm_episode_rate'])} |\n"
        f"| shipped (`classifier`) | {pct(s['isolation_accuracy'])} | {pct(s['detection_rate'])} | "
        f"{pct(s['false_alarm_episode_rate'])} |\n\n"
        f"The paired difference of isolation accuracy (Minari - shipped) is {100 * d['value']:+.1f} points "
        f"({100 * d['low']:+.1f} to {100 * d['high']:+.1f}); the Minari-trained classifier's isolation "
        f"{'lies within' if out['within_shipped_interval'] else 'lies outside'} the shipped one's interval.  "
        f"{same}  {entry_note}Its training took {out['minari_model']['cpu_minutes']} CPU min "
        f"({out['minari_model']['training_episodes']} training episodes, the Minari export included, on a 2-core "
        f"machine shared with other jobs; the shipped run {out['minari_model']['shipped_cpu_minutes']}).\n"
        f"{END}"
    )
    text = DOC.read_text(encoding="utf-8")
    pat = re.compile(re.escape(BEGIN) + r".*?" + re.escape(END), flags=re.S)
    if pat.search(text):
        text = pat.sub(lambda _: block, text)
    else:
        text = text.replace("<!-- minari-result: filled from the run below -->", block)
    DOC.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    raise SystemExit(main())
