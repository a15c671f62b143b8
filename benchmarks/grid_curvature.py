"""Evaporator grid nodes chosen where the LUT cycle's interpolant needs them (for ``grid_study.py``).

The LUT cycle interpolates the evaporator's outlet as ``approach_log``
(:mod:`evtms.cycle.approach`) with a quadratic correction along every axis:
the second differences at a cell's two nodes (three-point divided
differences on the axis as it is, an end node taking its neighbour's),
interpolated to the query and times ``(x - x_a)(x - x_b) / 2``
(:class:`evtms.luts.Interpolator`). Dropping an interior node ``i`` of one
axis leaves its neighbours one cell; the interpolant of that cell, with the
second differences of the thinned axis, misses the LUT's value at ``i`` (and
at nodes dropped before inside the cell) by what that node was worth. That
miss is taken at the nodes where the cycle's roots lie, an outlet
superheat within ``band`` (the valves' setpoints, 5-10 K, and the searches
around them), in two measures:

- in outlet enthalpy (``|dh/d ln psi| = span * psi``, the approach
  transform's slope) and kelvin (``/ CP_SCALE``), its largest value over
  the grid: what the superheat closure, and so the suction pressure, sees;
- in flow: the miss over ``|d ln psi / d ln mdot|`` [%], the share by which
  the flow that meets the setpoint moves, which sets a valve's opening and
  the split between two parallel branches. Where the outlet hardly responds
  to the flow (the vapour zone's Nusselt corners) that share is unbounded at
  a few nodes, so its 99th percentile over the grid is taken.

A node's cost is the larger of the two, each over its threshold (``tau`` [K]
and ``tau_flow`` [%]). :func:`curvature_nodes` drops, axis by axis, the node
of least cost, then recomputes its neighbours' costs on the thinned axis,
until the least cost reaches 1: the nodes that remain are where the outlet
curves.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evtms.cycle import load_cycle_luts
from evtms.cycle.api import SaturationCurve
from evtms.cycle.approach import SUPERHEAT_MIN, approach_log
from evtms.cycle.state import CP_SCALE
from evtms.cycle.tables import vapour_table
from evtms.fluid import Fluid
from evtms.luts import open_lut

#: The secondary inlet of the evaporator's approach transform.
_SECONDARY = "T_air_in"


def curvature_nodes(
    folder: Path, tau: float, tau_flow: float = np.inf, band: tuple[float, float] = (2.0, 20.0)
) -> dict[str, np.ndarray]:
    """The evaporator LUT's axes in ``folder`` (its cycle LUTs) with the nodes of least cost dropped
    while the outlet's miss stays below ``tau`` [K] and the flow's below ``tau_flow`` [%] (the
    module's text); only axes of three nodes or more."""
    luts = load_cycle_luts(str(folder), "cabin")
    lut = luts["evaporator"]
    ds = open_lut(lut.path, "evaporator", ["h_out_continued", "p_out", "T_out"])
    dims = list(ds["status"].dims)
    axes = {d: np.asarray(ds[d].values, float) for d in dims}
    p_out = ds["p_out"].values
    t_sec = np.broadcast_to(axes[_SECONDARY].reshape([-1 if d == _SECONDARY else 1 for d in dims]), p_out.shape)
    vapour = vapour_table(luts)
    log_psi = approach_log(ds["h_out_continued"].values, p_out, t_sec, vapour)
    _, span = vapour.rise_to(p_out, t_sec, SUPERHEAT_MIN)
    superheat = ds["T_out"].values - SaturationCurve(Fluid()).temperature(p_out)
    roots = (superheat >= band[0]) & (superheat <= band[1])
    # Per unit of ln psi: the outlet enthalpy's change [K] and the flow's [%], where the roots lie.
    per_kelvin = np.where(roots, span * np.exp(log_psi), np.nan) / CP_SCALE
    response = np.abs(np.gradient(log_psi, np.log(axes["mdot"]), axis=dims.index("mdot")))
    with np.errstate(divide="ignore"):
        per_flow = np.where(roots, 100.0 / response, np.nan)
    kept = {}
    for j, d in enumerate(dims):
        if axes[d].size >= 3:
            f, weights = np.moveaxis(log_psi, j, 0), (np.moveaxis(per_kelvin, j, 0), np.moveaxis(per_flow, j, 0))
            kept[d] = axes[d][_thinned(f, weights, axes[d], (tau, tau_flow))]
    return kept


def _thinned(f: np.ndarray, weights: tuple, x: np.ndarray, taus: tuple[float, float]) -> list[int]:
    """The nodes of ``x`` kept: the least costly dropped one at a time while its cost is below 1."""
    nodes = list(range(x.size))
    while len(nodes) > 3:
        costs = [_drop_cost(f, weights, x, nodes, p, taus) for p in range(1, len(nodes) - 1)]
        p = int(np.argmin(costs))
        if costs[p] >= 1.0:
            break
        nodes.pop(p + 1)
    return nodes


def _drop_cost(f: np.ndarray, weights: tuple, x: np.ndarray, nodes: list[int], p: int, taus: tuple) -> float:
    """Dropping ``nodes[p]``: the interpolant's miss along axis 0 of ``f`` at the grid nodes inside
    the cell it makes, in the outlet (largest, over ``taus[0]``) and in the flow (99th percentile,
    over ``taus[1]``), the larger of the two."""
    rest = nodes[:p] + nodes[p + 1 :]
    a, b = rest[p - 1], rest[p]
    d2a, d2b = _second_difference(f, x, rest, p - 1), _second_difference(f, x, rest, p)
    misses = []
    for i in range(a + 1, b):
        t = (x[i] - x[a]) / (x[b] - x[a])
        d2 = (1 - t) * d2a + t * d2b
        value = (1 - t) * f[a] + t * f[b] + np.where(np.isfinite(d2), d2 * (x[i] - x[a]) * (x[i] - x[b]) / 2, 0.0)
        misses.append(np.abs(f[i] - value))
    miss = np.stack(misses)
    inside = slice(a + 1, b)
    outlet, flow = miss * weights[0][inside], miss * weights[1][inside]
    outlet, flow = outlet[np.isfinite(outlet)], flow[np.isfinite(flow)]
    cost = float(outlet.max()) / taus[0] if outlet.size else 0.0
    if flow.size and np.isfinite(taus[1]):
        cost = max(cost, float(np.quantile(flow, 0.99)) / taus[1])
    return cost


def _second_difference(f: np.ndarray, x: np.ndarray, nodes: list[int], p: int) -> np.ndarray:
    """The interpolator's second difference at ``nodes[p]`` on the axis of ``nodes`` (an end node takes
    its neighbour's, as :func:`evtms.luts.interp.second_difference`)."""
    q = min(max(p, 1), len(nodes) - 2)
    k0, k1, k2 = nodes[q - 1], nodes[q], nodes[q + 1]
    h0, h1 = x[k1] - x[k0], x[k2] - x[k1]
    return 2.0 * ((f[k2] - f[k1]) / h1 - (f[k1] - f[k0]) / h0) / (h0 + h1)
