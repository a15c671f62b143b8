"""Compressor bench: positive-displacement compressor at fixed speed and pressure ratio.

Mass flow from the swept volume, the shaft speed, the suction density and a
clearance-volume volumetric efficiency (re-expansion of the clearance gas with
polytropic exponent ``n``):

.. math:: \\dot m = \\eta_v \\rho_{in} V_d N,\\quad
          \\eta_v = 1 + C - C\\,\\pi^{1/n},\\quad
          C = \\frac{1 - \\eta_{v,nom}}{\\pi_{nom}^{1/n} - 1}

(C set so that eta_v is the nominal value at the nominal pressure ratio).
Discharge state and power from the isentropic efficiency and the mechanical
efficiency:

.. math:: h_{out} = h_{in} + \\frac{h(p_{out}, s_{in}) - h_{in}}{\\eta_{is}},\\quad
          W = \\frac{\\dot m (h_{out} - h_{in})}{\\eta_{mech}}

so ``W eta_mech = mdot (h_out - h_in)`` exactly.

The ``thesis`` grid gives no suction pressure; it is set from a 10 K suction
superheat, ``p_in = p_sat(T_in - 10 K)`` (``suction_superheat`` parameter),
unless ``p_in`` is given as an axis. A compressor never compresses liquid: a
suction state at or below saturation is an invalid point (status 3), as is a
pressure ratio at which the clearance gas re-expands to fill the whole stroke
(``eta_v <= 0``, status 4).

Computation: with numba (:func:`evtms._jit.numba_enabled`) each point runs in
machine code (:mod:`evtms.benches._compressor_kernel`) on the tabulated
refrigerant properties of :mod:`evtms.fluid_tables` (suction ``(p, T)`` with
its entropy, the isentropic discharge by ``(p, s) -> h``, ``(p, h) -> T``):
within 1e-5 relative of CoolProp in ``W``, ``mdot`` and ``h_out`` and 1e-3 K
in ``T_out``, the same statuses. Points whose states leave the tables
(discharge above 450 K or 0.9 of the critical pressure, say) take the NumPy
path on CoolProp, which is also the reference and the path without numba.

References
----------
Stoecker, W. F., Jones, J. W. (1982). Refrigeration and Air Conditioning,
2nd ed., McGraw-Hill, ch. 11 (clearance volumetric efficiency).
Dincer, I., Kanoglu, M. (2010). Refrigeration Systems and Applications, 2nd
ed., Wiley, ch. 4 (isentropic and mechanical efficiencies).
MathWorks (2024). Compressor (2P), Simscape Fluids reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from evtms._jit import numba_enabled
from evtms.benches.base import (
    COMMON_FLAGS,
    STATUS_OUTSIDE_FLUID_RANGE,
    Bench,
    finish_status,
    first_code,
    pressure_nodes,
)
from evtms.fluid import Fluid, quality
from evtms.params import fraction, param, temperature

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters


@dataclass(frozen=True)
class CompressorParams:
    """Positive-displacement compressor.

    Attributes
    ----------
    displacement : float
        Swept volume per revolution [m3] (80 cm3), (0, 0.01].
    speed_max : float
        Shaft speed at speed fraction 1 [rev/min], (0, 100000].
    eta_isentropic : float
        Isentropic efficiency [1], (0, 1].
    eta_vol_nominal : float
        Volumetric efficiency at the nominal pressure ratio [1], (0, 1].
    pr_nominal : float
        Nominal pressure ratio [1], (1, 50].
    p_in_nominal : float
        Nominal suction pressure [Pa], 1 kPa to 10 MPa.
    T_in_nominal : float
        Nominal suction temperature [K], 150 K to 500 K.
    eta_mechanical : float
        Mechanical efficiency [1], (0, 1].
    polytropic_exponent : float
        Re-expansion exponent of the clearance gas [1], 1 to 2.
    suction_superheat : float
        Superheat that sets the suction pressure of the ``thesis`` grid [K], 0 K to 100 K.
    """

    displacement: float = param(80e-6, 0.0, 0.01, "m3", lo_open=True)
    speed_max: float = param(3600.0, 0.0, 100_000.0, "rev/min", lo_open=True)
    eta_isentropic: float = fraction(0.65)
    eta_vol_nominal: float = fraction(0.9)
    pr_nominal: float = param(4.6, 1.0, 50.0, lo_open=True)
    p_in_nominal: float = param(0.3e6, 1e3, 10e6, "Pa")
    T_in_nominal: float = temperature(284.15)
    eta_mechanical: float = fraction(0.95)
    polytropic_exponent: float = param(1.2, 1.0, 2.0)
    suction_superheat: float = param(10.0, 0.0, 100.0, "K")


STATUS_LIQUID_SUCTION = 3
STATUS_NO_VOLUMETRIC_FLOW = 4

OUTPUTS = ("status", "W", "mdot", "p_in", "h_in", "h_out", "T_out", "p_out", "eta_is", "eta_vol")


def clearance_volumetric_efficiency(pr: np.ndarray, comp: CompressorParams) -> np.ndarray:
    """Volumetric efficiency [1] at pressure ratio ``pr`` from the clearance-volume model."""
    n = comp.polytropic_exponent
    C = (1.0 - comp.eta_vol_nominal) / (comp.pr_nominal ** (1.0 / n) - 1.0)
    return 1.0 + C - C * np.asarray(pr, float) ** (1.0 / n)


def suction_pressure(T_in: np.ndarray, comp: CompressorParams, fluid: Fluid) -> np.ndarray:
    """Suction pressure [Pa] that gives ``comp.suction_superheat`` at suction temperature ``T_in`` [K]."""
    return fluid.saturation_pressure(np.asarray(T_in, float) - comp.suction_superheat)


def compressor_power(
    inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid, compiled: bool | None = None
) -> dict[str, np.ndarray]:
    """Steady-state compressor response over arrays of bench inputs.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``speed`` [1] (fraction of ``speed_max``), ``T_in`` [K] or ``h_in``
        [J/kg], ``pr`` [1], and optionally ``p_in`` [Pa].
    params : Parameters
        Compressor parameters (``params.compressor``).
    fluid : Fluid
        Refrigerant properties.
    compiled : bool, optional
        Whether the points run one by one in machine code on tabulated properties
        (:mod:`evtms.benches._compressor_kernel`, :mod:`evtms.fluid_tables`: within the
        tables' tolerance of CoolProp; points whose states leave the tables on CoolProp)
        or over NumPy arrays on ``fluid`` (the reference). By default compiled where numba
        is enabled (:func:`evtms._jit.numba_enabled`).

    Returns
    -------
    dict of str to numpy.ndarray
        ``W`` shaft power [W], ``mdot`` [kg/s], ``p_in`` [Pa], ``h_in``,
        ``h_out`` [J/kg], ``T_out`` [K], ``p_out`` [Pa], ``eta_is``,
        ``eta_vol`` [1], ``status`` (int8, see :data:`FLAGS`).
    """
    comp = params.compressor
    speed = np.asarray(inputs["speed"], float)
    pr = np.asarray(inputs["pr"], float)
    if "p_in" in inputs:
        p_in = np.asarray(inputs["p_in"], float).copy()
    else:
        p_in = suction_pressure(inputs["T_in"], comp, fluid)
    by_enthalpy = "h_in" in inputs
    x_in = np.asarray(inputs["h_in"] if by_enthalpy else inputs["T_in"], float)
    if compiled is None:
        compiled = numba_enabled()
    if not compiled:
        return _compress_numpy(comp, speed, pr, p_in, x_in, by_enthalpy, fluid)
    out, fallback = _compress_compiled(comp, speed, pr, p_in, x_in, by_enthalpy, fluid)
    if fallback.any():  # states beyond the property tables: CoolProp's path, point by point
        idx = np.nonzero(fallback)[0]
        sub = _compress_numpy(comp, speed[idx], pr[idx], p_in[idx], x_in[idx], by_enthalpy, fluid)
        for key, value in sub.items():
            out[key][idx] = value
    return out


def _compress_numpy(
    comp: CompressorParams,
    speed: np.ndarray,
    pr: np.ndarray,
    p_in: np.ndarray,
    x_in: np.ndarray,
    by_enthalpy: bool,
    fluid: Fluid,
) -> dict[str, np.ndarray]:
    """:func:`compressor_power` over arrays on ``fluid``; ``x_in`` is ``h_in`` [J/kg] if
    ``by_enthalpy`` else ``T_in`` [K]."""
    if by_enthalpy:
        h_in = x_in.copy()
        suction = fluid.state("PH", p_in, h_in, ("D", "S"))
    else:
        suction = fluid.state("PT", p_in, x_in, ("H", "D", "S"))
        h_in = suction["H"]
    sat = fluid.saturation(p_in)
    # Vapour strictly above saturation; (p, T) exactly at saturation is ambiguous and treated as wet.
    wet = ~(quality(h_in, sat["h_l"], sat["h_v"]) > 1.0) & np.isfinite(sat["h_v"]) | (
        ~np.isfinite(sat["h_v"]) & (p_in < fluid.p_crit)
    )
    eta_vol = clearance_volumetric_efficiency(pr, comp)
    no_flow = ~(eta_vol > 0)
    mdot = eta_vol * suction["D"] * comp.displacement * speed * comp.speed_max / 60.0
    p_out = pr * p_in
    h_out_s = fluid.state("PS", p_out, suction["S"], ("H",))["H"]
    h_out = h_in + (h_out_s - h_in) / comp.eta_isentropic
    T_out = fluid.state("PH", p_out, h_out, ("T",))["T"]
    out = {
        "W": mdot * (h_out - h_in) / comp.eta_mechanical,
        "mdot": mdot,
        "p_in": p_in.copy(),
        "h_in": h_in.copy(),
        "h_out": h_out,
        "T_out": T_out,
        "p_out": p_out,
        "eta_is": np.full(p_in.shape, comp.eta_isentropic),
        "eta_vol": eta_vol,
    }
    status = first_code(
        [
            (~np.isfinite(h_in + suction["D"]), STATUS_OUTSIDE_FLUID_RANGE),
            (wet, STATUS_LIQUID_SUCTION),
            (no_flow, STATUS_NO_VOLUMETRIC_FLOW),
        ],
        p_in.size,
    )
    finish_status(status, out, (0,))
    out["status"] = status
    return out


def kernel_constants(comp: CompressorParams, fluid: Fluid) -> np.ndarray:
    """The compressor constants of :func:`evtms.benches._compressor_kernel.compress_point`
    (its ``CONSTANTS``, in that order)."""
    from evtms.benches import _compressor_kernel as kernel

    return np.array([getattr(comp, k) for k in kernel.CONSTANTS[:-1]] + [fluid.p_crit])


def _compress_compiled(
    comp: CompressorParams,
    speed: np.ndarray,
    pr: np.ndarray,
    p_in: np.ndarray,
    x_in: np.ndarray,
    by_enthalpy: bool,
    fluid: Fluid,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`compressor_power` by :func:`evtms.benches._compressor_kernel.compress_points` on
    the tables of :mod:`evtms.fluid_tables`, and the mask of the points it leaves to CoolProp."""
    from evtms.benches import _compressor_kernel as kernel
    from evtms.fluid_tables import tables_for

    constants = kernel_constants(comp, fluid)
    speed, pr, p_in, x_in = (np.ascontiguousarray(a, float).reshape(-1) for a in (speed, pr, p_in, x_in))
    rows = kernel.compress_points(speed, pr, p_in, x_in, by_enthalpy, constants, tables_for(fluid).arrays)
    res = {name: rows[:, k] for k, name in enumerate(kernel.COLUMNS)}
    out = {
        "W": res["W"],
        "mdot": res["mdot"],
        "p_in": p_in.copy(),
        "h_in": res["h_in"],
        "h_out": res["h_out"],
        "T_out": res["T_out"],
        "p_out": pr * p_in,
        "eta_is": np.full(p_in.shape, comp.eta_isentropic),
        "eta_vol": res["eta_vol"],
    }
    status = res["code"].astype(np.int8)
    finish_status(status, out, (0,))
    out["status"] = status
    return out, res["fallback"] > 0.0


FLAGS = {
    **COMMON_FLAGS,
    STATUS_LIQUID_SUCTION: "liquid_or_two_phase_suction",
    STATUS_NO_VOLUMETRIC_FLOW: "pressure_ratio_beyond_volumetric_limit",
}

BENCH = Bench(
    name="compressor",
    title="evtms compressor bench: positive-displacement R134a compressor",
    axes=("speed", "T_in", "pr"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=compressor_power,
    parameters=CompressorParams,
    extra_axes=("p_in",),
    # p_in is an output where it is not an axis (the suction pressure the grid implies).
    optional_outputs=("p_in",),
    main_output=("W", "speed"),
    surface_axes=(("pr", "T_in"),),
    presets={
        "thesis": {
            "speed": (0.3, 0.6, 0.8),
            "T_in": (250.0, 265.0, 280.0),
            "pr": (4.5, 5.25, 6.0, 8.0),
        },
        # Cycle envelope: W and mdot are linear in speed, so its two ends suffice; the
        # suction grid is fine enough (2.5 K, < 2 K of saturation per pressure cell)
        # that no cell of a point superheated by 5 K or more touches a wet corner. Pressure
        # ratios from 1.02 (a -10 degC ambient with fan 1 runs at 1.0-1.2) and suction up to
        # 42 degC saturation (the evaporator's 41 degC) for the system simulator's envelope;
        # up to 17 for the heat pump (evaporating at -26 degC, condensing at 65 degC: 16.6).
        "cycle": {
            "speed": (0.1, 1.0),
            "T_in": tuple(np.linspace(240.0, 340.0, 41)),
            "pr": (1.02, 1.1, *np.geomspace(1.2, 12.0, 14), 14.3, 17.0),
            "p_in": pressure_nodes(np.arange(-36.0, 44.0, 2.0)),
        },
    },
)
