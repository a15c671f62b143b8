"""The code base stays ruff-clean (the same check a developer runs)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_clean():
    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.fail("ruff is not installed; it is part of the 'test' extra")
    res = subprocess.run([ruff, "check", "evtms", "tests", "benchmarks"], cwd=ROOT, capture_output=True, text=True)
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
