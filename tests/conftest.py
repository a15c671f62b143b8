"""Shared fixtures: one fluid and one thesis sweep per bench for the whole session."""

from __future__ import annotations

import os

# One OpenBLAS thread per process, set before NumPy or SciPy load it (subprocesses, dask workers and
# the background job inherit it). The suite shares two cores with the background LUT build, and
# OpenBLAS's second thread spin-waits for a core at every small product (each step of a simulation
# has some): in-process simulations ran about ten times slower beside the build (test_compare's
# runs: 2.5 s alone, 28-38 s beside it). Every process of the run uses the same single thread.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest

from evtms.benches import BENCHES
from evtms.benches.grid import build_grid
from evtms.benches.parameters import Parameters
from evtms.benches.sweep import run_sweep
from evtms.fluid import Fluid


@pytest.fixture(scope="session", autouse=True)
def _forkserver_preload():
    """The fork server that ``PoolRunner``'s workers start from loads CoolProp and the benches once.

    Every worker of every pool would import them itself (about 2 s of CPU each, beside the
    background build); forked from a server that holds them, it starts with them and computes
    the same chunks. Set before any test starts a pool: the server starts with the first one.
    """
    import multiprocessing

    multiprocessing.set_forkserver_preload(["CoolProp", "evtms.benches", "evtms.benches.chunked"])


#: The environment variable naming the run's shared folder (made by the first process of the run,
#: inherited by xdist's workers): the derived tables' cache, the background job's LUTs and demo.
SHARED_ENV = "EVTMS_TEST_SHARED"


def _is_worker(config) -> bool:
    return hasattr(config, "workerinput")


def pytest_configure(config):
    """The run's shared folder and its cache of derived LUT tables (never the user's), made once by
    the first process (pytest itself, or xdist's controller before it starts the workers)."""
    import tempfile

    from evtms.luts.cache import CACHE_DIR_ENV

    if _is_worker(config):
        return
    shared = tempfile.mkdtemp(prefix="evtms-tests-")
    config._evtms_env = {k: os.environ.get(k) for k in (SHARED_ENV, CACHE_DIR_ENV)}
    os.environ[SHARED_ENV] = shared
    os.environ[CACHE_DIR_ENV] = os.path.join(shared, "cache")


def pytest_unconfigure(config):
    """Stop the background job (its whole process group) and remove the shared folder."""
    import json
    import shutil
    import signal

    if _is_worker(config) or not hasattr(config, "_evtms_env"):
        return
    shared = os.environ.get(SHARED_ENV)
    job = os.path.join(shared or "", "job.json")
    if shared and os.path.exists(job):
        with open(job) as f:
            pid = json.load(f)["pid"]
        try:
            os.killpg(pid, signal.SIGTERM)
        except OSError:
            pass  # finished already
    if shared:
        shutil.rmtree(shared, ignore_errors=True)
    for k, v in config._evtms_env.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@pytest.fixture(scope="session")
def fluid() -> Fluid:
    return Fluid()


@pytest.fixture(scope="session")
def params() -> Parameters:
    return Parameters()


@pytest.fixture(scope="session")
def small_condenser_grid():
    """A small condenser grid with two inputs of one value (p_in, T_res: fixed inputs of the LUT)."""
    import numpy as np

    small = {
        "mdot": np.array([0.005, 0.007]),
        "fan": np.array([0.2, 0.5]),
        "p_in": np.array([1.0e6]),
        "T_in": np.array([340.0, 360.0]),
        "T_res": np.array([300.0]),
    }
    return build_grid(BENCHES["condenser"], None, small)


@pytest.fixture(scope="session")
def thesis(fluid, params):
    """Thesis-grid datasets by component, computed once."""
    cache = {}

    def get(component: str):
        if component not in cache:
            bench = BENCHES[component]
            grid = build_grid(bench, "thesis", {})
            cache[component] = run_sweep(bench, grid, params, grid_name="thesis", fluid=fluid)
        return cache[component]

    return get


#: Cycle-map axes of 2-3 nodes (maps in seconds instead of the full axes' half minute).
SMALL_MAP_AXES = {
    "speed": [0.1, 0.4, 1.0],
    "fan": [0.3, 1.0],
    "blower": [0.1, 0.5, 1.0],
    "T_amb": [268.15, 298.15, 313.15],
    "T_air_in": [288.15, 303.15, 313.15],
    "RH_air_in": [0.4, 0.6],
    "u_pump": [0.3, 1.0],
    "T_coolant_in": [283.15, 303.15],
}


@pytest.fixture(scope="session")
def small_map_axes():
    return SMALL_MAP_AXES


def sigint_default() -> None:
    """``preexec_fn`` of a child process a test interrupts: SIGINT at its default disposition.

    A shell starts a background job (``nohup``, a script's ``&``) with SIGINT ignored, and a
    child inherits that: its Python would never raise KeyboardInterrupt and the test would see
    it run to the end. With the default disposition the child's Python installs its own handler.
    """
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def one_error_line(result, *fragments: str) -> str:
    """A CLI result that failed as bad input must: exit 2 and one ``error: ...`` line holding every fragment."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


def patch_small_maps(mp: pytest.MonkeyPatch) -> None:
    """Make ``evtms.system.refrigerant`` build its cycle maps on :data:`SMALL_MAP_AXES` (seconds, not a minute)."""
    import dataclasses

    from evtms.system import refrigerant

    full = refrigerant.map_settings
    mp.setattr(refrigerant, "map_settings", lambda p: dataclasses.replace(full(p), axes=SMALL_MAP_AXES))


@pytest.fixture(scope="session")
def small_map_luts(cycle_luts_dir, tmp_path_factory):
    """A folder linking the session's cycle LUTs, where the tests that patch the maps to the small axes build
    them once and share them (the maps are cached beside the LUTs)."""
    import os

    folder = tmp_path_factory.mktemp("small_maps") / "luts"
    folder.mkdir()
    for f in cycle_luts_dir.glob("*.nc"):
        os.symlink(f, folder / f.name)
    return folder


@pytest.fixture()
def small_maps(monkeypatch):
    """Cycle maps on 2-3 nodes per axis for this test (:func:`patch_small_maps`)."""
    patch_small_maps(monkeypatch)


#: What the collected tests need of the background job (set at collection).
_NEEDS = {"cycle_luts": False, "demo": False}

#: The background job: the cycle LUTs (``evtms.workflows.demo.ensure_luts``, as 'evtms bench all --grid cycle'
#: writes them), a marker when they are complete, the derived tables every circuit reads built into the
#: run's cache (one point each; the tests that need them then find them, and wait for one being built:
#: the cache locks it), then (if asked) 'evtms demo' into a fresh folder holding hard links to them (the
#: same cache entries), with its result as JSON; a ``failed`` marker if any of it raises. With
#: ``EVTMS_TEST_CYCLE_LUTS=DIR`` (development loops only; CI leaves it unset and builds them) the LUTs of
#: DIR are copied first, and only the ones that are stale for the current parameters are built.
_BACKGROUND = """
import json
import os
import shutil
import sys
import traceback
from pathlib import Path


def main(luts, work, demo, axes):
    from evtms.workflows.demo import ensure_luts
    from evtms.benches.parameters import Parameters

    seed = os.environ.get("EVTMS_TEST_CYCLE_LUTS")
    if seed:  # a development loop's copy of LUTs built before; ensure_luts rebuilds any stale or missing
        for f in sorted(Path(seed).glob("*.nc")):
            shutil.copy2(f, luts / f.name)
    ensure_luts(luts, "cycle", Parameters(), workers=2)
    if demo:
        out = Path(demo)
        (out / "luts" / "cycle").mkdir(parents=True)
        for f in sorted(luts.glob("*.nc")):  # before the tests may add map caches to the folder
            try:
                os.link(f, out / "luts" / "cycle" / f.name)
            except OSError:  # another file system: a copy (its own cache entries)
                shutil.copy2(f, out / "luts" / "cycle" / f.name)
    (work / "luts.done").touch()

    import numpy as np

    from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
    from evtms.cycle.topology import INPUTS, TOPOLOGIES

    for name in ("cabin+wcc", "hp", "cabin+chiller", "chiller", "cabin"):  # those the tests need last first
        inputs = {k: np.array([INPUTS[k].default]) for k in TOPOLOGIES[name].inputs}
        run_cycle(OperatingPoints(**inputs), load_cycle_luts(luts, name), circuit=name)
    if demo:
        from evtms.workflows.demo import run_demo
        from evtms.system.maps import MapSettings

        messages = []
        r = run_demo(out, workers=2, notify=messages.append, map_settings=MapSettings(axes=axes))
        result = {"index": str(r.index), "computed": r.computed, "reused": r.reused, "timings": r.timings}
        (work / "demo.json").write_text(json.dumps({"result": result, "messages": messages}))


os.nice(10)  # the tests run first
work = Path(sys.argv[2])
try:
    main(Path(sys.argv[1]), work, sys.argv[3], json.loads(sys.argv[4]))
except BaseException:
    traceback.print_exc()
    sys.stdout.flush()
    (work / "failed").touch()
    raise
"""


@pytest.hookimpl(trylast=True)  # after -m / -k deselection: only the tests that will run count
def pytest_collection_modifyitems(session, config, items):
    """Modules that use the cycle LUTs run last (module order and the order within a module kept).

    Building the cycle LUTs takes about 1.5 min of both cores, while most of the suite runs on one
    core. The build (and then the demo) starts with the session in a child process
    (``_background``) and overlaps the modules that do not need it, instead of blocking the first
    one that does.
    """
    # Per module using the LUTs: how many of its tests run before the first one that needs them.
    before: dict[str, int] = {}
    seen: dict[str, int] = {}
    for item in items:
        name = item.module.__name__
        if "cycle_luts_dir" in item.fixturenames:
            before.setdefault(name, seen.get(name, 0))
        seen[name] = seen.get(name, 0) + 1
        _NEEDS["demo"] = _NEEDS["demo"] or "demo_run" in item.fixturenames
    _NEEDS["cycle_luts"] = bool(before)
    # Modules without the LUTs first, then those that can run longest before they need them
    # (e.g. test_topology's direct solves). sort is stable: a module stays in one piece, in order.
    items.sort(key=lambda item: (item.module.__name__ in before, -before.get(item.module.__name__, 0)))


@pytest.fixture(scope="session", autouse=True)
def _background():
    """The run's background job if a collected test needs the cycle LUTs: started by the first process
    that asks (xdist's workers share it through the run's folder), stopped when the run ends
    (:func:`pytest_unconfigure`). ``None`` where no collected test needs it."""
    import fcntl
    import json
    import subprocess
    import sys
    from pathlib import Path

    if not _NEEDS["cycle_luts"]:
        return None
    shared = Path(os.environ[SHARED_ENV])
    job = {
        "luts": shared / "cycle_luts",
        "work": shared / "background",
        "demo": shared / "background" / "demo" if _NEEDS["demo"] else "",
        "log": shared / "background.log",
    }
    with open(shared / "start.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (shared / "job.json").exists():
            job["luts"].mkdir()
            job["work"].mkdir()
            with open(job["log"], "wb") as log:
                # Its own process group: the run's end stops the job and its workers.
                proc = subprocess.Popen(
                    [sys.executable, "-c", _BACKGROUND, str(job["luts"]), str(job["work"]), str(job["demo"]),
                     json.dumps(SMALL_MAP_AXES)],
                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                )  # fmt: skip
            (shared / "job.json").write_text(json.dumps({"pid": proc.pid}))
    return job


def _wait_for(job, marker: str, what: str):
    """Wait until the background job writes ``marker`` in its folder; fail with its log if it fails."""
    import time

    while not (job["work"] / marker).exists():
        if (job["work"] / "failed").exists():
            log = job["log"].read_text(errors="replace")
            pytest.fail(f"{what} failed in the background job:\n{log}", pytrace=False)
        time.sleep(0.1)


@pytest.fixture(scope="session")
def cycle_luts_dir(_background, tmp_path_factory, params):
    """Every bench's LUT on the 'cycle' grid preset, as 'evtms bench all --grid cycle' writes them
    (``evtms.workflows.demo.ensure_luts(folder, "cycle", Parameters(), workers=2)``, started with the run)."""
    if _background is None:  # requested by name at run time only: build it here
        from evtms.workflows.demo import ensure_luts

        folder = tmp_path_factory.mktemp("cycle_luts")
        ensure_luts(folder, "cycle", params, workers=2)
        return folder
    _wait_for(_background, "luts.done", "building the cycle LUTs")
    return _background["luts"]


@pytest.fixture(scope="session")
def demo_run(_background, tmp_path_factory, cycle_luts_dir):
    """One full 'evtms demo' into a fresh folder that already holds the cycle LUTs (the demo reuses
    up-to-date LUTs: it computes the thesis ones, solves, draws), shared by the tests. It runs in
    the background job (while other tests run) as
    ``run_demo(out, workers=2, notify=messages.append, map_settings=MapSettings(axes=SMALL_MAP_AXES))``."""
    import json
    from pathlib import Path

    from evtms.workflows.demo import DemoResult

    if _background is None or not _background["demo"]:  # requested by name at run time only
        import shutil

        from evtms.system.maps import MapSettings
        from evtms.workflows.demo import run_demo

        out = tmp_path_factory.mktemp("demo")
        shutil.copytree(cycle_luts_dir, out / "luts" / "cycle")
        messages = []
        result = run_demo(out, workers=2, notify=messages.append, map_settings=MapSettings(axes=SMALL_MAP_AXES))
        return out, result, messages
    _wait_for(_background, "demo.json", "the demo")
    saved = json.loads((_background["work"] / "demo.json").read_text())
    r = saved["result"]
    result = DemoResult(index=Path(r["index"]), computed=r["computed"], reused=r["reused"], timings=r["timings"])
    return _background["demo"], result, saved["messages"]


@pytest.fixture(scope="session")
def cycle_luts(cycle_luts_dir):
    from evtms.cycle import load_cycle_luts

    return load_cycle_luts(cycle_luts_dir)
