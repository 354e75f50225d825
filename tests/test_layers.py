"""The import layers of fmu_fdi (fmu_fdi/_layers.py): no import from a lower layer to a higher
one and no import circles, counting imports inside functions; README.md shows the same list.

The import graph is read from the source with ``ast`` (every ``import``/``from … import`` at
any depth, ``if TYPE_CHECKING`` blocks included), never by importing the package, so an
import that a lazy function would run only later counts the same as one at module level.
A name taken from a package face (``from .design import nullspace_design``) counts as an
import of the module the face takes it from; a face that re-exports nothing by that name
counts as its package.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from fmu_fdi._layers import LAYERS, layer_of, table

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fmu_fdi"


def modules(root: Path) -> dict[str, Path]:
    """Dotted module name → file, for every .py under the package folder ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _base(mod: str, path: Path, level: int) -> list[str]:
    parts = mod.split(".")
    if path.name != "__init__.py":
        parts = parts[:-1]  # a module's relative imports start at its package
    return parts[: len(parts) - (level - 1)] if level > 1 else parts


def _faces(mods: dict[str, Path]) -> dict[str, dict[str, str]]:
    """Package → {name: module the package's __init__ takes it from by a relative import}."""
    faces: dict[str, dict[str, str]] = {}
    for m, p in mods.items():
        if p.name != "__init__.py":
            continue
        for node in ast.parse(p.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom) and node.level:
                src = ".".join(_base(m, p, node.level) + ([node.module] if node.module else []))
                for a in node.names:
                    faces.setdefault(m, {})[a.asname or a.name] = src
    return faces


def import_graph(root: Path = PACKAGE) -> tuple[dict[str, Path], dict[str, set[tuple[str, int]]]]:
    """Modules and their import edges ``{module: {(imported module, line), ...}}`` inside the
    package (an importer's own package face, which Python runs first anyway, is left out)."""
    mods = modules(root)
    faces = _faces(mods)
    edges: dict[str, set[tuple[str, int]]] = {m: set() for m in mods}
    for m, p in mods.items():
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = ".".join(_base(m, p, node.level) + ([node.module] if node.module else [])) if node.level \
                    else (node.module or "")
                for a in node.names:
                    if f"{base}.{a.name}" in mods:  # `from . import x`, x a module
                        targets.append(f"{base}.{a.name}")
                    elif base in mods and mods[base].name == "__init__.py" and a.name in faces.get(base, {}):
                        targets.append(faces[base][a.name])
                    else:
                        targets.append(base)
            for t in targets:
                while t and t not in mods:  # `import fmu_fdi.design.x as y` and the like
                    t = t.rpartition(".")[0]
                if t and t != m and t in mods and not (mods[t].name == "__init__.py" and m.startswith(t + ".")):
                    edges[m].add((t, node.lineno))
    return mods, edges


def upward_imports(edges, layers=LAYERS, package: str = "fmu_fdi") -> list[str]:
    order = [name for name, _, _ in layers]
    out = []
    for m in sorted(edges):
        for t, line in sorted(edges[m]):
            lm, lt = layer_of(m, layers, package), layer_of(t, layers, package)
            if lm and lt and order.index(lt) > order.index(lm):
                out.append(f"{m} (layer {lm}) imports {t} (layer {lt}), line {line}")
    return out


def circles(edges) -> list[list[str]]:
    """Strongly connected groups of two or more modules (Tarjan), each sorted."""
    graph = {m: sorted({t for t, _ in es}) for m, es in edges.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    groups = []
    for start in graph:
        if start in index:
            continue
        work = [(start, 0)]
        while work:  # iterative, so deep chains do not hit the recursion limit
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = len(index)
                stack.append(v)
                on.add(v)
            else:
                low[v] = min(low[v], low[graph[v][i - 1]])
            for k in range(i, len(graph[v])):
                w = graph[v][k]
                if w not in index:
                    work.append((v, k + 1))
                    work.append((w, 0))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                if low[v] == index[v]:
                    group = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        group.append(w)
                        if w == v:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))
    return groups


GRAPH = import_graph()


def test_every_module_has_a_layer_and_every_entry_a_module():
    mods, _ = GRAPH
    assert [m for m in mods if layer_of(m) is None] == []
    rel = {m[len("fmu_fdi."):] if m != "fmu_fdi" else "__init__" for m in mods}
    stale = [e for _, _, entries in LAYERS for e in entries
             if not any(r == e or r.startswith(e + ".") for r in rel)]
    assert stale == [], f"layer entries that name no module: {stale}"


def test_no_import_runs_up_a_layer():
    up = upward_imports(GRAPH[1])
    assert up == [], "imports from a lower layer to a higher one:\n" + "\n".join(up)


def test_no_import_circles():
    found = circles(GRAPH[1])
    assert found == [], "import circles:\n" + "\n".join(" ↔ ".join(g) for g in found)


def test_readme_shows_the_layers():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert table() in readme, "README.md's layer table differs from fmu_fdi/_layers.py: paste _layers.table()"


# ---------------------------------------------------------------- the checker can fail
@pytest.fixture
def planted(tmp_path):
    """A package ``pkg`` with an upward import inside a function and a circle through a face."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "from .top import run\n",
        "low.py": "import numpy\n\ndef f():\n    from .top import run  # lazy, and upward\n    return run\n",
        "top.py": "from . import low\nfrom .sub import helper\n\ndef run():\n    return low, helper\n",
        "sub/__init__.py": "from .a import helper\n",
        "sub/a.py": "def helper():\n    from ..sub import other\n    return other\n",
        "sub/b.py": "from .a import helper\n\ndef other():\n    return helper\n",
    }
    for name, text in files.items():
        (pkg / name).write_text(text, encoding="utf-8")
    (pkg / "sub" / "__init__.py").write_text("from .a import helper\nfrom .b import other\n", encoding="utf-8")
    layers = (("ground", "", ("low", "sub")), ("above", "", ("top", "__init__")))
    return pkg, layers


def test_checker_finds_a_planted_upward_import_and_circles(planted):
    pkg, layers = planted
    mods, edges = import_graph(pkg)
    assert set(mods) == {"pkg", "pkg.low", "pkg.top", "pkg.sub", "pkg.sub.a", "pkg.sub.b"}
    up = upward_imports(edges, layers, "pkg")
    assert up == ["pkg.low (layer ground) imports pkg.top (layer above), line 4"]
    # low → top (lazy) → low, and sub.a → sub.b (through the face of pkg.sub) → sub.a
    assert sorted(circles(edges)) == [["pkg.low", "pkg.top"], ["pkg.sub.a", "pkg.sub.b"]]
