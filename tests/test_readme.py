"""Every documented command works, in order, in a fresh folder: the bash blocks of the README, then of
the guides in the pipeline's order (docs/guide/: benches and LUTs, cycle, system, comparison), all in
one folder, each file's commands after the earlier files'; and every Python block of the README and
of docs/ runs.

The commands run in-process (``CliRunner``: CoolProp is imported once), each
must exit 0, and a heredoc (``cat > FILE <<'EOF'``) writes its file. Three
kinds of line are not run here, each covered elsewhere: the set-up commands
(``pip install``, ``evtms demo``: CI runs the first two, the demo fixture the
demo; here ``evtms demo -o OUT`` leaves the session's cycle LUTs in
``OUT/luts/cycle/``, where the demo writes them, for the commands that read
them), ``evtms bench all --grid cycle`` (its LUTs are the session's, linked in:
building them again would take minutes) and nothing that needs a cluster of
one's own (the docs give no such command to copy). Four commands run
lighter than written, each checked in full elsewhere: ``evtms surrogate
train`` with ``--quick --runs-per-mode 3`` (tiny networks; the full training
takes minutes), ``evtms report compare`` with ``--dts 1,10 --repeat 1`` (with ``--controllers``: on UDDS and one
preview), ``evtms sweep`` at
one ambient (``--t-amb 25 --rh-amb 0.4 --sun 0``: its other scenarios are the same code), and
``--model physics`` with the cycle maps standing in for the bench physics
(a hot WLTC on the physics takes minutes; ``test_simulate_cli`` runs the
physics end to end on a short trace).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
from pathlib import Path

import pytest
from conftest import patch_small_maps
from typer.testing import CliRunner

from evtms.cli import app

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: The guides in the pipeline's order: each one's commands run after the earlier ones', in the same folder.
GUIDES = [ROOT / "docs" / "guide" / f"{name}.md" for name in ("benches-and-luts", "cycle", "system", "comparison")]
DOCUMENTED = [README, *GUIDES]
_BLOCK = re.compile(r"```(bash|python)\n(.*?)```", re.S)
_HEREDOC = re.compile(r"cat > (\S+) <<'(\w+)'")


def doc_steps(paths=DOCUMENTED) -> list[tuple[str, object]]:
    """('write', (path, text)), ('run', argv) and ('python', (file, code)) steps of the files' bash and Python
    blocks, file after file, each in order."""
    steps: list[tuple[str, object]] = []
    for path in paths:
        steps += _file_steps(path)
    return steps


def readme_steps() -> list[tuple[str, object]]:
    return doc_steps([README])


def _file_steps(path: Path) -> list[tuple[str, object]]:
    steps: list[tuple[str, object]] = []
    for lang, block in _BLOCK.findall(path.read_text(encoding="utf-8")):
        if lang == "python":
            steps.append(("python", (path.relative_to(ROOT).as_posix(), block)))
            continue
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


def test_the_guides_exist_in_pipeline_order():
    assert all(g.is_file() for g in GUIDES), GUIDES
    assert not set((ROOT / "docs" / "guide").glob("*.md")) - set(GUIDES), "a guide the tests do not run"


def test_every_documented_command_works_in_a_fresh_folder(tmp_path, monkeypatch, cycle_luts_dir, small_map_luts):

    from evtms.system import refrigerant

    monkeypatch.chdir(tmp_path)
    # 'evtms simulate' builds its cycle maps on 2-3 nodes per axis here (seconds, not half a minute).
    patch_small_maps(monkeypatch)
    monkeypatch.setattr(refrigerant.Refrigerant, "solve_direct", _maps_as_physics)
    lighter = {("surrogate", "train"): ["--quick", "--runs-per-mode", "3"], ("report", "compare"): [
        "--dts", "1,10", "--repeat", "1"], ("sweep",): ["--t-amb", "25", "--rh-amb", "0.4", "--sun", "0"]}  # fmt: skip
    runner = CliRunner()
    ran = 0
    for kind, step in doc_steps():
        if kind == "write":
            path, text = step
            Path(path).write_text(text)
            continue
        if kind == "python":
            run_python(*step)
            continue
        argv = step
        if argv[0] != "evtms":
            continue  # pip and pytest: see the module notes
        if argv[1] == "demo":  # the demo's cycle LUTs, where it writes them (see the module notes)
            link_luts(cycle_luts_dir, Path(argv[argv.index("-o") + 1]) / "luts" / "cycle")
            copy_small_maps(small_map_luts, Path(argv[argv.index("-o") + 1]) / "luts" / "cycle")
            continue
        if argv[1:4] == ["bench", "all", "--grid"] and argv[4] == "cycle":
            link_luts(cycle_luts_dir, Path(argv[argv.index("-o") + 1]))
            copy_small_maps(small_map_luts, Path(argv[argv.index("-o") + 1]))
            continue
        extra = lighter.get(tuple(argv[1:3]), lighter.get(tuple(argv[1:2]), []))
        if "--controllers" in argv:  # the controllers on one cycle (test_controllers runs the table in full)
            extra = ["--cycle", "udds", "--preview", "perfect"]
        res = runner.invoke(app, argv[1:] + extra)
        assert res.exit_code == 0, f"{shlex.join(argv)}\n{res.output}"
        ran += 1
    assert ran >= 25
    for made in ("luts/condenser_44.nc", "condenser.mat", "condenser.csv", "ph.svg", "pt.png", "eb.png", "eb.csv"):
        assert (tmp_path / made).is_file(), made


def link_luts(luts: Path, out: Path) -> None:
    """The session's cycle LUTs in ``out``, as 'evtms bench all --grid cycle -o out' leaves them."""
    out.mkdir(parents=True, exist_ok=True)
    for f in luts.glob("*.nc"):  # hard links share the session's derived tables
        (out / f.name).unlink(missing_ok=True)  # 'bench all' replaces a file there
        same_device = f.stat().st_dev == out.stat().st_dev
        os.link(f, out / f.name) if same_device else shutil.copy(f, out / f.name)


def copy_small_maps(shared: Path, luts: Path) -> None:
    """The small-axes maps other tests built from the session's LUTs, copied beside ``luts`` (links to
    the same LUT files, so the same maps): 'evtms simulate' then builds only those not built yet.
    Building maps is the maps' and the simulate command's tests' business; copies, as a build
    replaces a map whose recipe differs."""
    (luts / "maps").mkdir(exist_ok=True)
    for f in (shared / "maps").glob("*.nc"):
        shutil.copy2(f, luts / "maps" / f.name)


def run_python(source: str, code: str) -> None:
    """One documented Python block, run as a script of its own in the current folder."""
    exec(compile(code, f"<python block of {source}>", "exec"), {"__name__": "__main__"})


def python_blocks() -> list[tuple[str, str]]:
    """(file, code) of every Python block of the README and of docs/."""
    files = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    return [step for kind, step in doc_steps(files) if kind == "python"]


def test_every_python_block_is_run():
    """The folder test runs every Python block of the docs: none of them lies outside the files it reads."""
    ran = [step for kind, step in doc_steps() if kind == "python"]
    assert ran == python_blocks() and any(src == "README.md" for src, _ in ran)


def test_the_readme_python_runs_on_the_demo_luts(tmp_path, monkeypatch, small_map_luts, capsys):
    """The README's snippet on its own, with the session's cycle LUTs standing in for the demo's."""
    monkeypatch.chdir(tmp_path)
    patch_small_maps(monkeypatch)
    blocks = [code for src, code in python_blocks() if src == "README.md"]
    assert blocks and all('"out/luts"' in code for code in blocks)
    for code in blocks:
        run_python("README.md", code.replace('"out/luts"', repr(str(small_map_luts))))
    assert capsys.readouterr().out.strip()


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
    """No elided arguments or folders that no earlier command makes, in the README and the guides."""
    for kind, step in doc_steps():
        if kind == "run" and step[0] == "evtms":
            assert marker not in " ".join(step), step


def test_docs_links_resolve():
    """Every relative link of the README and of docs/ names a file of the checkout (and a heading of it)."""
    for path in [README, *(ROOT / "docs").rglob("*.md")]:
        for target in _LINK.findall(path.read_text(encoding="utf-8")):
            if re.match(r"[a-z]+:", target):
                continue  # http:, https:, mailto:
            name, _, anchor = target.partition("#")
            dest = (path.parent / name).resolve() if name else path
            assert dest.is_relative_to(ROOT) and dest.exists(), f"{path.relative_to(ROOT)}: {target}"
            if anchor:
                assert anchor in _anchors(dest), f"{path.relative_to(ROOT)}: {target}"


_LINK = re.compile(r"\]\(([^)\s]+)\)")


def _anchors(path: Path) -> set[str]:
    """GitHub's anchors of a Markdown file's headings."""
    heads = re.findall(r"^#+ (.+)$", path.read_text(encoding="utf-8"), re.M)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in heads}


def test_performance_page_is_what_the_benchmarks_write(tmp_path):
    """docs/performance.md is performance_page.py's page of the stored runs; a run rewrites it whole."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("performance_page", ROOT / "benchmarks" / "performance_page.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    assert page.render(page.load()) == (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    results, out = tmp_path / "runs.json", tmp_path / "performance.md"
    results.write_text((ROOT / "benchmarks" / "performance.json").read_text(encoding="utf-8"))
    machine = {"date": "2000-01-02 03:04 UTC", "cpu": "Test CPU", "cores": "3", "load": "0.1", "commit": "abc1234"}
    rows = [{"figure": "LUT cycle, 10 points in one batch", "value": "1.000 ms a point", "target": ""}]
    page.write("cycle", {"machine": machine, "rows": rows}, results_path=results, page=out)
    text = out.read_text(encoding="utf-8")
    assert "| 2000-01-02 03:04 UTC | Test CPU, 3 cores | abc1234 |" in text  # the header names the run
    assert "Measured on 2000-01-02 03:04 UTC, Test CPU, 3 cores, load average 0.1." in text
    assert "| LUT cycle, 10 points in one batch | 1.000 ms a point | |" in text and "9.9-10.2 ms" not in text
    loop_ms = json.loads(results.read_text(encoding="utf-8"))["system"]["performance"]["loop_dt0.1_s"] * 1e3
    assert f"| {loop_ms:.1f} ms |" in text  # the other table's run is kept
    with pytest.raises(ValueError, match="unknown table"):
        page.write("nope", {}, results_path=results, page=out)
