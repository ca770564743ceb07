"""No import cycle in ``isf_robot`` or ``satellite``: every import statement counts, top-level or not.

Each ``.py`` file is read with ``ast``; every ``Import`` / ``ImportFrom`` node anywhere in it (inside
functions, under ``if TYPE_CHECKING:``, in ``try`` blocks) is an edge of the module graph, relative
imports resolved. ``from pkg import name`` is an edge to ``pkg.name`` when that is a module, else to
the submodule that ``pkg``'s lazy export table ``_EXPORTS`` names for ``name`` (see
:func:`isf_robot._exports.lazy_exports`), else to ``pkg``. Importing ``a.b.c`` also runs the
``__init__`` of ``a`` and ``a.b``: those are edges too, unless they are packages of the importing
module itself (which Python has started before it).

The export tables are not edges of the ``__init__`` that holds them: the ``__init__`` imports those
submodules only when a name is first used, after every module involved has finished importing, so
they cannot close an import-time cycle. What they say is which submodule ``from pkg import Name``
really loads, and that is where the importer's edge goes: ``from isf_robot.core import
IntermittentSafetyFilter`` depends on ``isf_robot.core.filters``, not on the package's table.

Imports by computed name (``importlib.import_module(name)`` in the command lines' subcommand
registries) are not read; those are the top layer, checked by ``tests/test_layers.py``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("isf_robot", "satellite")

Graph = dict[str, dict[str, list[int]]]  # module -> imported module -> line numbers


def _module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _export_table(tree: ast.Module) -> dict[str, str]:
    """The ``_EXPORTS = {name: submodule}`` literal of a package ``__init__``, if it has one."""
    for node in tree.body:
        target = (
            node.targets[0]
            if isinstance(node, ast.Assign) and len(node.targets) == 1
            else (node.target if isinstance(node, ast.AnnAssign) else None)
        )
        value = getattr(node, "value", None)
        if isinstance(target, ast.Name) and target.id == "_EXPORTS" and isinstance(value, ast.Dict):
            return {
                k.value: v.value
                for k, v in zip(value.keys, value.values, strict=True)
                if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)
            }
    return {}


def _ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def module_graph(root: Path, packages: Iterable[str]) -> Graph:
    """Every module under ``root/<package>`` and the project modules each one imports."""
    files = {_module_name(root, p): p for pkg in packages for p in sorted((root / pkg).rglob("*.py"))}
    trees = {name: ast.parse(path.read_text(encoding="utf-8"), filename=str(path)) for name, path in files.items()}
    exports = {name: _export_table(tree) for name, tree in trees.items() if files[name].name == "__init__.py"}

    def owner(dotted: str) -> str | None:
        """The longest prefix of ``dotted`` that is a project module (``import a.b.c`` of a non-module)."""
        while dotted and dotted not in files:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    graph: Graph = {}
    for name, tree in trees.items():
        package = name if files[name].name == "__init__.py" else name.rpartition(".")[0]
        edges: dict[str, list[int]] = {}

        def add(target: str | None, line: int, importer: str = name, edges: dict[str, list[int]] = edges) -> None:
            if target is None or target == importer:
                return
            own = set(_ancestors(importer))
            for module in [*_ancestors(target), target]:
                if module in files and module not in own:
                    edges.setdefault(module, []).append(line)

        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    add(owner(alias.name), node.lineno)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                for alias in node.names:
                    if f"{source}.{alias.name}" in files:
                        add(f"{source}.{alias.name}", node.lineno)
                    elif alias.name in exports.get(source, {}):
                        add(owner(f"{source}.{exports[source][alias.name]}"), node.lineno)
                    else:
                        add(owner(source), node.lineno)
        graph[name] = edges
    return graph


def import_cycles(graph: Graph) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def _loop(graph: Graph, component: list[str]) -> list[str]:
    """One closed import path inside ``component``, starting and ending at its first module."""
    start, members = component[0], set(component)
    parent: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v]):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(parent[path[-1]])
                    return [start, *reversed(path[:-1]), start]
                if w in members and w not in parent:
                    parent[w] = v
                    nxt.append(w)
        frontier = nxt
    return component  # unreachable for a strongly connected component


def describe(graph: Graph, component: list[str]) -> str:
    loop = _loop(graph, component)
    steps = " -> ".join(f"{a} (line {graph[a][b][0]})" for a, b in zip(loop, loop[1:], strict=False))
    return f"{len(component)} modules: {', '.join(component)}\n    e.g. {steps} -> {loop[-1]}"


def test_no_import_cycle() -> None:
    graph = module_graph(ROOT, PACKAGES)
    assert sum(m.startswith("satellite.") for m in graph) > 30  # (every package read, the satellite's subpackages too)
    cycles = import_cycles(graph)
    report = "\n".join(describe(graph, c) for c in cycles)
    print(report)
    assert not cycles, f"{len(cycles)} import cycle(s):\n{report}"


# --- the check itself, on small trees -------------------------------------------------------------


def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def test_a_function_local_relative_import_closes_a_cycle(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/a.py": "from pkg import b\n",
            "pkg/b.py": "def f():\n    from . import c\n",
            "pkg/c.py": "def g():\n    if True:\n        from .a import thing\n",
            "pkg/d.py": "import pkg.a\n",
        },
    )
    graph = module_graph(root, ["pkg"])
    assert graph["pkg.b"] == {"pkg.c": [2]}
    assert import_cycles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]
    assert "pkg.a (line 1) -> pkg.b (line 2) -> pkg.c (line 3) -> pkg.a" in describe(graph, ["pkg.a", "pkg.b", "pkg.c"])


def test_names_from_a_lazy_package_lead_to_their_submodule(tmp_path: Path) -> None:
    init = 'from lib import lazy\n_EXPORTS: dict[str, str] = {"Foo": "foo", "Bar": "bar"}\n'
    root = _tree(
        tmp_path,
        {
            "pkg/__init__.py": init,
            "pkg/foo.py": "from pkg import Bar\n",  # a sibling's name through the table: no cycle with __init__
            "pkg/bar.py": "X = 1\n",
            "other/__init__.py": "",
            "other/user.py": "from pkg import Foo\n",
        },
    )
    graph = module_graph(root, ["pkg", "other"])
    assert graph["pkg"] == {}  # the table is not an import of the __init__
    assert graph["pkg.foo"] == {"pkg.bar": [1]}
    assert graph["other.user"] == {"pkg": [1], "pkg.foo": [1]}  # the package runs, then the submodule
    assert import_cycles(graph) == []
    (root / "pkg/bar.py").write_text("def f():\n    from pkg import Foo\n", encoding="utf-8")
    assert import_cycles(module_graph(root, ["pkg", "other"])) == [["pkg.bar", "pkg.foo"]]


def test_an_eager_package_init_is_part_of_the_graph(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "low/__init__.py": "from .impl import thing\n",
            "low/impl.py": "import high.user\n",
            "high/__init__.py": "",
            "high/user.py": "from low.other import x\n",
            "low/other.py": "x = 1\n",
        },
    )
    graph = module_graph(root, ["low", "high"])
    assert import_cycles(graph) == [["high.user", "low", "low.impl"]]
