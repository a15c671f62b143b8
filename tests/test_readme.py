"""Every command of the README's bash blocks works, in order, in a fresh folder.

The commands run in-process (``CliRunner``: CoolProp is imported once), each
must exit 0, and a heredoc (``cat > FILE <<'EOF'``) writes its file. Three
kinds of line are not run here, each covered elsewhere: the set-up commands
(``pip install``, ``evtms demo``: CI runs the first two, the demo fixture the
demo), ``evtms bench all --grid cycle`` (its LUTs are the demo's, copied in:
building them again would take minutes) and nothing that needs a cluster of
one's own (the README gives no such command to copy). Three commands run
lighter than written, each checked in full elsewhere: ``evtms surrogate
train`` with ``--quick --runs-per-mode 3`` (tiny networks; the full training
takes minutes), ``evtms report compare`` with ``--dts 1,10 --repeat 1``, and
``--model physics`` with the cycle maps standing in for the bench physics
(a hot WLTC on the physics takes minutes; ``test_simulate_cli`` runs the
physics end to end on a short trace).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
from pathlib import Path

import pytest
from conftest import patch_small_maps
from typer.testing import CliRunner

from evtms.cli import app

README = Path(__file__).resolve().parents[1] / "README.md"
_BLOCK = re.compile(r"```bash\n(.*?)```", re.S)
_HEREDOC = re.compile(r"cat > (\S+) <<'(\w+)'")


def readme_steps() -> list[tuple[str, object]]:
    """('write', (path, text)) and ('run', argv) steps of the README's bash blocks, in order."""
    steps: list[tuple[str, object]] = []
    for block in _BLOCK.findall(README.read_text(encoding="utf-8")):
        lines = iter(block.splitlines())
        for line in lines:
            m = _HEREDOC.match(line)
            if m:
                body = []
                for inner in lines:
                    if inner == m[2]:
                        break
                    body.append(inner)
                steps.append(("write", (m[1], "\n".join(body) + "\n")))
                continue
            for command in line.split("&&"):
                argv = shlex.split(command, comments=True)
                if argv:
                    steps.append(("run", argv))
    return steps


def test_readme_has_the_two_setup_commands_first():
    steps = readme_steps()
    assert steps[0] == ("run", ["python3", "-m", "pip", "install", "."]) and steps[1] == (
        "run",
        ["evtms", "demo", "-o", "out/"],
    )
    assert steps[2][1][:4] == ["python3", "-m", "pip", "install"] and steps[3][1] == ["python3", "-m", "pytest"]
    assert "shared/" not in README.read_text(encoding="utf-8")  # users have no shared/ folder


def test_every_readme_command_works_in_a_fresh_folder(tmp_path, monkeypatch, cycle_luts_dir):

    from evtms.system import refrigerant

    monkeypatch.chdir(tmp_path)
    # 'evtms simulate' builds its cycle maps on 2-3 nodes per axis here (seconds, not half a minute).
    patch_small_maps(monkeypatch)
    monkeypatch.setattr(refrigerant.Refrigerant, "solve_direct", _maps_as_physics)
    lighter = {("surrogate", "train"): ["--quick", "--runs-per-mode", "3"], ("report", "compare"): [
        "--dts", "1,10", "--repeat", "1"]}  # fmt: skip
    runner = CliRunner()
    ran = 0
    for kind, step in readme_steps():
        if kind == "write":
            path, text = step
            Path(path).write_text(text)
            continue
        argv = step
        if argv[0] != "evtms" or argv[1] == "demo":
            continue  # pip, pytest and the demo: see the module notes
        if argv[1:4] == ["bench", "all", "--grid"] and argv[4] == "cycle":
            out = Path(argv[argv.index("-o") + 1])
            out.mkdir(parents=True, exist_ok=True)
            for f in cycle_luts_dir.glob("*.nc"):  # hard links share the session's derived tables
                (out / f.name).unlink(missing_ok=True)  # 'bench all' replaces a file there
                same_device = f.stat().st_dev == out.stat().st_dev
                os.link(f, out / f.name) if same_device else shutil.copy(f, out / f.name)
            continue
        res = runner.invoke(app, argv[1:] + lighter.get(tuple(argv[1:3]), []))
        assert res.exit_code == 0, f"{shlex.join(argv)}\n{res.output}"
        ran += 1
    assert ran >= 25
    for made in ("luts/condenser_44.nc", "condenser.mat", "condenser.csv", "ph.svg", "pt.png", "eb.png", "eb.csv"):
        assert (tmp_path / made).is_file(), made


def _maps_as_physics(self, map_id, x):
    """The physics model's solve, answered by the cycle map (see the module notes)."""
    import numpy as np

    from evtms.system import loop
    from evtms.system.maps import map_interp
    from evtms.system.refrigerant import MAP_NAMES

    cmap = self.maps[MAP_NAMES[map_id]]
    y = np.zeros(loop.N_Y)
    map_interp(*cmap.packed(), np.ascontiguousarray(x[: len(cmap.axes)]), y)
    return y, False, True


@pytest.mark.parametrize("marker", ["...", "old/"])
def test_readme_commands_are_complete(marker):
    """No elided arguments or folders that no earlier command makes."""
    for kind, step in readme_steps():
        if kind == "run" and step[0] == "evtms":
            assert marker not in " ".join(step), step
