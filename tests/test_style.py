"""The code base stays ruff-clean (the same check a developer runs)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_clean():
    """ruff of the running interpreter (no activated venv or ruff on PATH needed): lint and format."""
    if importlib.util.find_spec("ruff") is None:
        pytest.fail("ruff is not installed; it is part of the 'test' extra")
    for args in (["check"], ["format", "--check"]):
        res = subprocess.run(
            [sys.executable, "-m", "ruff", *args, "evtms", "tests", "benchmarks"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
        assert res.returncode == 0, res.stdout + res.stderr


def test_library_never_prints_or_exits():
    """Only the CLI package (evtms/cli/) talks to the terminal or ends the process."""
    for path in (ROOT / "evtms").rglob("*.py"):
        if path.relative_to(ROOT / "evtms").parts[0] == "cli":
            continue
        text = path.read_text()
        for word in ("print(", "sys.exit(", "typer.Exit"):
            assert word not in text, f"{path.relative_to(ROOT)} uses {word}"
    assert sys.version_info >= (3, 10)


#: Package -> packages it must not import (at module level or inside functions): lower layers
#: never import upper ones (docs/architecture.md). fluid <- hx <- benches <- cycle <- system <- workflows <- cli;
#: luts knows no physics.
FORBIDDEN_IMPORTS = {
    "fluid": ("hx", "benches", "luts", "cycle", "reports", "workflows", "cli", "params"),
    "params": ("hx", "benches", "luts", "cycle", "reports", "workflows", "cli"),
    "hx": ("benches", "luts", "cycle", "reports", "workflows", "cli"),
    "luts": ("fluid", "hx", "benches", "cycle", "reports", "workflows", "cli", "params"),
    "benches": ("cycle", "system", "reports", "workflows", "cli"),
    "cycle": ("system", "reports", "workflows", "cli"),
    "system": ("surrogates", "reports", "workflows", "cli"),
    "surrogates": ("reports", "workflows", "cli"),
    "reports": ("workflows", "cli"),
    "workflows": ("cli",),
}


def _evtms_imports(path: Path) -> set[str]:
    """First-level evtms subpackages/modules that ``path`` imports anywhere in its code."""
    import ast

    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module == "evtms":  # a subpackage or module by name
            names = [f"evtms.{a.name}" for a in node.names if not a.name.startswith("__")]  # not __version__
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.ImportFrom):
            raise AssertionError(f"{path.relative_to(ROOT)}:{node.lineno}: a relative import; evtms imports absolutely")
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] == "evtms" and len(parts) > 1:
                found.add(parts[1])
    return found


def test_lower_layers_never_import_upper_ones():
    evtms = ROOT / "evtms"
    for layer, forbidden in FORBIDDEN_IMPORTS.items():
        target = evtms / layer
        files = list(target.rglob("*.py")) if target.is_dir() else [evtms / f"{layer}.py"]
        assert files, layer
        for path in files:
            bad = _evtms_imports(path) & set(forbidden)
            assert not bad, f"{path.relative_to(ROOT)} imports evtms.{', evtms.'.join(sorted(bad))}"


#: All the CLI package (evtms/cli/) may import of evtms: the application layer, the reports whose
#: summaries it prints and the error types.
CLI_MAY_IMPORT = {"cli", "workflows", "reports", "errors"}


def test_the_cli_imports_only_workflows_reports_and_errors():
    files = list((ROOT / "evtms" / "cli").rglob("*.py"))
    assert files
    for path in files:
        bad = _evtms_imports(path) - CLI_MAY_IMPORT
        assert not bad, f"{path.relative_to(ROOT)} imports evtms.{', evtms.'.join(sorted(bad))}"


#: Longest function of the CLI package [lines, decorators aside]: a command parses its options into a
#: request, calls one workflow and prints; the work itself is the workflow's (evtms/workflows/).
CLI_MAX_LINES = 50


def test_no_cli_function_is_longer_than_50_lines():
    import ast

    files = list((ROOT / "evtms" / "cli").rglob("*.py"))
    assert files
    long = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > CLI_MAX_LINES:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {lines} lines")
    assert not long, "move the work into evtms/workflows/:\n" + "\n".join(long)
