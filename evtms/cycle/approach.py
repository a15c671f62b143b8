"""An evaporating branch's outlet as the logarithm of its approach to the secondary inlet.

A thermostatic valve sets its branch's flow so that the outlet is superheated
by the setpoint. Where the secondary stream (cabin air, coolant) is only a few
kelvin warmer than the evaporating refrigerant plus that setpoint, the outlet
runs in the exponential tail of the superheated zone: against a secondary of
nearly constant temperature the zone is an exchanger with a capacity ratio
near 0, so its effectiveness is ``1 - exp(-NTU)`` (Incropera et al. 2007,
eq. 11.35a) and the outlet approaches the secondary inlet temperature as
``exp(-NTU)``. There the outlet enthalpy changes little with the flow, and an
enthalpy interpolated linearly between LUT nodes puts the flow that meets the
setpoint several per cent off (the split between two parallel branches, even
more). The LUT cycle therefore interpolates the logarithm of the approach
fraction

    psi = (h(p_out, T_sec) - h_out) / (h(p_out, T_sec) - h_v(p_out))    [1]

which is 1 for a saturated-vapour outlet, falls towards 0 as the outlet
approaches the secondary inlet temperature ``T_sec`` (close to
``exp(-NTU)`` of the superheated zone, so ``ln psi`` is close to linear in
it) and exceeds 1 for the continued two-phase side (``h_out_continued`` below
``h_v``). Where the secondary is less than :data:`SUPERHEAT_MIN` warmer than
saturation, the denominator takes that superheat (a branch that cannot
superheat its outlet). The same function of the same inputs is applied at the
nodes and inverted at a query (:func:`outlet_enthalpy`), so the interpolant
still passes through every node; the vapour enthalpies come from a
:class:`~evtms.fluid.VapourTable`, which spares the LUT cycle CoolProp.

References
----------
Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
Fundamentals of Heat and Mass Transfer, 6th ed., Wiley, section 11.4.
"""

from __future__ import annotations

import numpy as np

from evtms._jit import jit, numba_enabled
from evtms.fluid import VapourTable

#: Name of the interpolated variable in a component's LUT tables.
APPROACH = "approach_log"
#: The outlet variable it stands for.
OUTLET = "h_out_continued"
#: The secondary inlet temperature of each evaporating component's LUT.
SECONDARY_INLET = {"evaporator": "T_air_in", "chiller": "T_coolant_in"}
#: Smallest secondary-over-saturation superheat [K] the denominator uses.
SUPERHEAT_MIN = 0.5
#: Smallest approach fraction [1]: an outlet at the secondary temperature (to round-off) stays finite.
APPROACH_MIN = 1e-9


def approach_log(h_out: np.ndarray, p_out: np.ndarray, T_sec: np.ndarray, vapour: VapourTable) -> np.ndarray:
    """``ln psi`` [1] of outlets ``h_out`` [J/kg] at ``p_out`` [Pa] against a secondary inlet at ``T_sec`` [K]."""
    h_v, span = vapour.rise_to(p_out, T_sec, SUPERHEAT_MIN)
    with np.errstate(invalid="ignore"):
        return np.log(np.maximum((h_v + span - h_out) / span, APPROACH_MIN))


def outlet_enthalpy(
    log_psi: np.ndarray, p_out: np.ndarray, T_sec: np.ndarray, vapour: VapourTable, compiled: bool = False
) -> np.ndarray:
    """The outlet enthalpy [J/kg] whose :func:`approach_log` is ``log_psi`` (its inverse).

    ``compiled``: one compiled loop over the points (numba; the same numbers to
    round-off), for the cycle solver's many calls on a few points each, where
    NumPy's per-call overhead of some thirty array operations dominates.
    """
    if compiled and numba_enabled():
        args = (log_psi, p_out, T_sec)
        if all(type(a) is np.ndarray and a.ndim == 1 and a.dtype == np.float64 for a in args) and (
            log_psi.size == p_out.size == T_sec.size
        ):  # the solver's calls: 1-D float arrays of one size
            shape = log_psi.shape
        else:  # anything else is broadcast first (0-d for scalar arguments, as on the array path)
            shape = np.broadcast_shapes(*(np.shape(a) for a in args))
            args = [np.array(np.broadcast_to(np.asarray(a, np.float64), shape)).reshape(-1) for a in args]
        # Writable C-ordered inputs whatever they came as: numba compiles once per argument type.
        args = [np.require(a, requirements=("C", "W")) for a in args]
        out = np.empty(shape)
        table = (vapour.log_p0, vapour.dlog_p, vapour.T, vapour.h_v, vapour.step, vapour.dh)
        compiled_outlet_kernel()(*(a.reshape(-1) for a in args), *table, SUPERHEAT_MIN, out.reshape(-1))
        return out
    h_v, span = vapour.rise_to(p_out, T_sec, SUPERHEAT_MIN)
    return h_v + span * (1.0 - np.exp(log_psi))


def _outlet_enthalpy_points(log_psi, p_out, T_sec, log_p0, dlog_p, T, h_v, step, dh, superheat_min, out):
    """:func:`outlet_enthalpy` point by point (the twin of :meth:`VapourTable.rise_to`, held to
    it in the tests)."""
    n_p, n_sh = dh.shape
    for k in range(log_psi.size):
        u = (np.log(p_out[k]) - log_p0) / dlog_p
        if not (u >= 0.0 and u <= n_p - 1):
            out[k] = np.nan
            continue
        i = min(int(u), n_p - 2)
        w = u - i
        T_sat = T[i] + w * (T[i + 1] - T[i])
        h_sat = h_v[i] + w * (h_v[i + 1] - h_v[i])
        superheat = T_sec[k] - T_sat
        if superheat < superheat_min:
            superheat = superheat_min
        v = superheat / step
        if not (v == v):
            out[k] = np.nan
            continue
        v = max(v, 0.0)
        j = min(int(v), n_sh - 2) if v < n_sh else n_sh - 2  # beyond the table: the last step continued
        t = v - j
        low = dh[i, j] + t * (dh[i, j + 1] - dh[i, j])
        high = dh[i + 1, j] + t * (dh[i + 1, j + 1] - dh[i + 1, j])
        span = low + w * (high - low)
        out[k] = h_sat + span * (1.0 - np.exp(log_psi[k]))


_COMPILED = []


def compiled_outlet_kernel():
    """:func:`outlet_enthalpy`'s point-by-point loop, compiled on first use (importing this module,
    and so the cycle, does not load numba); the one compiled copy, which
    :mod:`evtms.cycle._component_kernel` calls as well."""
    if not _COMPILED:
        _COMPILED.append(jit(_outlet_enthalpy_points, counted=False))
    return _COMPILED[0]
