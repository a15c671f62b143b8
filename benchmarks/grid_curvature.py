"""Evaporator grid nodes chosen where the LUT cycle's interpolant needs them (for ``grid_study.py``).

The LUT cycle interpolates the evaporator's outlet as ``approach_log``
(:mod:`evtms.cycle.approach`) with a quadratic correction along every axis:
the second differences at a cell's two nodes (three-point divided
differences on the axis as it is, an end node taking its neighbour's),
interpolated to the query and times ``(x - x_a)(x - x_b) / 2``
(:class:`evtms.luts.Interpolator`). Dropping an interior node of one axis
changes the second differences at its two neighbours, and so the
interpolant of the cell it leaves and of the cells on either side: at the
grid nodes inside those three cells (the node itself and any dropped
before) the interpolant now misses the LUT's values. That miss is taken at
the nodes where the cycle's roots lie, an outlet superheat within ``band``
(the valves' setpoints, 5-10 K, and the searches around them), in two
measures:

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

Each axis is thinned on its own; thinned together, their misses may add up (the thresholds
bound each axis's, not the grid's): the cycle against the direct physics
(``grid_study.py``) judges the grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms.cycle import load_cycle_luts
from evtms.cycle.api import SaturationCurve
from evtms.cycle.approach import SUPERHEAT_MIN, approach_log
from evtms.cycle.state import CP_SCALE
from evtms.cycle.tables import vapour_table
from evtms.fluid import Fluid
from evtms.luts import open_lut
from evtms.luts.interp import second_difference

#: The secondary inlet of the evaporator's approach transform.
_SECONDARY = "T_air_in"


@dataclass(frozen=True)
class Dropped:
    """A node dropped: its axis and value, and the misses it left [K, %] (module's text)."""

    axis: str
    value: float
    outlet: float
    flow: float


def curvature_nodes(
    folder: Path,
    tau: float,
    tau_flow: float = np.inf,
    band: tuple[float, float] = (2.0, 20.0),
    dropped: list[Dropped] | None = None,
) -> dict[str, np.ndarray]:
    """The evaporator LUT's axes in ``folder`` (its cycle LUTs) with the nodes of least cost dropped
    while the outlet's miss stays below ``tau`` [K] and the flow's below ``tau_flow`` [%] (the
    module's text); only axes of three nodes or more. The nodes dropped go into ``dropped``."""
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
    # Per unit of ln psi: the outlet enthalpy's change [K] and the flow's [%], where the roots lie
    # (infinite where the outlet does not respond to the flow).
    per_kelvin = np.where(roots, span * np.exp(log_psi), np.nan) / CP_SCALE
    response = np.abs(np.gradient(log_psi, np.log(axes["mdot"]), axis=dims.index("mdot")))
    with np.errstate(divide="ignore"):
        per_flow = np.where(roots, 100.0 / response, np.nan)
    kept = {}
    for j, d in enumerate(dims):
        if axes[d].size >= 3:
            f, weights = np.moveaxis(log_psi, j, 0), (np.moveaxis(per_kelvin, j, 0), np.moveaxis(per_flow, j, 0))
            nodes, misses = thin_axis(f, weights, axes[d], (tau, tau_flow))
            kept[d] = axes[d][nodes]
            if dropped is not None:
                dropped.extend(Dropped(d, float(axes[d][i]), *m) for i, m in misses)
    return kept


def thin_axis(
    f: np.ndarray, weights: tuple[np.ndarray, np.ndarray], x: np.ndarray, taus: tuple[float, float]
) -> tuple[list[int], list[tuple[int, tuple[float, float]]]]:
    """The nodes of axis ``x`` kept, the one of least cost dropped at a time while its cost is below
    1, and each node dropped with the misses (outlet, flow) it left."""
    nodes, dropped = list(range(x.size)), []
    while len(nodes) > 3:
        misses = [drop_misses(f, weights, x, nodes, p) for p in range(1, len(nodes) - 1)]
        costs = [m[0] / taus[0] if np.isinf(taus[1]) else max(m[0] / taus[0], m[1] / taus[1]) for m in misses]
        k = int(np.argmin(costs))
        if costs[k] >= 1.0:
            break
        dropped.append((nodes.pop(k + 1), misses[k]))
    return nodes, dropped


def drop_misses(f: np.ndarray, weights: tuple[np.ndarray, np.ndarray], x: np.ndarray, nodes: list[int], p: int):
    """Dropping ``nodes[p]`` of the kept ``nodes``: the interpolant's misses along axis 0 of ``f`` at
    the grid nodes it no longer passes through, in the outlet (weighted by ``weights[0]``, largest)
    and in the flow (``weights[1]``, 99th percentile).

    The second differences at the two neighbours change, and with them the interpolant of the
    cells on either side as well as the new one: the misses are taken at every grid node inside
    those three cells (the nodes dropped before included)."""
    rest = nodes[:p] + nodes[p + 1 :]
    d2 = {q: _second_difference(f, x, rest, q) for q in range(max(p - 2, 0), min(p + 2, len(rest)))}
    misses = []
    for q in range(max(p - 2, 0), min(p + 1, len(rest) - 1)):  # the cells rest[q]..rest[q + 1]
        a, b = rest[q], rest[q + 1]
        for i in range(a + 1, b):
            t = (x[i] - x[a]) / (x[b] - x[a])
            curve = (1 - t) * d2[q] + t * d2[q + 1]
            bow = (x[i] - x[a]) * (x[i] - x[b]) / 2
            value = (1 - t) * f[a] + t * f[b] + np.where(np.isfinite(curve), curve * bow, 0.0)
            misses.append((i, np.abs(f[i] - value)))
    with np.errstate(invalid="ignore"):  # no miss where the flow does not respond: 0 * inf, NaN, left out
        outlet = np.concatenate([(m * weights[0][i]).ravel() for i, m in misses])
        flow = np.concatenate([(m * weights[1][i]).ravel() for i, m in misses])
    outlet, flow = outlet[~np.isnan(outlet)], flow[~np.isnan(flow)]
    return (
        float(outlet.max()) if outlet.size else 0.0,
        float(np.quantile(flow, 0.99)) if flow.size else 0.0,
    )


def _second_difference(f: np.ndarray, x: np.ndarray, nodes: list[int], p: int) -> np.ndarray:
    """The interpolator's second difference at ``nodes[p]`` on the axis of ``nodes``: its own
    (:func:`evtms.luts.interp.second_difference`) on the node's three, an end node taking its
    neighbour's."""
    q = min(max(p, 1), len(nodes) - 2)
    three = nodes[q - 1 : q + 2]
    return second_difference(f[three], x[three], 0, 1, 2)[0]
