"""Agents by name: the non-learned baselines and the shipped trained models (``marine-fdi agents``).

Nothing here lists the models: they are found where they are installed.

* **Baselines**: :data:`BUILTIN_AGENTS` (name -> ``module:Class`` in the package
  ``marine_fdi_env.baselines``).
* **Models**: every folder of ``MODELS_PACKAGE/MODELS_FOLDER/`` (package data) holding an
  ``agent.json``.  Its name is the ``name`` of its ``config.json`` (the name the agent reports in
  results), else the folder's name; the folder's name is accepted too.  A new model folder is a
  new agent name, with no code change.  A model trained with several seeds keeps one sub-folder per
  seed (``seed0``, ...) and an ``agent.json`` naming the default one (``"kwargs": {"model":
  "seed0"}``); every seed runs by its path (``training/models/classifier/seed1``).

:data:`MODELS_PACKAGE` is the only place that knows where the training code is installed
(``marine_fdi_env.training``, from the repository folder ``training/``), and the targets of
``BUILTIN_AGENTS`` the only place for the baselines (``marine_fdi_env.baselines``, from
``baselines/``).  These are looked up by name at run time: the environments never import an
agent's code in their source (``python -m marine_fdi_env.info --imports``).
"""

from __future__ import annotations

import importlib.util
from dataclasses import asdict, dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from ..jsonfile import read_json

__all__ = ["AgentEntry", "list_agents", "find_agent", "MODELS_PACKAGE", "MODELS_FOLDER", "models_dir", "BUILTIN_AGENTS"]

MODELS_PACKAGE = "marine_fdi_env.training"  # the repository folder training/, installed under the namespace
MODELS_FOLDER = "models"
# name -> module:Class of the non-learned agents (marine_fdi_env.baselines)
BUILTIN_AGENTS = {
    "null": "marine_fdi_env.baselines.null_agent:NullAgent",
    "random": "marine_fdi_env.baselines.random_agent:RandomAgent",
    "reference": "marine_fdi_env.baselines.reference_agent:ReferenceAgent",
    "reference-distributed": "marine_fdi_env.baselines.reference_distributed_agent:ReferenceDistributedAgent",
    "sequential": "marine_fdi_env.baselines.sequential_agent:SequentialAgent",
    "reference-thesis": "marine_fdi_env.baselines.reference_agent:ReferenceThesisAgent",
    "reference-grid": "marine_fdi_env.baselines.reference_agent:ReferenceGridAgent",
    "sequential-thesis": "marine_fdi_env.baselines.sequential_agent:SequentialThesisAgent",
    "sequential-grid": "marine_fdi_env.baselines.sequential_agent:SequentialGridAgent",
    "reference-lipschitz": "marine_fdi_env.baselines.reference_agent:ReferenceLipschitzAgent",
    "reference-no-interconnection": "marine_fdi_env.baselines.reference_agent:ReferenceNoInterconnectionAgent",
    "reference-table-6.1": "marine_fdi_env.baselines.reference_agent:ReferenceTable61Agent",
    "reference-table-6.1-m4": "marine_fdi_env.baselines.reference_agent:ReferenceTable61M4Agent",
    "oracle": "marine_fdi_env.baselines.oracle_agent:OracleAgent",
}
# what a variant of a baseline is (the others are described by their module's docstring)
BUILTIN_VARIANTS = {
    "reference-thesis": "The reference with the table-size cells (the thesis's exoneration)",
    "reference-grid": "The reference with the size-blind grid cells",
    "sequential-thesis": "The sequential diagnoser with the table-size cells",
    "sequential-grid": "The sequential diagnoser with the size-blind grid cells",
    "reference-lipschitz": "The reference with the thesis's eq. 5.11 read with a global Lipschitz bound "
    "(docs/reproduction.md)",
    "reference-no-interconnection": "The reference without the interconnection term in its observers' "
    "thresholds (fires at once: docs/reproduction.md)",
    "reference-table-6.1": "The reference with eq. 5.10-5.12 and table 6.1's constants in every observer "
    "(fires at once: docs/reproduction.md)",
    "reference-table-6.1-m4": "The reference with table 6.1's constants in the charge-air observers M4.1/M4.2 "
    "(docs/reproduction.md)",
}
# top-level package names of the agents and the training code before they moved under the namespace
LEGACY_PACKAGES = ("baselines", "training")
TRAIN_EXTRA_HINT = "pip install 'marine-fdi-env[train]'"


@dataclass(frozen=True)
class AgentEntry:
    """One named agent.  ``spec`` is what :func:`~.agent_api.load_agent` loads (the name of a
    baseline, the folder of a model)."""

    name: str
    kind: str  # "baseline" | "model"
    spec: str
    description: str
    aliases: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()  # Python modules it imports beyond the core (torch, ...)

    @property
    def available(self) -> bool:
        return all(importlib.util.find_spec(m) is not None for m in self.needs)

    def to_dict(self) -> dict:
        """The fields (tuples as lists) and whether the agent is available, as JSON."""
        return {**asdict(self), "aliases": list(self.aliases), "needs": list(self.needs), "available": self.available}


def models_dir() -> Path | None:
    """The installed models folder (``training/models``), or None if there is none."""
    try:
        root = resources.files(MODELS_PACKAGE) / MODELS_FOLDER
    except ModuleNotFoundError:
        return None
    p = Path(str(root))
    return p if p.is_dir() else None


def _first_line(doc: str | None) -> str:
    """The first sentence of a docstring's first paragraph (a paragraph may wrap over several lines)."""
    para = " ".join((doc or "").strip().split("\n\n")[0].split())
    return para.split(". ")[0].rstrip(".")


def _pairs_note(cfg: dict) -> str:
    """What a team config's declaration takes from the thesis's logic (``declaration.pairs``), or ''."""
    if (cfg.get("declaration") or {}).get("pairs") == "thesis":
        return ", with the thesis's logic where it names a fault pair: a hybrid"
    return ""


def _model_entry(folder: Path) -> AgentEntry | None:
    meta = folder / "agent.json"
    if not meta.is_file():
        return None
    cfg_file = folder / "config.json"
    cfg = read_json(cfg_file, "model config") if cfg_file.is_file() else {}
    spec = read_json(meta, "agent description") or {}
    cls = str(spec.get("class", ""))
    name = str(cfg.get("name") or folder.name)
    desc = cfg.get("description")
    kw = spec.get("kwargs") or {}
    where = f"{MODELS_PACKAGE.rpartition('.')[2]}/{MODELS_FOLDER}"
    if not desc and not cfg and kw.get("model") and kw.get("use_reference"):  # a hybrid over another folder's model
        desc = (
            f"the model of {where}/{Path(str(kw['model'])).name} with the reference diagnoser's "
            f"conclusion ({kw.get('use_reference', '?')}): a hybrid"
        )
    if not desc and not cfg and kw.get("model"):  # one model of several (training seeds) in sub-folders
        sub = folder / str(kw["model"])
        seeds = sorted(p.name for p in folder.iterdir() if (p / "config.json").is_file())
        sub_cfg = read_json(sub / "config.json", "model config") if (sub / "config.json").is_file() else {}
        minutes = sub_cfg.get("cpu_minutes")
        desc = (
            f"trained {sub_cfg.get('algo', '?')} model in {where}/{folder.name}: {sub.name} by default, "
            f"{len(seeds)} training seeds ({', '.join(seeds)})"
            + (f", {float(minutes):.1f} CPU min of training ({sub.name})" if minutes is not None else "")
            + _pairs_note(sub_cfg)
        )
    if not desc:
        algo = cfg.get("algo", "?")
        minutes = cfg.get("cpu_minutes")
        size = cfg.get("model_bytes")
        parts = [f"trained {algo} model in {where}/{folder.name}"]
        if minutes is not None:
            parts.append(f"{float(minutes):.1f} CPU min of training")
        if size:
            parts.append(f"{int(size) / 1024:.0f} KiB")
        ref = (cfg.get("declaration") or {}).get("use_reference")
        if ref:
            parts.append(f"uses the reference diagnoser's conclusion ({ref})")
        desc = ", ".join(parts) + _pairs_note(cfg)
    needs = ("torch",) + (("stable_baselines3",) if "SB3" in cls else ())
    aliases = (folder.name,) if folder.name != name else ()
    return AgentEntry(name, "model", str(folder), str(desc), aliases, needs)


@lru_cache(maxsize=1)
def _entries() -> tuple[AgentEntry, ...]:
    out = []
    for name, target in BUILTIN_AGENTS.items():
        mod, _, cls = target.partition(":")
        doc = None
        try:
            spec = importlib.util.find_spec(mod)
            if spec is not None and spec.origin:
                import ast

                doc = ast.get_docstring(ast.parse(Path(spec.origin).read_text(encoding="utf-8")))
        except (ImportError, OSError, SyntaxError, ValueError):
            pass
        out.append(AgentEntry(name, "baseline", name, BUILTIN_VARIANTS.get(name) or _first_line(doc) or target))
    root = models_dir()
    if root is not None:
        for folder in sorted(p for p in root.iterdir() if p.is_dir()):
            e = _model_entry(folder)
            if e is not None:
                out.append(e)
    names: dict[str, str] = {}
    for e in out:
        for n in (e.name, *e.aliases):
            if n in names and names[n] != e.spec:
                raise ValueError(f"two agents are called {n!r}: {names[n]} and {e.spec}")
            names[n] = e.spec
    return tuple(out)


def list_agents() -> list[AgentEntry]:
    """Every named agent: the baselines, then the shipped models (by folder name)."""
    return list(_entries())


def find_agent(name: str) -> AgentEntry | None:
    """The agent called ``name`` (or whose model folder is called so), else None."""
    for e in _entries():
        if name == e.name or name in e.aliases:
            return e
    return None
