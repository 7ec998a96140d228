"""Train the decentralised team of every message budget for one seed (:mod:`.decentralised`): simulate
the training and calibration episodes once, train one team per budget on them, calibrate its alarm and
isolation, and save each as a model folder (``training/models/dec-classifier-BUDGET/seedS``).

The CPU time of each budget's model counts the whole simulation of the episodes (``cpu_s_data``, also
when read from the cache) plus its own training and calibration (``cpu_s_train``): the cost of training
that model alone.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import yaml

from marine_fdi_env.envs.observation import feature_names
from marine_fdi_env.multiagent.budgets import get_budget
from marine_fdi_env.multiagent.roles import LOCAL_AGENTS, local_modules

from .artifacts import machine_record, observation_meta, write_curve
from .datasets import training_dataset

__all__ = [
    "load_decentralised_hyperparams",
    "train_decentralised_run",
    "isolation_declaration",
    "recalibrate_isolation",
]

ISOLATION_GRID = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5)

HERE = Path(__file__).resolve().parent


def load_decentralised_hyperparams(entry: str = "decentralised") -> dict:
    """The entry of ``training/hyperparams/decentralised.yml``."""
    data = yaml.safe_load((HERE / "hyperparams" / "decentralised.yml").read_text())
    if entry not in data:
        raise ValueError(f"decentralised.yml: no entry {entry!r} (has {', '.join(data)})")
    return dict(data[entry])


def train_decentralised_run(
    seed: int, hp: dict, out_root: Path | None, *, budgets=None, use_cache: bool = True, command: str = "", log=print
) -> list[dict]:
    """Train every budget of ``hp`` (or ``budgets``) with ``seed``; returns the configs (saved to
    ``out_root/NAME-BUDGET/seedS`` unless ``out_root`` is None)."""
    import torch

    from .classifier import calibrate_threshold
    from .decentralised import episode_probabilities, local_inputs, train_decentralised
    from .features import AgentFeatures, transform_episodes
    from .train import training_specs

    hp = dict(hp)
    torch.set_num_threads(int(hp.get("torch_threads", 1)))
    datasets, calibration, iso_calibration = training_specs(hp, seed)
    locals_ = str(hp.get("locals", "learned"))
    features = AgentFeatures(feature_names(False), **hp["features"])
    in_names = features.input_names()
    if locals_ == "thesis":  # the inputs are the 19 fired features, local l's are its modules'
        in_names = [n for n in feature_names(False) if n.endswith(".fired")]
        fired = np.array([feature_names(False).index(n) for n in in_names])
        columns = {
            a: np.array([j for j, n in enumerate(in_names) if n.rpartition(".")[0] in local_modules(a)])
            for a in LOCAL_AGENTS
        }
    else:
        columns = {a: local_inputs(in_names, a) for a in LOCAL_AGENTS}
    data_cpu = 0.0
    c_load = time.process_time()

    def load(spec):
        nonlocal data_cpu
        arr, cpu, fresh = training_dataset(spec, use_cache, log)
        data_cpu += cpu
        if locals_ == "thesis":
            arr["obs"] = (arr["obs"][..., fired] >= 0.5).astype(np.float32)  # the decision vectors
        else:
            arr["obs"] = transform_episodes(features, arr["obs"])  # the locals' own preprocessing, computed once
        return arr

    parts = [load(s) for s in datasets]
    data = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "active", "valid")}
    del parts
    cal, iso = load(calibration), load(iso_calibration)
    prep_cpu = time.process_time() - c_load  # loading and transforming (the exports' CPU is data_cpu)
    configs = []
    for b in budgets or hp["budgets"]:
        budget = get_budget(b)
        c0 = time.process_time()
        res = train_decentralised(
            data["obs"],
            data["active"],
            data["valid"],
            budget,
            columns,
            seed=seed,
            hidden_local=int(hp["hidden_local"]),
            hidden_global=int(hp["hidden_global"]),
            epochs=int(hp["epochs"]),
            batch_size=int(hp["batch_size"]),
            lr=float(hp["lr"]),
            weight_decay=float(hp["weight_decay"]),
            alarm_weight=float(hp["alarm_weight"]),
            locals_=locals_,
            log=log,
        )
        alarm = calibrate_threshold(
            episode_probabilities(res.net, cal["obs"])[..., -1],
            cal["valid"],
            target_per_hour=float(hp["target_false_alarms_per_hour"]),
            margin=float(hp["margin_logodds"]),
        )
        iso_threshold, conf, search = isolation_declaration(
            episode_probabilities(res.net, iso["obs"]), iso["active"], iso["valid"], hp
        )
        train_cpu = time.process_time() - c0
        name = f"{hp['name']}-{budget.name}"
        log(
            f"{name} seed {seed}: alarm threshold {alarm['alarm_threshold']:.4f}, "
            f"isolation quantile {conf['quantile']:.3f}"
        )
        cfg = {
            "name": name,
            "algo": str(hp["name"]),
            "seed": seed,
            "budget": budget.to_dict(),
            "bits_per_decision": budget.bits_per_decision,
            "hyperparams": hp,
            "datasets": datasets,
            "calibration_sets": [calibration, iso_calibration],
            "architecture": {
                "kind": "local GRU encoders + GRU global decoder"
                if locals_ == "learned"
                else "the thesis's decision vectors + GRU global decoder",
                "locals": locals_,
                "hidden_local": int(hp["hidden_local"]),
                "hidden_global": int(hp["hidden_global"]),
                "columns": {a: c.tolist() for a, c in columns.items()},
                "inputs": in_names,
            },
            "features": {k: v for k, v in features.to_dict().items() if k not in ("mean", "scale")},
            "declaration": {
                "alarm_threshold": alarm["alarm_threshold"],
                "isolation_threshold": iso_threshold,
                "calibration": alarm,
                "isolation_threshold_search": search,
                "isolation_conformal": conf,
            },
            "observation": observation_meta(),
            "training_episodes": int(len(data["obs"])),
            "n_parameters": int(sum(p.numel() for p in res.net.parameters())),
            "cpu_s_data": round(data_cpu + prep_cpu, 1),
            "cpu_s_train": round(train_cpu, 1),
            "cpu_s": round(data_cpu + prep_cpu + train_cpu, 1),
            "cpu_minutes": round((data_cpu + prep_cpu + train_cpu) / 60.0, 2),
            "command": command,
            "machine": machine_record(),
        }
        if out_root is not None:
            out = Path(out_root) / name / f"seed{seed}"
            out.mkdir(parents=True, exist_ok=True)
            torch.save(res.net.state_dict(), out / "model.pt")
            write_curve(out / "learning_curve.csv", res.curve)
            cfg["model_bytes"] = (out / "model.pt").stat().st_size
            write_team_folder(out, cfg)
        configs.append(cfg)
    return configs


def write_team_folder(out: Path, cfg: dict) -> None:
    """A team's seed folder beside its ``model.pt``: ``config.json``, ``agent.json`` naming
    :class:`~.agents.DecentralisedAgent`, and the parent folder's ``agent.json`` (seed 0 by default) if missing."""
    (out / "config.json").write_text(json.dumps(cfg, indent=1) + "\n")
    agent = {"class": "marine_fdi_env.training.agents:DecentralisedAgent"}
    (out / "agent.json").write_text(json.dumps(agent, indent=1) + "\n")
    top = out.parent / "agent.json"
    if not top.exists():
        top.write_text(json.dumps(dict(agent, kwargs={"model": "seed0"}), indent=1) + "\n")


def isolation_declaration(
    probs: np.ndarray, active: np.ndarray, valid: np.ndarray, hp: dict
) -> tuple[float, dict, dict]:
    """The isolation threshold and its conformal quantile from held-in faulty episodes (``probs`` (E, T, 27)).

    ``isolation_threshold: calibrated``: the threshold of :data:`ISOLATION_GRID` whose fault set (the faults
    at or above it) equals the active faults at the last decision of the most episodes (the highest on a
    tie); a number: that threshold.  Then the split-conformal quantile at that threshold
    (:func:`~.classifier.calibrate_isolation`).  Returns (threshold, conformal record, search record)."""
    from .classifier import N_FAULTS, calibrate_isolation

    search: dict = {"rule": "fixed"}
    if hp["isolation_threshold"] == "calibrated":
        last = valid.sum(axis=1) - 1
        rows = np.arange(len(probs))
        faulty = active[rows, last].any(axis=1) & (last >= 0)
        p, truth = probs[rows, last, :N_FAULTS][faulty], active[rows, last][faulty]
        exact = [float(np.mean(((p >= t) == truth).all(axis=1))) if len(p) else 0.0 for t in ISOLATION_GRID]
        best = max(range(len(ISOLATION_GRID)), key=lambda i: (exact[i], ISOLATION_GRID[i]))
        threshold = float(ISOLATION_GRID[best])
        search = {"rule": "most exact sets at the last decision", "grid": list(ISOLATION_GRID), "exact": exact}
    else:
        threshold = float(hp["isolation_threshold"])
    conf = calibrate_isolation(probs, active, valid, alpha=float(hp["isolation_alpha"]), isolation_threshold=threshold)
    return threshold, conf, search


def recalibrate_isolation(folder: Path, hp: dict, *, use_cache: bool = True, log=print) -> dict:
    """Calibrate a trained team's isolation again with ``hp`` (:func:`isolation_declaration` on its own
    isolation-calibration episodes) and rewrite its ``config.json``: what training with ``hp`` gives,
    the networks unchanged."""
    import torch

    from .decentralised import DecentralisedNet, episode_probabilities
    from .features import AgentFeatures, transform_episodes

    folder = Path(folder)
    cfg = json.loads((folder / "config.json").read_text())
    arch = cfg["architecture"]
    locals_ = arch.get("locals", "learned")
    columns = {a: np.asarray(c, dtype=np.int64) for a, c in arch["columns"].items()}
    net = DecentralisedNet(
        get_budget(cfg["budget"]["name"]), columns, int(arch["hidden_local"]), int(arch["hidden_global"]), locals_
    )
    net.load_state_dict(torch.load(folder / "model.pt", map_location="cpu", weights_only=True))
    net.eval()
    iso, _, _ = training_dataset(cfg["calibration_sets"][1], use_cache, log)
    if locals_ == "thesis":
        fired = np.array([feature_names(False).index(n) for n in arch["inputs"]])
        x = (iso["obs"][..., fired] >= 0.5).astype(np.float32)
    else:
        x = transform_episodes(AgentFeatures(feature_names(False), **hp["features"]), iso["obs"])
    threshold, conf, search = isolation_declaration(episode_probabilities(net, x), iso["active"], iso["valid"], hp)
    cfg["hyperparams"]["isolation_threshold"] = hp["isolation_threshold"]
    cfg["declaration"].update(
        isolation_threshold=threshold, isolation_threshold_search=search, isolation_conformal=conf
    )
    (folder / "config.json").write_text(json.dumps(cfg, indent=1) + "\n")
    log(f"{folder}: isolation threshold {threshold}, conformal quantile {conf['quantile']:.3f}")
    return cfg


def derive_thesis_pairs(folder: Path, out_root: Path, *, command: str = "", log=print) -> Path:
    """A model folder of ``folder``'s team with the thesis's logic for fault pairs
    (:class:`~.decentralised_agent.ThesisPairsGlobal`): the same weights and calibration, ``declaration.pairs``
    set to ``thesis``, saved as ``out_root/NAME+thesis-pairs/seedS``; nothing is trained.  ``ValueError``
    unless the team's messages are the thesis's decision vectors."""
    import hashlib
    import shutil

    folder = Path(folder)
    cfg = json.loads((folder / "config.json").read_text())
    if cfg["architecture"].get("locals") != "thesis":
        raise ValueError(f"{folder}: the thesis's logic for pairs needs the thesis's locals (dec-global teams)")
    name = f"{cfg['name']}+thesis-pairs"
    out = Path(out_root) / name / f"seed{cfg['seed']}"
    out.mkdir(parents=True, exist_ok=True)
    for f in ("model.pt", "learning_curve.csv"):
        shutil.copyfile(folder / f, out / f)
    cfg["name"] = name
    cfg["declaration"]["pairs"] = "thesis"
    cfg["derived_from"] = {
        "folder": f"{folder.parent.name}/{folder.name}",
        "model_sha256": hashlib.sha256((folder / "model.pt").read_bytes()).hexdigest(),
        "training_command": cfg.get("command", ""),
    }
    cfg["command"] = command
    write_team_folder(out, cfg)
    log(f"{out}: {folder}'s team, the thesis's logic for pairs")
    return out
