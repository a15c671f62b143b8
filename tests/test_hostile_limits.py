"""Hostile input that needs its own set-up: deep nesting, wrong provenance, huge sizes.

Each case runs the CLI in a child process (as a user would: a RecursionError,
a traceback or a kill by the out-of-memory killer show there as they would in
a terminal) and checks the one ``error: ...`` line, exit code 2, an empty
stdout and that no file appeared or changed. None needs the cycle LUTs of the
session: what is refused is refused before any LUT is interpolated.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

CLI = "import sys; from evtms.cli import main; sys.argv[0] = 'evtms'; main()"


def run_cli(cwd: Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)


def snapshot(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        for p in sorted(root.rglob("*"))
    }


def refused(cwd: Path, *args: str, message: str) -> str:
    """Run ``evtms args`` in ``cwd``: one error line holding ``message``, exit 2, nothing written."""
    before = snapshot(cwd)
    res = run_cli(cwd, *args)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr[-2000:])
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr[-2000:]
    assert "Traceback" not in res.stderr and res.stdout == ""
    assert message in lines[0], lines[0]
    assert snapshot(cwd) == before
    return lines[0]


# --- TOML files nested deeper than the parser's recursion ----------------------------------------

DEEP = {
    "array": "x = " + "[" * 5000 + "]" * 5000 + "\n",
    "inline-table": "x = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n",
    "parsed-but-deep": "x = " + "[" * 100 + "]" * 100 + "\n",  # tomllib parses it; the checks after it would not
}


@pytest.mark.parametrize("kind", DEEP)
@pytest.mark.parametrize(
    "args",
    [
        ["bench", "condenser", "--params", "deep.toml", "-o", "o.nc"],
        ["simulate", "--cycle", "wltc3b", "--t-amb", "30", "--params", "deep.toml", "-o", "o.nc"],
        ["simulate", "--scenario-file", "deep.toml", "-o", "o.nc"],
    ],
    ids=["bench-params", "simulate-params", "scenario-file"],
)
def test_a_deeply_nested_toml_file_is_one_line(tmp_path, kind, args):
    (tmp_path / "deep.toml").write_text(DEEP[kind])
    refused(tmp_path, *args, message="'deep.toml' nests tables or arrays more than 32 levels deep")


def test_toml_nested_as_deep_as_a_scenario_file_is_read(tmp_path):
    from evtms.params import read_params_toml

    (tmp_path / "s.toml").write_text("[a.b.c]\nx = [[1.0, 2.0], [3.0, 4.0]]\n")  # 5 levels
    assert read_params_toml(tmp_path / "s.toml")["a"]["b"]["c"]["x"][1] == [3.0, 4.0]
