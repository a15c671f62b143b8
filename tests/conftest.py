"""Shared fixtures: one fluid and one thesis sweep per bench for the whole session."""

from __future__ import annotations

import pytest

from evtms.benches import BENCHES
from evtms.benches.grid import build_grid
from evtms.benches.sweep import run_sweep
from evtms.fluid import Fluid
from evtms.params import Parameters


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory):
    """The session's own cache of derived LUT tables (subprocesses inherit it), never the user's."""
    import os

    from evtms.luts.cache import CACHE_DIR_ENV

    old = os.environ.get(CACHE_DIR_ENV)
    os.environ[CACHE_DIR_ENV] = str(tmp_path_factory.mktemp("evtms-cache"))
    yield
    if old is None:
        os.environ.pop(CACHE_DIR_ENV, None)
    else:
        os.environ[CACHE_DIR_ENV] = old


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


@pytest.fixture(scope="session")
def cycle_luts_dir(tmp_path_factory, params):
    """Every bench's LUT on the 'cycle' grid preset, as 'evtms bench all --grid cycle' writes them."""
    from evtms.demo import ensure_luts

    folder = tmp_path_factory.mktemp("cycle_luts")
    ensure_luts(folder, "cycle", params, workers=2)
    return folder


#: Cycle-map axes of 2-3 nodes (maps in seconds instead of the full axes' half minute).
SMALL_MAP_AXES = {
    "speed": [0.1, 0.4, 1.0],
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


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory, cycle_luts_dir):
    """One full 'evtms demo' into a fresh folder that already holds the cycle LUTs (the demo reuses
    up-to-date LUTs: it computes the thesis ones, solves, draws), shared by the tests."""
    import shutil

    from evtms.demo import run_demo

    out = tmp_path_factory.mktemp("demo")
    shutil.copytree(cycle_luts_dir, out / "luts" / "cycle")
    messages = []
    from evtms.system.maps import MapSettings

    result = run_demo(out, workers=2, notify=messages.append, map_settings=MapSettings(axes=SMALL_MAP_AXES))
    return out, result, messages


@pytest.fixture(scope="session")
def cycle_luts(cycle_luts_dir):
    from evtms.cycle import load_cycle_luts

    return load_cycle_luts(cycle_luts_dir)
