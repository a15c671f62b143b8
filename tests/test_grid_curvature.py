"""benchmarks/grid_curvature.py prices a node by what the LUT interpolator misses without it: its
interpolant must be the interpolator's (quadratic correction included), and its greedy must keep
the nodes where a function curves."""

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
    return np.ones(shape), np.full(shape, np.nan)


@pytest.mark.parametrize("p", [1, 3, 5])
def test_drop_cost_is_the_interpolators_miss(curvature, p):
    x = np.array([0.0, 0.3, 0.5, 1.1, 1.4, 2.0, 2.2, 3.0])
    y = np.linspace(0.0, 1.0, 4)
    f = np.exp(x)[:, None] * np.cos(2 * y)[None, :]
    nodes = list(range(x.size))
    cost = curvature._drop_cost(f, _unit(f.shape), x, nodes, p, (1.0, np.inf))
    kept = [i for i in nodes if i != p]
    itp = Interpolator([("x", x[kept]), ("y", y)], {"f": f[kept]}, curvature=True)
    at = itp({"x": np.full(y.size, x[p]), "y": y})["f"]
    assert cost == pytest.approx(np.abs(f[p] - at).max(), rel=1e-12)
    assert cost > 1e-3  # an exponential is not quadratic: the node is worth something


def test_a_quadratic_costs_nothing_and_keeps_only_its_ends(curvature):
    # The quadratic correction is exact for a quadratic, so any node may go, down to the three
    # the correction needs; a cubic's nodes cost in proportion to their cells.
    x = np.linspace(0.0, 1.0, 9)
    quad = (3 * x**2 - x)[:, None] * np.ones((1, 2))
    kept = curvature._thinned(quad, _unit(quad.shape), x, (1e-9, np.inf))
    assert len(kept) == 3 and kept[0] == 0 and kept[-1] == x.size - 1
    cubic = (x**3)[:, None] * np.ones((1, 2))
    kept = curvature._thinned(cubic, _unit(cubic.shape), x, (1e-4, np.inf))
    assert 3 < len(kept) < x.size


def test_nodes_stay_where_the_function_bends(curvature):
    # A knee at 0.5 (a smoothed kink): the nodes left cluster around it.
    x = np.linspace(0.0, 1.0, 41)
    f = np.logaddexp(0.0, (x - 0.5) * 40)[:, None] / 40 * np.ones((1, 2))
    kept = x[curvature._thinned(f, _unit(f.shape), x, (2e-4, np.inf))]
    near = np.abs(kept - 0.5) <= 0.15
    assert near.sum() > (~near).sum()


def test_the_flow_measure_binds_where_its_threshold_is_tighter(curvature):
    x = np.linspace(0.0, 1.0, 9)
    f = np.exp(2 * x)[:, None] * np.ones((1, 2))
    ones = np.ones(f.shape)
    loose = curvature._thinned(f, (ones, ones), x, (1.0, 1.0))
    tight = curvature._thinned(f, (ones, ones), x, (1.0, 1e-5))
    assert len(tight) > len(loose)
