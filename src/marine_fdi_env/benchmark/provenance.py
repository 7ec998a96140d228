"""What an entry names (:mod:`.entries`): the agent by its files' hashes, the suites by their content
hashes, the software by its versions.

* **Agent identity** (:func:`agent_identity`): a baseline by its name (its code is the package's, whose
  version the entry records); a shipped model by its name, its folder under the installed models folder
  (``classifier/seed1``) and the sha256 of every file in that folder; an agent folder (``agent.json``)
  or an agent file (``path/file.py:Class``) by the sha256 of its files, which the entry keeps a copy of
  (``DIR/agent/``), so that anyone can replay it.  ``family`` says what kind of agent it is:
  ``baseline``, the model's algorithm (``classifier``, ``ppo``), or ``folder`` / ``file``.
* **Suite identity** (:func:`suite_sha256`): the sha256 of the suite's content (its JSON object,
  keys sorted, scenarios as :meth:`ScenarioSpec.to_dict` writes them): a changed scenario, seed or
  environment option changes it; the file's whitespace does not.
* **Software** (:func:`software_versions`): Python, the platform and the versions of the packages the
  numbers depend on (informational: a verification on other versions says which differ).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import platform
import shutil
from pathlib import Path

from .._version import __version__

__all__ = [
    "file_sha256",
    "folder_hashes",
    "suite_sha256",
    "software_versions",
    "agent_identity",
    "copy_agent",
    "agent_spec_of",
    "AGENT_FOLDER",
    "PACKAGES",
]

AGENT_FOLDER = "agent"  # the copy of a folder or file agent inside an entry
# the distributions whose versions an entry records (those installed)
PACKAGES = (
    "numpy",
    "scipy",
    "numba",
    "llvmlite",
    "gymnasium",
    "torch",
    "stable-baselines3",
    "sb3-contrib",
    "pyarrow",
)
_SKIP = (".png", ".pyc")  # figures and byte code: never loaded by an agent


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def folder_hashes(folder: Path) -> dict[str, str]:
    """``{relative path: sha256}`` of every file under ``folder`` (figures and byte code left out)."""
    folder = Path(folder)
    return {
        str(p.relative_to(folder)): file_sha256(p)
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.suffix not in _SKIP and "__pycache__" not in p.parts
    }


def suite_sha256(suite) -> str:
    """The sha256 of a loaded suite's content (module docstring)."""
    obj = {k: v for k, v in suite.items() if k != "scenarios"}
    obj["scenarios"] = [s.to_dict() for s in suite.scenarios]
    return hashlib.sha256(json.dumps(obj, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def software_versions() -> dict[str, str]:
    """Python, the platform, this package and the installed :data:`PACKAGES` with their versions."""
    out = {"python": platform.python_version(), "platform": platform.platform(), "marine-fdi-env": __version__}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return out


def _family_of(folder: Path) -> str:
    """A model folder's algorithm: ``algo`` of its config.json (or of the model it wraps), else from its class."""
    from ..jsonfile import read_json

    cfg = folder / "config.json"
    if cfg.is_file():
        algo = read_json(cfg, "model config").get("algo")
        if algo:
            return "ppo" if str(algo).startswith("ppo") else str(algo)
    meta = read_json(folder / "agent.json", "agent description") if (folder / "agent.json").is_file() else {}
    model = (meta.get("kwargs") or {}).get("model")
    if model and (folder / str(model)).resolve() != folder.resolve() and (folder / str(model)).is_dir():
        return _family_of((folder / str(model)).resolve())
    cls = str(meta.get("class", ""))
    return "classifier" if "Classifier" in cls else "ppo" if "SB3" in cls else "model"


def _needs_of(folder: Path) -> list[str]:
    """The extras a model folder's agent needs (its class is in the training code: ``train``)."""
    from ..jsonfile import read_json

    meta = read_json(folder / "agent.json", "agent description") if (folder / "agent.json").is_file() else {}
    return ["train"] if str(meta.get("class", "")).startswith("marine_fdi_env.training") else []


def agent_identity(spec: str, training_seed: int | None = None) -> dict:
    """The identity an entry records for the agent ``spec`` (a name, a shipped model's folder, a folder
    with agent.json, or ``path/file.py:Class``): ``{"kind", "family", "name", ..., "files": {path:
    sha256}, "needs": [extras]}`` (module docstring)."""
    from .agent_api import BUILTIN_AGENTS, split_file_spec
    from .agent_registry import find_agent, models_dir

    spec = str(spec)
    if spec in BUILTIN_AGENTS:
        return {"kind": "baseline", "family": "baseline", "name": spec, "code": BUILTIN_AGENTS[spec], "needs": []}
    fs = split_file_spec(spec)
    if fs is not None:
        path = fs[0]
        if not path.is_file():
            raise ValueError(f"agent {spec!r}: no such file {str(path)!r}")
        return {
            "kind": "file",
            "family": "file",
            "file": f"{AGENT_FOLDER}/{path.name}",
            "class": fs[1],
            "files": {path.name: file_sha256(path)},
            "needs": [],
        }
    path = Path(spec)
    entry = find_agent(spec) if not path.exists() else None
    if entry is not None and entry.kind == "model":
        path = Path(entry.spec)
    if not path.is_dir():
        raise ValueError(f"agent {spec!r}: not a baseline name, a shipped model, a folder or path/file.py:Class")
    root = models_dir()
    inside = root is not None and path.resolve().is_relative_to(root.resolve())
    folder = path.resolve()
    out = {
        "kind": "shipped" if inside else "folder",
        "family": _family_of(folder),
        "files": folder_hashes(folder),
        "needs": _needs_of(folder),
    }
    if inside:
        out["folder"] = folder.relative_to(root.resolve()).as_posix()
    else:
        out["folder"] = AGENT_FOLDER
    if training_seed is not None:
        out["training_seed"] = int(training_seed)
    return out


def copy_agent(spec: str, identity: dict, entry_dir: Path) -> None:
    """Copy a folder or file agent into ``entry_dir/agent/`` (shipped agents are found by name)."""
    from .agent_api import split_file_spec

    dest = Path(entry_dir) / AGENT_FOLDER
    if identity["kind"] == "file":
        dest.mkdir(parents=True, exist_ok=True)
        shutil.copy2(split_file_spec(spec)[0], dest / Path(identity["file"]).name)
    elif identity["kind"] == "folder":
        shutil.copytree(Path(spec), dest, dirs_exist_ok=True, ignore=shutil.ignore_patterns("*.png", "__pycache__"))


def agent_spec_of(identity: dict, entry_dir: Path) -> str:
    """The ``--agent`` spec that loads the agent an entry names: a baseline's name, the shipped model's
    folder in this installation, or the entry's copy of a folder or file agent."""
    from .agent_registry import models_dir

    kind = identity.get("kind")
    if kind == "baseline":
        return str(identity["name"])
    if kind == "shipped":
        root = models_dir()
        if root is None:
            raise ValueError("this installation has no shipped models folder (training/models)")
        return str(root / identity["folder"])
    if kind == "folder":
        return str((Path(entry_dir) / identity["folder"]).resolve())
    if kind == "file":
        return f"{(Path(entry_dir) / identity['file']).resolve()}:{identity['class']}"
    raise ValueError(f"{entry_dir}: agent.kind must be baseline, shipped, folder or file, got {kind!r}")
