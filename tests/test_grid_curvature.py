"""benchmarks/grid_curvature.py prices a node by what the LUT interpolator misses without it: its
interpolant must be the interpolator's (quadratic correction included), every miss a thinned axis
leaves must stay within the threshold, and the nodes kept must sit where a function curves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evtms.luts import Interpolator

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture
def curvature(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import grid_curvature

    return grid_curvature


def _unit(shape) -> tuple[np.ndarray, np.ndarray]:
    """Outlet weights 1, no flow measure."""
    return np.ones(shape), np.full(shape, np.nan)


def _interpolator_miss(x, y, f, kept) -> float:
    """The largest miss of the LUT interpolator on the ``kept`` nodes of axis 0 at every node of ``x``."""
    itp = Interpolator([("x", x[kept]), ("y", y)], {"f": f[kept]}, curvature=True)
    xs, ys = np.meshgrid(x, y, indexing="ij")
    return float(np.abs(itp({"x": xs.ravel(), "y": ys.ravel()})["f"].reshape(f.shape) - f).max())


@pytest.mark.parametrize("p", [1, 3, 6])
def test_a_drop_misses_what_the_interpolator_misses(curvature, p):
    x = np.array([0.0, 0.3, 0.5, 1.1, 1.4, 2.0, 2.2, 3.0])
    y = np.linspace(0.0, 1.0, 4)
    f = np.exp(x)[:, None] * np.cos(2 * y)[None, :]
    outlet, _ = curvature.drop_misses(f, _unit(f.shape), x, list(range(x.size)), p)
    kept = [i for i in range(x.size) if i != p]
    assert outlet == pytest.approx(_interpolator_miss(x, y, f, kept), rel=1e-12)
    assert outlet > 1e-3  # an exponential is not quadratic: the node is worth something


@pytest.mark.parametrize("seed", range(12))
def test_every_miss_a_thinned_axis_leaves_stays_within_the_threshold(curvature, seed):
    # Dropping a node changes its neighbours' second differences, and so the cells on either side
    # too, where nodes dropped before sit: uneven axes show it.
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.uniform(0.2, 1.0, 32))
    y = np.linspace(0.0, 1.0, 3)
    f = np.sin(x / 3)[:, None] * (1 + y)[None, :]
    tau = 1e-3
    kept, dropped = curvature.thin_axis(f, _unit(f.shape), x, (tau, np.inf))
    assert dropped and len(kept) + len(dropped) == x.size
    assert _interpolator_miss(x, y, f, kept) <= tau


def test_a_quadratic_costs_nothing_a_cubic_does(curvature):
    # The quadratic correction is exact for a quadratic: nodes go down to the three it needs.
    x = np.linspace(0.0, 1.0, 9)
    quad = (3 * x**2 - x)[:, None] * np.ones((1, 2))
    assert len(curvature.thin_axis(quad, _unit(quad.shape), x, (1e-9, np.inf))[0]) == 3
    cubic = (x**3)[:, None] * np.ones((1, 2))
    assert 3 < len(curvature.thin_axis(cubic, _unit(cubic.shape), x, (1e-4, np.inf))[0]) < x.size


def test_nodes_stay_where_the_function_bends(curvature):
    # A knee at 0.5 (a smoothed kink): the nodes left cluster around it.
    x = np.linspace(0.0, 1.0, 41)
    f = np.logaddexp(0.0, (x - 0.5) * 40)[:, None] / 40 * np.ones((1, 2))
    kept = x[curvature.thin_axis(f, _unit(f.shape), x, (2e-4, np.inf))[0]]
    near = np.abs(kept - 0.5) <= 0.15
    assert near.sum() > (~near).sum()


def test_the_flow_measure_takes_the_99th_percentile_and_binds_when_tighter(curvature):
    x = np.linspace(0.0, 1.0, 9)
    f = np.exp(2 * x)[:, None] * np.ones((1, 400))
    ones = np.ones(f.shape)
    spiked = ones.copy()
    spiked[:, 0] = 1e9  # one column in 400 where the flow hardly responds: above the 99th percentile
    spiked[:, 1] = np.inf
    loose = curvature.thin_axis(f, (ones, ones), x, (1.0, 1.0))[0]
    assert curvature.thin_axis(f, (ones, spiked), x, (1.0, 1.0))[0] == loose
    assert len(curvature.thin_axis(f, (ones, ones), x, (1.0, 1e-5))[0]) > len(loose)


def test_nodes_outside_the_roots_band_cost_nothing(curvature):
    # NaN weights (no root lies there): whatever the function does, the axis thins to three nodes.
    x = np.linspace(0.0, 1.0, 9)
    f = np.sin(8 * x)[:, None] * np.ones((1, 2))
    nowhere = np.full(f.shape, np.nan)
    assert len(curvature.thin_axis(f, (nowhere, nowhere), x, (1e-6, 1e-6))[0]) == 3
