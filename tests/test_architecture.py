"""The module diagram of docs/architecture.md is drawn from the imports, and the imports go one way.

Every module of ``evtms/`` is parsed and each import of another package (at
module level or inside a function, lazy imports included) is an edge between
packages. The diagram between the markers of docs/architecture.md is that
graph; after a change of the imports between packages rewrite it with::

    python3 tests/test_architecture.py --write

The package itself (``evtms/__init__.py``: the version every layer stamps into
its files, and the workflows' names loaded when first used; ``__main__.py``:
``python -m evtms``) is no layer and draws no edge.
"""

from __future__ import annotations

import ast
import graphlib
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "evtms"
DOC = ROOT / "docs" / "architecture.md"
BEGIN = "<!-- module diagram: written from the imports by tests/test_architecture.py --write -->"
END = "<!-- end of the module diagram -->"

#: The layers, lowest first: a package imports packages of lower layers only, none of its own layer
#: (luts, for one, knows no physics: neither fluid nor params).
LAYERS = (
    ("_locks",),
    ("errors", "_jit"),
    ("paths", "params", "fluid", "luts"),
    ("fluid_tables",),
    ("fluid_tables_dome",),
    ("hx",),
    ("benches",),
    ("cycle",),
    ("system",),
    ("surrogates", "reports"),
    ("workflows",),
    ("cli",),
)
#: The package itself, no layer (see the module notes).
NOT_LAYERS = ("__init__", "__main__")


def units(package: Path = PACKAGE) -> list[str]:
    """The first-level packages and modules of ``package`` (no ``__init__``, ``__main__``)."""
    found = [p.name for p in package.iterdir() if p.is_dir() and (p / "__init__.py").is_file()]
    found += [p.stem for p in package.glob("*.py") if p.stem not in NOT_LAYERS]
    return sorted(found)


def imported(tree: ast.AST, package: tuple[str, ...], names: set[str]) -> set[str]:
    """The first-level units of evtms (``names``) that a module of ``package`` imports anywhere in its code.

    ``from evtms import X`` is an edge when X is a unit (a subpackage or module), not when it is a name
    of the package itself (``__version__``); a relative import is resolved against ``package``.
    """
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules = [a.name.split(".") for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = list(package[: len(package) - node.level + 1]) if node.level else []
            module = base + (node.module.split(".") if node.module else [])
            modules = [[*module, a.name] for a in node.names]
        else:
            continue
        for parts in modules:
            if parts[0] == "evtms" and len(parts) > 1 and parts[1] in names:
                found.add(parts[1])
    return found


def edges(package: Path = PACKAGE) -> dict[str, set[str]]:
    """Unit -> the other units it imports, over every module of ``package``."""
    names = set(units(package))
    graph: dict[str, set[str]] = {name: set() for name in names}
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package)
        unit = rel.parts[0].removesuffix(".py")
        if unit in NOT_LAYERS:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        graph[unit] |= imported(tree, ("evtms", *rel.parts[:-1]), names) - {unit}
    return graph


def _rank() -> dict[str, int]:
    return {name: i for i, layer in enumerate(LAYERS) for name in layer}


def _node(name: str) -> str:
    """A mermaid node: id and label (``cli/`` a package, ``errors.py`` a module)."""
    label = f"{name}/" if (PACKAGE / name).is_dir() else f"{name}.py"
    return f'{name.strip("_")}["{label}"]'


def diagram(graph: dict[str, set[str]]) -> str:
    """The mermaid block of ``graph``: every node, top layer first, then one line per importing unit."""
    rank = _rank()

    def order(name: str) -> tuple[int, str]:
        return (-rank.get(name, -1), name.strip("_"))

    lines = ["```mermaid", "flowchart TD"]
    lines += [f"  {_node(name)}" for name in sorted(graph, key=order)]
    for name in sorted(graph, key=order):
        if graph[name]:
            targets = " & ".join(t.strip("_") for t in sorted(graph[name], key=order))
            lines.append(f"  {name.strip('_')} --> {targets}")
    lines.append("```")
    return "\n".join(lines)


def _between(text: str) -> re.Match:
    m = re.search(re.escape(BEGIN) + r"\n(.*?)\n?" + re.escape(END), text, re.S)
    assert m, f"{DOC.relative_to(ROOT)} has no diagram between {BEGIN!r} and {END!r}"
    return m


def documented(text: str) -> str:
    """The diagram between the markers of the doc's ``text``."""
    return _between(text)[1]


def write(path: Path = DOC) -> None:
    """Rewrite the diagram between the markers of ``path``."""
    text = path.read_text(encoding="utf-8")
    m = _between(text)
    path.write_text(f"{text[: m.start()]}{BEGIN}\n{diagram(edges())}\n{END}{text[m.end() :]}", encoding="utf-8")


def test_the_documented_diagram_is_the_imports():
    assert documented(DOC.read_text(encoding="utf-8")) == diagram(edges()), (
        "the imports between packages changed: python3 tests/test_architecture.py --write"
    )


def test_every_unit_has_one_layer():
    layered = [name for layer in LAYERS for name in layer]
    assert sorted(layered) == units() and len(set(layered)) == len(layered)


def test_imports_go_down_the_layers_only():
    rank = _rank()
    upward = [f"{a} imports {b}" for a, targets in edges().items() for b in sorted(targets) if rank[b] >= rank[a]]
    assert not upward, "a package imports one of its own layer or above (LAYERS):\n" + "\n".join(upward)


def test_the_graph_has_no_cycle():
    graphlib.TopologicalSorter(edges()).prepare()  # raises graphlib.CycleError on a cycle


def test_lazy_and_package_imports_are_seen(tmp_path):
    """Imports inside functions are edges; the package's own names (``__version__``) are not."""
    pkg = tmp_path / "evtms"
    for name in ("low", "high"):
        (pkg / name).mkdir(parents=True)
        (pkg / name / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("from evtms import high\n")
    (pkg / "errors.py").write_text("")
    (pkg / "low" / "a.py").write_text("from evtms import __version__\n")
    (pkg / "low" / "b.py").write_text("def f():\n    from evtms.errors import E\n    from . import a\n")
    (pkg / "high" / "c.py").write_text("def g():\n    import evtms.low.a\n    from evtms import errors\n")
    (pkg / "high" / "d.py").write_text("from ..low import b\n")
    assert edges(pkg) == {"low": {"errors"}, "high": {"low", "errors"}, "errors": set()}


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        write()
    else:
        print(diagram(edges()))
