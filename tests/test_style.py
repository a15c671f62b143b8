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
    """Only cli.py talks to the terminal or ends the process."""
    for path in (ROOT / "evtms").rglob("*.py"):
        if path.name == "cli.py":
            continue
        text = path.read_text()
        for word in ("print(", "sys.exit(", "typer.Exit"):
            assert word not in text, f"{path.relative_to(ROOT)} uses {word}"
    assert sys.version_info >= (3, 10)
