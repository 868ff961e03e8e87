"""The package's structure: data flows one way through the pipeline's stages.

Every internal import (at module level or inside a function) is read from the source;
the stages form a strict order, a module may import only its own subpackage and earlier
stages, and no two modules import each other, directly or around a cycle.  A new
cycle, or an import against the flow, fails here with the import that causes it.
"""

from __future__ import annotations

import ast
from pathlib import Path

from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

import kgarment

ROOT = Path(kgarment.__file__).parent
# the pipeline, first to last; a module may import its own stage and earlier ones only
STAGES = (
    ("kgarment", "kgarment.errors", "kgarment.constants", "kgarment.io"),
    ("kgarment.body",),
    ("kgarment.garment",),
    ("kgarment.clutch",),
    ("kgarment.render",),
    ("kgarment.sim",),
    ("kgarment.problem",),
    ("kgarment.case",),
    ("kgarment.evaluate",),
    ("kgarment.optimize",),
    ("kgarment.design",),
    ("kgarment.fabricate",),
    ("kgarment.reproduce", "kgarment.studio", "kgarment.sweep"),
    ("kgarment.cli",),
)
MAX_LINES = 500


def _modules() -> dict[str, Path]:
    out = {}
    for f in ROOT.rglob("*.py"):
        parts = f.relative_to(ROOT.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    return out


def _imports(modules: dict[str, Path]) -> list[tuple[str, str, int]]:
    """(importer, imported kgarment module, line) for every import statement."""
    edges = []
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    target = full if full in modules else base
                    if target.startswith("kgarment"):
                        edges.append((name, target, node.lineno))
            elif isinstance(node, ast.Import):
                edges += [(name, a.name, node.lineno) for a in node.names if a.name.startswith("kgarment")]
    return edges


def _stage(module: str) -> int:
    best = None
    for k, stage in enumerate(STAGES):
        for prefix in stage:
            if module == prefix or module.startswith(prefix + "."):
                if best is None or len(prefix) > best[1]:
                    best = (k, len(prefix))
    assert best is not None, f"{module} belongs to no stage: add it to STAGES"
    return best[0]


def _subpackage(module: str) -> str:
    return ".".join(module.split(".")[:2])


def test_every_import_follows_the_pipeline():
    modules = _modules()
    against = [f"{a} (line {line}) imports {b}" for a, b, line in _imports(modules)
               if _stage(b) > _stage(a)]
    assert not against, "imports against the pipeline's flow:\n" + "\n".join(against)


def _cycles(nodes: list[str], edges: list[tuple[str, str]]) -> list[list[str]]:
    index = {n: i for i, n in enumerate(nodes)}
    rows = [index[a] for a, b in edges if a != b]
    cols = [index[b] for a, b in edges if a != b]
    graph = csr_matrix(([1] * len(rows), (rows, cols)), shape=(len(nodes), len(nodes)))
    n, labels = connected_components(graph, directed=True, connection="strong")
    groups = [[nodes[i] for i in range(len(nodes)) if labels[i] == k] for k in range(n)]
    return [sorted(g) for g in groups if len(g) > 1]


def test_no_import_cycles_between_modules_or_subpackages():
    modules = _modules()
    edges = [(a, b) for a, b, _ in _imports(modules) if b in modules]
    # a package's __init__ re-exports its modules: edges into a package are edges into its
    # __init__, which the modules of the package do not import back
    assert _cycles(sorted(modules), edges) == []
    subs = sorted({_subpackage(m) for m in modules})
    assert _cycles(subs, [(_subpackage(a), _subpackage(b)) for a, b in edges]) == []


def test_the_checks_see_a_cycle_and_a_backward_import():
    """The graph code above finds what it is meant to find."""
    assert _cycles(["a", "b", "c"], [("a", "b"), ("b", "c"), ("c", "a")]) == [["a", "b", "c"]]
    assert _cycles(["a", "b"], [("a", "b")]) == []
    assert _stage("kgarment.sim.solve") > _stage("kgarment.clutch.strip")
    assert _stage("kgarment.cli.design") > _stage("kgarment.optimize.loop")


def test_modules_stay_short():
    long = {name: n for name, path in _modules().items() if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"
