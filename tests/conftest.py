"""Shared fixtures: one fluid and one thesis sweep per bench for the whole session."""

from __future__ import annotations

import pytest

from evtms.benches import BENCHES
from evtms.benches.grid import build_grid
from evtms.benches.sweep import run_sweep
from evtms.fluid import Fluid
from evtms.params import Parameters


@pytest.fixture(scope="session")
def fluid() -> Fluid:
    return Fluid()


@pytest.fixture(scope="session")
def params() -> Parameters:
    return Parameters()


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
def cycle_luts_dir(tmp_path_factory, params, fluid):
    """The four LUTs on the 'cycle' grid preset, written once per session (about a minute)."""
    from evtms.luts.io import write_lut

    folder = tmp_path_factory.mktemp("cycle_luts")
    for name, bench in BENCHES.items():
        ds = run_sweep(bench, build_grid(bench, "cycle", {}), params, grid_name="cycle", fluid=fluid)
        write_lut(ds, folder / f"{name}.nc")
    return folder


@pytest.fixture(scope="session")
def cycle_luts(cycle_luts_dir):
    from evtms.cycle import load_cycle_luts

    return load_cycle_luts(cycle_luts_dir)
