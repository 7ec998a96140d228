"""The check of the package's layers (``python -m marine_fdi_env.info --imports``).

:func:`check_imports` parses every module of the package with :mod:`ast`
(no module is imported), collects every import (at module level and inside functions; imports under
``if TYPE_CHECKING:`` are not run and not counted), prints the layer graph and exits with status 1,
listing the offenders, if two modules import each other through a circle, a module imports from a
layer above its own, or a module imports the repository's ``studies`` (research code that is not
installed).  Data flows one way::

    util -> params -> engine -> io -> diagnosis -> envs -> benchmark -> agents -> cli
                         \\-> validation -----------------------------------------> cli

A module may import its own layer and the layers before it on its path: ``validation`` only
``util``, ``params`` and ``engine`` (and itself); only ``cli`` imports ``validation``.  Inside
``validation`` the stages are layers of their own, one way too (:data:`VALIDATION_STAGES`)::

    validation.measured -> validation.fit -> validation.select -> validation.explain -> validation.report

(data in, fit, select, explain, report); the package ``validation`` itself (its ``__init__``, the public
names) may import every stage.  ``cli`` is the command line (:mod:`marine_fdi_env.cli` and the
``python -m marine_fdi_env.info`` entry), and nothing outside it imports it; ``top`` is the package
``__init__`` (it registers the environments).
``io`` (run files, the thesis scenarios) sits on the engine because the diagnosis reads run files
and the suites are built from the scenarios.

Decision: agents loaded *by name* (``benchmark.agent_api.BUILTIN_AGENTS``, ``agent.json`` ``"class"``
strings, ``benchmark.agent_registry.MODELS_PACKAGE``) are looked up with :func:`importlib.import_module`
at run time; that is a plug-in registry, not an import, and is not an edge of the graph (the
environments never import an agent's code in their source).
"""

from __future__ import annotations

import ast
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path

from ._version import __version__

__all__ = [
    "LAYERS",
    "ALLOWED",
    "VALIDATION_STAGES",
    "ImportEdge",
    "layer_of",
    "package_roots",
    "package_modules",
    "import_edges",
    "studies_imports",
    "check_imports",
    "print_imports",
]

PACKAGE = "marine_fdi_env"

# layer name -> module name prefixes (relative to the package), most specific first when matched
LAYERS: dict[str, tuple[str, ...]] = {
    "util": (
        "_version",
        "_jit",
        "coldstart",
        "suggest",
        "plotting",
        "jsonfile",
        "errors",
        "outputs",
        "progress",
        "costs",
        "layers",
    ),
    "params": ("engine.params", "engine.submodels"),
    "engine": ("engine",),
    "io": ("runio", "scenarios"),
    "validation": ("validation",),
    "validation.measured": ("validation.measured",),
    "validation.fit": ("validation.fit",),
    "validation.select": ("validation.select",),
    "validation.explain": ("validation.explain",),
    "validation.report": ("validation.report",),
    "diagnosis": ("diagnosis",),
    "envs": ("envs", "multiagent"),
    "benchmark": ("benchmark", "multiagent.evaluate"),
    "agents": ("baselines", "training"),
    "cli": ("cli", "info", "__main__"),
    "top": ("",),
}
_BASE = ("util", "params", "engine")
#: the stages of ``validation``, in the order data flows through them
VALIDATION_STAGES = (
    "validation.measured",
    "validation.fit",
    "validation.select",
    "validation.explain",
    "validation.report",
)
ALLOWED: dict[str, frozenset[str]] = {
    "util": frozenset({"util"}),
    "params": frozenset({"util", "params"}),
    "engine": frozenset(_BASE),
    "io": frozenset(_BASE + ("io",)),
    "validation": frozenset(_BASE + ("validation",) + VALIDATION_STAGES),
    **{stage: frozenset(_BASE + VALIDATION_STAGES[: i + 1]) for i, stage in enumerate(VALIDATION_STAGES)},
    "diagnosis": frozenset(_BASE + ("io", "diagnosis")),
    "envs": frozenset(_BASE + ("io", "diagnosis", "envs")),
    "benchmark": frozenset(_BASE + ("io", "diagnosis", "envs", "benchmark")),
    "agents": frozenset(_BASE + ("io", "diagnosis", "envs", "benchmark", "agents")),
    "cli": frozenset(set(LAYERS) - {"top"}),
    "top": frozenset(set(LAYERS) - {"cli"}),
}
STUDIES = "studies"  # the repository's research code: never imported by the package


@dataclass(frozen=True)
class ImportEdge:
    """``importer`` imports ``imported`` (full module names) at ``line`` of ``path``."""

    importer: str
    imported: str
    path: Path
    line: int
    in_function: bool


def layer_of(module: str) -> str:
    """The layer of a module of the package (full dotted name)."""
    rel = module[len(PACKAGE) + 1 :] if module != PACKAGE else ""
    best, best_len = None, -1
    for layer, prefixes in LAYERS.items():
        for pre in prefixes:
            hit = rel == pre or (pre and rel.startswith(pre + "."))
            if hit and len(pre) > best_len:
                best, best_len = layer, len(pre)
    if best is None:
        raise ValueError(f"module {module} is in no layer of marine_fdi_env.layers.LAYERS; add it there")
    return best


def package_roots() -> dict[str, Path]:
    """Package name -> directory, for the package and the subpackages installed from other folders
    (``marine_fdi_env.baselines``, ``marine_fdi_env.training``), editable install or not."""
    roots: dict[str, Path] = {PACKAGE: Path(__file__).resolve().parent}  # this module's own package
    for name in (f"{PACKAGE}.baselines", f"{PACKAGE}.training"):
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.submodule_search_locations:
            raise RuntimeError(f"cannot find the installed package {name}; reinstall with pip install -e .")
        roots[name] = Path(list(spec.submodule_search_locations)[0])
    return roots


def package_modules() -> dict[str, Path]:
    """Every module of the package: full dotted name -> source file (packages are their
    ``__init__.py``).  Folders without ``__init__.py`` (data, shipped models) are skipped."""
    mods: dict[str, Path] = {}
    for pkg, root in package_roots().items():
        for f in sorted(root.rglob("*.py")):
            rel = f.relative_to(root)
            if any(not (root.joinpath(*rel.parts[:i]) / "__init__.py").is_file() for i in range(1, len(rel.parts))):
                continue
            parts = list(rel.with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            name = ".".join([pkg] + parts)
            if (
                name.startswith(f"{PACKAGE}.baselines")
                and pkg == PACKAGE
                or (name.startswith(f"{PACKAGE}.training") and pkg == PACKAGE)
            ):
                continue  # a stray copy inside the source folder: the installed one wins
            mods[name] = f
    return mods


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST):
    """(node, inside a function) for every import statement, skipping ``if TYPE_CHECKING:`` bodies."""
    stack = [(tree, False)]
    while stack:
        node, in_fn = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                for sub in child.orelse:
                    stack.append((sub, in_fn))
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child, in_fn
            stack.append((child, in_fn or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))))


def _resolved_imports(mods: dict[str, Path]):
    """``(importer, imported, as written, path, line, in a function)`` for every import of every module, the
    imported name resolved to a module of the package where it is one (``from pkg import sub``: the submodule)."""
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        here = name if is_pkg else name.rpartition(".")[0]
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node, in_fn in _imports(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base_parts = here.split(".")
                    if node.level - 1 > len(base_parts) - 1:
                        raise ValueError(f"{path}:{node.lineno}: relative import beyond the package")
                    base = ".".join(base_parts[: len(base_parts) - (node.level - 1)])
                    base = f"{base}.{node.module}" if node.module else base
                else:
                    base = node.module or ""
                for a in node.names:  # `from pkg import sub` imports the submodule if there is one
                    sub = f"{base}.{a.name}"
                    targets.append(sub if sub in mods else base)
            for written in targets:
                t = written
                while t and t not in mods and "." in t:  # `import a.b.c` of a function-free path
                    t = t.rpartition(".")[0]
                yield name, t, written, path, node.lineno, in_fn


def import_edges(mods: dict[str, Path] | None = None) -> list[ImportEdge]:
    """Every import of a module of the package by a module of the package."""
    mods = package_modules() if mods is None else mods
    edges, seen = [], set()
    for name, t, _, path, line, in_fn in _resolved_imports(mods):
        edge = ImportEdge(name, t, path, line, in_fn)
        if t in mods and t != name and edge not in seen:
            seen.add(edge)
            edges.append(edge)
    return edges


def studies_imports(mods: dict[str, Path] | None = None) -> list[ImportEdge]:
    """Every import of the repository's ``studies`` by a module of the package (there must be none)."""
    mods = package_modules() if mods is None else mods
    return [
        ImportEdge(name, w, path, line, in_fn)
        for name, _, w, path, line, in_fn in _resolved_imports(mods)
        if w == STUDIES or w.startswith(STUDIES + ".")
    ]


def _cycles(nodes, edges: list[ImportEdge]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    succ: dict[str, set[str]] = {n: set() for n in nodes}
    for e in edges:
        succ[e.importer].add(e.imported)
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in sorted(nodes):
        if root in index:
            continue
        work = [(root, iter(sorted(succ[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            nxt = next(it, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter[0]
                    counter[0] += 1
                    stack.append(nxt)
                    on.add(nxt)
                    work.append((nxt, iter(sorted(succ[nxt]))))
                elif nxt in on:
                    low[v] = min(low[v], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out)


def check_imports(mods: dict[str, Path] | None = None) -> dict:
    """The layer graph and its violations: ``{"modules", "edges", "layers": {layer: {imported
    layer: count}}, "cycles": [[module, ...]], "backward": [ImportEdge], "studies": [ImportEdge]}``."""
    mods = package_modules() if mods is None else mods
    edges = import_edges(mods)
    layers: dict[str, dict[str, int]] = {layer: {} for layer in LAYERS}
    backward = []
    for e in edges:
        a, b = layer_of(e.importer), layer_of(e.imported)
        if a != b:
            layers[a][b] = layers[a].get(b, 0) + 1
        if b not in ALLOWED[a]:
            backward.append(e)
    return {
        "modules": mods,
        "edges": edges,
        "layers": layers,
        "cycles": _cycles(mods, edges),
        "backward": backward,
        "studies": studies_imports(mods),
    }


def _where(e: ImportEdge) -> str:
    return f"{e.path}:{e.line}"


def print_imports(result: dict, verbose: bool = False, file=None) -> int:
    """Print the layer graph and the violations; returns the exit status (0: clean)."""
    file = file or sys.stdout
    mods = result["modules"]
    count = {layer: 0 for layer in LAYERS}
    for m in mods:
        count[layer_of(m)] += 1
    print(f"{PACKAGE} {__version__}: {len(mods)} modules, {len(result['edges'])} imports between them", file=file)
    width = max(map(len, LAYERS)) + 1
    print(f"{'layer':<{width + 2}}modules  imports from (number of imports)", file=file)
    for layer in LAYERS:
        deps = result["layers"][layer]
        txt = ", ".join(f"{b} ({deps[b]})" for b in LAYERS if b in deps) or "-"
        print(f"  {layer:<{width}}{count[layer]:>7}   {txt}", file=file)
    if verbose:
        for e in sorted(result["edges"], key=lambda e: (e.importer, e.imported)):
            print(f"    {e.importer} -> {e.imported}{' (in a function)' if e.in_function else ''}", file=file)
    status = 0
    if result["cycles"]:
        status = 1
        print(f"IMPORT CIRCLES ({len(result['cycles'])}):", file=file)
        for comp in result["cycles"]:
            inside = [e for e in result["edges"] if e.importer in comp and e.imported in comp]
            print("  " + " <-> ".join(comp), file=file)
            for e in inside:
                print(f"    {e.importer} -> {e.imported}  ({_where(e)})", file=file)
    if result["backward"]:
        status = 1
        print(f"BACKWARD IMPORTS ({len(result['backward'])}):", file=file)
        for e in result["backward"]:
            print(
                f"  {e.importer} [{layer_of(e.importer)}] -> {e.imported} [{layer_of(e.imported)}]  ({_where(e)})",
                file=file,
            )
    if result.get("studies"):
        status = 1
        print(f"IMPORTS OF THE REPOSITORY'S STUDIES ({len(result['studies'])}):", file=file)
        for e in result["studies"]:
            print(f"  {e.importer} -> {e.imported}  ({_where(e)})", file=file)
    if status == 0:
        print("no import circle, no backward import between layers, no import of studies", file=file)
    return status
