"""Chiller bench: brazed-plate evaporator cooling the battery's water-glycol loop.

The refrigerant enters at ``(p_in, h_in)`` with mass flow ``mdot`` and
evaporates in a chevron-plate exchanger (:class:`PlateHXParams`);
the coolant, monoethylene glycol 50 % by mass in water (CoolProp's
incompressible ``MEG``, :class:`evtms.fluid.Coolant`), enters at
``T_coolant_in`` with mass flow ``mdot_coolant`` and flows against it. The
steady state comes from the counter-flow moving-boundary core
(:func:`evtms.hx.counterflow.solve_counterflow_evaporator`): subcooled,
two-phase and superheated refrigerant zones, each with its own
refrigerant-side coefficient, the coolant passing all of them in series.

Correlations (:mod:`evtms.hx.plate`): single-phase channels on both sides by
Martin (1996), the generalised Leveque equation with his friction factor
(viscosity ratio taken as 1, the wall state not being resolved);
evaporation by Yan and Lin (1999), averaged over quality 0..1 at the mean
heat flux of an all-two-phase exchanger (found by fixed-point iteration,
as the coils do); two-phase friction by Yan and Lin, single-phase friction by
Martin, and 1.4 velocity heads per port (Shah and Focke 1988). The coolant
coefficient is evaluated at the coolant's mean temperature (two passes: at
the inlet temperature, then at the mean of inlet and outlet). Heat transfer
is evaluated at the inlet pressure; the pressure drop sets the outlet
pressure at which the outlet state is reported.

Validity: Martin compared his equations with data of Re 200 to 10,000;
Yan and Lin state 2000 < Re_eq < 10,000 for R134a. The chiller's coolant
flows give Re of about 20 to 500 and its refrigerant flows Re_eq of about 200
to 8000, so many points use a correlation outside its range: they are valid
with status 11 (``valid_correlation_outside_range``), the correlations
evaluated as published.

Computation: with numba (:func:`evtms._jit.numba_enabled`) the bench solves
each point in machine code (:func:`solve_chiller_compiled`,
:mod:`evtms.benches._chiller_kernel`) on tabulated refrigerant properties
(:mod:`evtms.fluid_tables`), within 1e-4 relative of CoolProp in ``Q``,
``h_out`` and ``dp``; :func:`solve_chiller`, the same steps over NumPy arrays
on CoolProp, is its reference and the fallback without numba.

Energy: ``Q = mdot (h_in - h_out) = -mdot_coolant (h_c,in - h_c,out)`` (< 0,
heat into the refrigerant), both to round-off, in the coolant's tabulated
enthalpy (:meth:`evtms.fluid.Coolant.enthalpy`). Second law: the
refrigerant never leaves warmer than the coolant enters, nor the coolant
colder than the refrigerant enters (the core needs infinite area for
either).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from evtms._jit import numba_enabled
from evtms.benches.base import (
    COMMON_FLAGS,
    STATUS_OUTSIDE_FLUID_RANGE,
    STATUS_PROPERTY_FAILED,
    Bench,
    finish_status,
    first_code,
    pressure_nodes,
)
from evtms.benches.condenser import inlet_enthalpy
from evtms.fluid import Fluid, coolant, quality
from evtms.hx import plate, tube
from evtms.hx.counterflow import LIQUID, TWO_PHASE, VAPOUR, RefrigerantPath, solve_counterflow_evaporator
from evtms.hx.sides import CoolantSide
from evtms.params import Relation, fouling, length, param

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters


@dataclass(frozen=True)
class PlateHXParams:
    """Brazed-plate refrigerant-to-coolant evaporator (the chiller).

    Chevron plates, refrigerant and coolant in alternate channels in counter
    flow, one pass each side. The plate pack has ``n_plates`` plates and so
    ``n_plates - 1`` channels, the refrigerant in ``(n_plates - 1) // 2`` of
    them and the coolant in the rest; the two end plates do not transfer heat,
    so the heat-transfer area is ``enlargement_factor * plate_width *
    plate_length * (n_plates - 2)``. Each channel is ``2 *
    corrugation_amplitude`` deep; the hydraulic diameter is ``4 *
    corrugation_amplitude / enlargement_factor`` (Martin 1996).

    Default sizing: the Simscape BEV example's chiller valve is rated 4.5 kW
    nominal (7 kW maximum) and ``system.md`` assumes a chiller UA of about
    175 W/K. The defaults (a 0.075 m x 0.25 m plate of 60 deg chevrons,
    2 mm channels, 0.4 mm stainless steel) take the plate count (20) at
    which 4.5 kW go into R134a entering at 1 degC saturation (0.304 MPa)
    as 35 degC liquid (the valve's nominal 40 degC condensing less 5 K
    subcooling) and leaving 10 K superheated, from MEG 50 % entering at
    30 degC at 0.15 kg/s: 4.53 kW at 0.0288 kg/s of refrigerant, UA 188 W/K,
    coolant leaving at 21.0 degC, 30 kPa refrigerant pressure drop (18
    plates give 4.19 kW, 22 plates 4.84 kW). ``tests/test_chiller.py``
    checks this sizing point.

    Attributes
    ----------
    n_plates : int
        Number of plates [1], 4 to 500.
    plate_width : float
        Channel width between the gaskets [m], (0, 2].
    plate_length : float
        Flow length, port centre to port centre [m], (0, 5].
    chevron_angle : float
        Angle of the corrugations to the main flow direction [deg], (0, 90)
        (Martin's phi; 60 deg is a "hard" plate).
    corrugation_pitch : float
        Corrugation wavelength [m], (0, 0.1].
    corrugation_amplitude : float
        Corrugation amplitude, half the channel depth [m], (0, 0.01], less
        than ``corrugation_pitch / 2``.
    plate_thickness : float
        Plate wall thickness [m], (0, 0.01].
    plate_conductivity : float
        Plate conductivity [W/(m K)], (0, 2000] (16 W/(m K), stainless steel).
    port_diameter : float
        Port diameter [m], (0, 0.5], less than ``plate_width``.
    fouling_ref, fouling_coolant : float
        Fouling factors [m2 K/W], [0, 0.01) (0.1 m2K/kW each, as the coils).
    coolant_mass_fraction : float
        Glycol (MEG) mass fraction of the coolant [1], [0.1, 0.6] (CoolProp's
        range for MEG); 0.5 freezes at -34 degC.
    """

    n_plates: int = param(20, 4, 500, whole=True)
    plate_width: float = length(0.075, 2.0)
    plate_length: float = length(0.25, 5.0)
    chevron_angle: float = param(60.0, 0.0, 90.0, "deg", lo_open=True, hi_open=True)
    corrugation_pitch: float = length(7.0e-3, 0.1)
    corrugation_amplitude: float = length(1.0e-3, 0.01)
    plate_thickness: float = length(0.4e-3, 0.01)
    plate_conductivity: float = param(16.0, 0.0, 2000.0, "W/(m K)", lo_open=True)
    port_diameter: float = length(0.016, 0.5)
    fouling_ref: float = fouling(1e-4)
    fouling_coolant: float = fouling(1e-4)
    coolant_mass_fraction: float = param(0.5, 0.1, 0.6)

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        Relation(
            "corrugation_amplitude",
            "<",
            lambda c: c.corrugation_pitch / 2,
            "corrugation_pitch / 2",
            ("corrugation_pitch",),
        ),
        Relation("port_diameter", "<", lambda c: c.plate_width, "plate_width", ("plate_width",)),
    )

    @property
    def enlargement_factor(self) -> float:
        """Developed over projected plate area [1], from the corrugation (Martin 1996, eq. 2).

        ``Phi = (1 + sqrt(1 + X^2) + 4 sqrt(1 + X^2 / 2)) / 6`` with the
        wavenumber ``X = 2 pi corrugation_amplitude / corrugation_pitch``:
        1.18 with the defaults.
        """
        X = 2.0 * math.pi * self.corrugation_amplitude / self.corrugation_pitch
        return (1.0 + math.sqrt(1.0 + X * X) + 4.0 * math.sqrt(1.0 + X * X / 2.0)) / 6.0


STATUS_NOT_COLDER_THAN_COOLANT = 3
STATUS_DP_EXCEEDS_INLET = 4
STATUS_COOLANT_FREEZES = 5
STATUS_FLOW_NOT_POSITIVE = 6
#: Valid point where a correlation (Martin, Yan and Lin) runs outside its data's range.
STATUS_CORRELATION_OUTSIDE_RANGE = 11

OUTPUTS = (
    "status",
    "Q",
    "h_in",
    "h_out",
    "T_out",
    "p_out",
    "x_out",
    "T_coolant_out",
    "dp",
    "capacity_ratio",
    "h_out_continued",
)

#: Fixed-point steps for the mean two-phase heat flux (the coefficient goes with q^0.3).
_FLUX_STEPS = 6


def plate_geometry(hx: PlateHXParams) -> dict[str, float]:
    """Derived geometry of the plate pack.

    Returns
    -------
    dict of str to float
        ``area`` heat-transfer area [m2], ``D_h`` hydraulic diameter [m],
        ``flow_ref`` and ``flow_coolant`` flow cross-sections [m2],
        ``port_area`` [m2], ``R_wall`` plate conduction resistance [K/W].
    """
    phi = hx.enlargement_factor
    n_channels = hx.n_plates - 1
    n_ref = n_channels // 2
    gap = 2.0 * hx.corrugation_amplitude
    area = phi * hx.plate_width * hx.plate_length * (hx.n_plates - 2)
    return {
        "area": area,
        "D_h": 4.0 * hx.corrugation_amplitude / phi,
        "flow_ref": n_ref * hx.plate_width * gap,
        "flow_coolant": (n_channels - n_ref) * hx.plate_width * gap,
        "port_area": np.pi * hx.port_diameter**2 / 4.0,
        "R_wall": hx.plate_thickness / (hx.plate_conductivity * area),
    }


def martin_htc(G, D_h, props, angle):
    """Single-phase coefficient [W/(m2 K)] and Reynolds number of a plate channel (Martin 1996)."""
    Re = G * D_h / props["MU"]
    Pr = props["CP"] * props["MU"] / props["K"]
    return plate.martin_nusselt(Re, Pr, angle) * props["K"] / D_h, Re


def _yan_lin_mean(G, D_h, sat, q):
    """Yan and Lin's coefficient [W/(m2 K)] averaged over quality 0..1 (Gauss-Legendre), and Re_eq at x = 1/2."""
    x = tube.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
    h = plate.yan_lin_boiling_htc(
        x,
        G[:, None],
        D_h,
        q[:, None],
        col["h_v"] - col["h_l"],
        col["mu_l"],
        col["rho_l"],
        col["rho_v"],
        col["k_l"],
        Pr_l,
    )
    Re_eq = plate.equivalent_mass_flux(G, 0.5, sat["rho_l"], sat["rho_v"]) * D_h / sat["mu_l"]
    return np.sum(h * tube.GAUSS_WEIGHTS, axis=-1), Re_eq


def _two_phase_gradient(G, D_h, sat, x0, x1):
    """Mean two-phase frictional gradient [Pa/m] over quality x0..x1 (Yan and Lin 1999)."""
    x = x0[:, None] + (x1 - x0)[:, None] * tube.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    G2 = G[:, None]
    Re_eq = plate.equivalent_mass_flux(G2, x, col["rho_l"], col["rho_v"]) * D_h / col["mu_l"]
    Re = G2 * D_h / col["mu_l"]
    rho_m = 1.0 / (x / col["rho_v"] + (1.0 - x) / col["rho_l"])
    grad = 2.0 * plate.yan_lin_friction_factor(Re_eq, Re) * G2**2 / (rho_m * D_h)
    return np.sum(grad * tube.GAUSS_WEIGHTS, axis=-1)


def refrigerant_props(fluid, p, T, sat, phase):
    """Single-phase refrigerant properties at (p, T), falling back to saturation where CoolProp fails."""
    props = fluid.state("PT", p, T, ("D", "CP", "MU", "K"))
    for key, sk in (("D", "rho"), ("CP", "cp"), ("MU", "mu"), ("K", "k")):
        props[key] = np.where(np.isfinite(props[key]), props[key], sat[f"{sk}_{phase}"])
    return props


def plate_outlet(
    fluid: Fluid,
    geo: dict[str, float],
    sat: dict[str, np.ndarray],
    p_in: np.ndarray,
    h_out: np.ndarray,
    mdot: np.ndarray,
    rho_in: np.ndarray,
    dp_channels: np.ndarray,
) -> tuple[np.ndarray, ...]:
    """A plate exchanger's refrigerant outlet: the ports' loss added to the channels' drop, and the outlet state.

    Each port loses :data:`evtms.hx.plate.PORT_VELOCITY_HEADS` velocity heads of its
    own flow (Shah and Focke 1988), at the inlet's and at the outlet's density (the
    homogeneous density of a two-phase outlet at the inlet pressure).

    Returns
    -------
    tuple of numpy.ndarray
        ``dp`` [Pa], ``p_out`` [Pa], ``bad_dp`` (the outlet pressure is not above the
        triple point), ``x_out`` [1] and ``T_out`` [K] at the outlet pressure.
    """
    h_l, h_v = sat["h_l"], sat["h_v"]
    x_hx = quality(h_out, h_l, h_v)
    two_phase_out = (x_hx >= 0.0) & (x_hx <= 1.0)
    rho_out = np.where(two_phase_out, 1.0 / (x_hx / sat["rho_v"] + (1.0 - x_hx) / sat["rho_l"]), np.nan)
    single = ~two_phase_out & np.isfinite(h_out)
    rho_out[single] = fluid.state("PH", p_in[single], h_out[single], ("D",))["D"]
    G_port = mdot / geo["port_area"]
    dp = dp_channels + plate.PORT_VELOCITY_HEADS * G_port**2 / 2.0 * (1.0 / rho_in + 1.0 / rho_out)
    p_out = p_in - dp
    bad_dp = ~(p_out > fluid.p_triple)
    p_ok = np.where(bad_dp, np.nan, p_out)
    curve = fluid.saturation_curve()
    x_out = quality(h_out, curve.liquid_enthalpy(p_ok), curve.vapour_enthalpy(p_ok))
    T_out = curve.temperature(p_ok)
    single = ~((x_out >= 0.0) & (x_out <= 1.0))
    T_out[single] = fluid.state("PH", p_ok[single], h_out[single], ("T",))["T"]
    return dp, p_out, bad_dp, x_out, T_out


def solve_chiller(
    fluid: Fluid,
    hx: PlateHXParams,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mdot_coolant: np.ndarray,
    T_coolant_in: np.ndarray,
) -> dict[str, np.ndarray]:
    """Steady-state plate-chiller response at arrays of refrigerant and coolant inlet conditions.

    Parameters
    ----------
    fluid : Fluid
        Refrigerant properties.
    hx : PlateHXParams
        Plate geometry, walls, fouling and the coolant's glycol fraction.
    p_in : numpy.ndarray
        Refrigerant inlet pressure [Pa].
    h_in : numpy.ndarray
        Refrigerant inlet specific enthalpy [J/kg].
    mdot : numpy.ndarray
        Refrigerant mass flow [kg/s], > 0.
    mdot_coolant : numpy.ndarray
        Coolant mass flow [kg/s], > 0.
    T_coolant_in : numpy.ndarray
        Coolant inlet temperature [K].

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` heat from refrigerant to coolant [W] (< 0), ``h_out`` [J/kg],
        ``p_out`` [Pa], ``dp`` [Pa], ``T_out`` [K], ``x_out`` [1],
        ``T_coolant_out`` [K], ``h_coolant_in``, ``h_coolant_out`` coolant
        enthalpies [J/kg], ``UA`` overall conductance [W/K] (``Q`` over the
        zones' log-mean differences), ``fractions`` zone area fractions
        (n, 3), ``capacity_ratio`` [1], ``h_out_continued`` [J/kg],
        ``Re_coolant``, ``Re_eq`` [1], and the masks ``outside_range`` (a
        correlation outside its data), ``bad_direction``, ``bad_dp``,
        ``bad_flow``, ``coolant_freezes``, ``coolant_outside`` (inlet above
        the coolant's property range) and ``bad_props``.
    """
    p_in, h_in, mdot, m_c, T_c_in = (
        np.asarray(a, float).reshape(-1).copy() for a in (p_in, h_in, mdot, mdot_coolant, T_coolant_in)
    )
    n = p_in.size
    geo = plate_geometry(hx)
    A, D_h = geo["area"], geo["D_h"]
    cool = coolant(mass_fraction=hx.coolant_mass_fraction)
    bad_flow = ~((mdot > 0) & (m_c > 0))
    mdot = np.where(bad_flow, np.nan, mdot)
    m_c = np.where(bad_flow, np.nan, m_c)
    coolant_freezes = T_c_in < cool.T_freeze
    coolant_outside = ~coolant_freezes & ~(T_c_in <= cool.T_max)  # above the fit's range, or not a number
    T_c_in = np.where(coolant_freezes | coolant_outside, np.nan, T_c_in)

    # --- refrigerant states --------------------------------------------------
    sat = fluid.saturation(p_in)
    T_sat, h_l, h_v = sat["T"], sat["h_l"], sat["h_v"]
    inlet = fluid.state("PH", p_in, h_in, ("T", "D"))
    T_in = inlet["T"]
    h_at_c = fluid.state("PT", p_in, T_c_in, ("H",))["H"]
    G = mdot / geo["flow_ref"]
    G_c = m_c / geo["flow_coolant"]
    bad_props = ~np.isfinite(T_in + T_sat + h_at_c)

    reachable = T_c_in > T_sat
    # Single-phase refrigerant coefficients at each zone's mean temperature (Martin 1996).
    T_end_l = np.where(reachable, T_sat, T_c_in)
    liq = refrigerant_props(fluid, p_in, 0.5 * (np.minimum(T_in, T_sat) + T_end_l), sat, "l")
    h_liq, Re_liq = martin_htc(G, D_h, liq, hx.chevron_angle)
    T0_v = np.where(h_in >= h_v, T_in, T_sat)
    vap = refrigerant_props(fluid, p_in, 0.5 * (T0_v + T_c_in), sat, "v")
    h_vap, Re_vap = martin_htc(G, D_h, vap, hx.chevron_angle)
    R_fixed = geo["R_wall"] + hx.fouling_ref / A

    T_c_mean = T_c_in
    for _ in range(2):  # coolant properties at the inlet, then at the mean temperature
        c_props = cool.properties(T_c_mean)
        h_c, Re_c = martin_htc(G_c, D_h, c_props, hx.chevron_angle)
        R_c = 1.0 / (h_c * A) + hx.fouling_coolant / A
        C_c = m_c * c_props["CP"]
        # Mean heat flux of an all-two-phase exchanger, by fixed point (Yan and Lin's h ~ q^0.3).
        q = np.full(n, 5000.0)
        for _ in range(_FLUX_STEPS):
            h_tp, Re_eq = _yan_lin_mean(G, D_h, sat, q)
            UA = 1.0 / (R_c + R_fixed + 1.0 / (h_tp * A))
            q = np.maximum(C_c * -np.expm1(-UA / C_c) * np.abs(T_c_in - T_sat) / A, 1.0)
        R_ref = np.stack([R_fixed + 1.0 / (h * A) for h in (h_liq, h_tp, h_vap)], axis=1)
        ref = RefrigerantPath(mdot, h_in, T_in, T_sat, h_l, h_v, h_at_c, R_ref)
        side = CoolantSide(cool, m_c, T_c_in, R_c)
        res = solve_counterflow_evaporator(ref, side)
        T_c_mean = np.where(np.isfinite(res.T_secondary_out), 0.5 * (T_c_in + res.T_secondary_out), T_c_in)

    Q = res.Q
    f = res.fractions
    h_out = res.h_out

    # --- pressure drop over the zone lengths, plus the ports -------------------
    L = f * hx.plate_length
    grad_l = plate.martin_friction_factor(Re_liq, hx.chevron_angle) * G**2 / (2.0 * liq["D"] * D_h)
    grad_v = plate.martin_friction_factor(Re_vap, hx.chevron_angle) * G**2 / (2.0 * vap["D"] * D_h)
    h_lv = h_v - h_l
    x0 = np.clip((np.maximum(h_in, h_l) - h_l) / h_lv, 0.0, 1.0)
    x1 = np.clip((np.minimum(h_out, h_v) - h_l) / h_lv, 0.0, 1.0)
    grad_tp = _two_phase_gradient(G, D_h, sat, x0, x1)
    dp = grad_l * L[:, LIQUID] + grad_tp * L[:, TWO_PHASE] + grad_v * L[:, VAPOUR]
    dp, p_out, bad_dp, x_out, T_out = plate_outlet(fluid, geo, sat, p_in, h_out, mdot, inlet["D"], dp)
    T_c_out = res.T_secondary_out
    coolant_freezes |= T_c_out < cool.T_freeze

    used = f > 0
    outside = plate.martin_outside_range(Re_c, hx.chevron_angle)
    outside |= used[:, LIQUID] & plate.martin_outside_range(Re_liq, hx.chevron_angle)
    outside |= used[:, VAPOUR] & plate.martin_outside_range(Re_vap, hx.chevron_angle)
    outside |= used[:, TWO_PHASE] & plate.yan_lin_outside_range(Re_eq)
    # Overall conductance the solution used: each zone's Q_z over its log-mean difference.
    with np.errstate(divide="ignore", invalid="ignore"):
        UA_total = np.sum(f / (R_ref + R_c[:, None]), axis=1)
    bad_props |= ~np.isfinite(T_out + x_out + T_c_out + dp)
    return {
        "Q": -Q,
        "h_out": h_out,
        "p_out": p_out,
        "dp": dp,
        "T_out": T_out,
        "x_out": x_out,
        "T_coolant_out": T_c_out,
        "h_coolant_in": side.h_in,
        "h_coolant_out": res.h_secondary_out,
        "UA": UA_total,
        "fractions": f,
        "capacity_ratio": res.capacity_ratio,
        "h_out_continued": res.h_out_continued,
        "Re_coolant": Re_c,
        "Re_eq": Re_eq,
        "outside_range": outside,
        "bad_direction": res.bad_direction,
        "bad_dp": bad_dp,
        "bad_flow": bad_flow,
        "coolant_freezes": coolant_freezes,
        "coolant_outside": coolant_outside,
        "bad_props": bad_props,
    }


def solve_chiller_compiled(
    fluid: Fluid,
    hx: PlateHXParams,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mdot_coolant: np.ndarray,
    T_coolant_in: np.ndarray,
) -> dict[str, np.ndarray]:
    """:func:`solve_chiller` per point in machine code, on tabulated refrigerant properties.

    The kernel (:mod:`evtms.benches._chiller_kernel`) reads the refrigerant
    tables of :mod:`evtms.fluid_tables` (built once per process from
    ``fluid``) and the coolant's own tables; points whose states leave the
    refrigerant tables are solved by :func:`solve_chiller` with ``fluid``
    itself. Same parameters and outputs as :func:`solve_chiller`; the results
    equal ``solve_chiller`` fed with those tables
    (:class:`evtms.fluid_tables_dome.DomeTabulatedFluid`) to round-off and
    CoolProp's within the tables' tolerance (``Q``, ``h_out`` and ``dp``
    within 1e-4 relative). Needs numba (:func:`evtms._jit.numba_enabled`).
    """
    from evtms.benches import _chiller_kernel as kernel

    inputs = (p_in, h_in, mdot, mdot_coolant, T_coolant_in)
    return solve_plate_points(kernel, kernel_constants(fluid, hx), solve_chiller, fluid, hx, *inputs)


def solve_plate_points(kernel, constants: tuple, reference, fluid: Fluid, hx: PlateHXParams, *inputs) -> dict:
    """A compiled plate core's points (``kernel.solve_points`` after the inputs ``constants``) as the
    array solve ``reference`` returns them; the points whose states leave the refrigerant tables (the
    kernel's ``outside_tables``) solved by ``reference`` with ``fluid`` itself.

    ``inputs``: ``p_in`` [Pa], ``h_in`` [J/kg], ``mdot``, ``mdot_coolant`` [kg/s], ``T_coolant_in`` [K].
    The kernel's columns (``kernel.COLUMNS``) end with its masks, from ``outside_range`` on."""
    p_in, h_in, mdot, m_c, T_c_in = (np.ascontiguousarray(np.asarray(a, float).reshape(-1)) for a in inputs)
    cols = kernel.solve_points(p_in, h_in, mdot, m_c, T_c_in, *constants)
    rows = cols.T.copy()  # one copy; each output a contiguous row of it
    out = {name: rows[j] for j, name in enumerate(kernel.COLUMNS) if not name.startswith("f_")}
    out["fractions"] = cols[:, [kernel.COLUMNS.index(f"f_{z}") for z in ("liquid", "two_phase", "vapour")]]
    for key in kernel.COLUMNS[kernel.COLUMNS.index("outside_range") :]:
        out[key] = out[key] != 0.0
    rest = np.nonzero(out.pop("outside_tables"))[0]
    if rest.size:  # states beyond the tables: CoolProp decides them
        ref = reference(fluid, hx, p_in[rest], h_in[rest], mdot[rest], m_c[rest], T_c_in[rest])
        for key, value in out.items():
            value[rest] = ref[key]
    return out


def kernel_constants(fluid: Fluid, hx: PlateHXParams) -> tuple:
    """The compiled chiller's arguments after the inputs: geometry, coolant tables, limits, property tables."""
    from evtms.fluid_tables import tables_for

    return (
        kernel_geometry(hx),
        *kernel_coolant_tables(hx.coolant_mass_fraction),
        fluid.p_triple,
        float(fluid.saturation_curve().p[0]),
        tables_for(fluid).arrays,
        KERNEL_GAUSS,
    )


#: Gauss-Legendre nodes and weights on [0, 1] (:mod:`evtms.hx.tube`), as the kernel reads them.
KERNEL_GAUSS = (np.ascontiguousarray(tube.GAUSS_NODES), np.ascontiguousarray(tube.GAUSS_WEIGHTS))


@functools.lru_cache(maxsize=16)
def kernel_geometry(hx: PlateHXParams) -> np.ndarray:
    """The kernel's geometry argument (:data:`evtms.benches._chiller_kernel.GEOMETRY`), kept per
    geometry: a cycle solver calls the chiller a point at a time."""
    from evtms.benches import _chiller_kernel as kernel

    values = {
        **plate_geometry(hx),
        "fouling_ref": hx.fouling_ref,
        "fouling_coolant": hx.fouling_coolant,
        "plate_length": hx.plate_length,
        "chevron_angle": hx.chevron_angle,
        "port_velocity_heads": plate.PORT_VELOCITY_HEADS,
        "flux_steps": float(_FLUX_STEPS),
    }
    geo = np.array([values[k] for k in kernel.GEOMETRY], float)
    geo.flags.writeable = False
    return geo


@functools.lru_cache(maxsize=4)
def kernel_coolant_tables(mass_fraction: float) -> tuple:
    """The coolant's tables as the compiled chiller reads them, its freezing point and table top [K].

    Kept per glycol fraction: indexing the tables costs more than a one-point solve."""
    from evtms.benches import _chiller_kernel as kernel
    from evtms.hx._counterflow_kernels import bucket_table

    cool = coolant(mass_fraction=mass_fraction)
    table = cool.tables()
    return tuple(bucket_table(table[x], table[y]) for x, y in kernel.COOLANT_TABLES), cool.T_freeze, cool.T_max


def chiller_heat_rate(inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid) -> dict[str, np.ndarray]:
    """Steady-state chiller response over arrays of bench inputs.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``mdot`` [kg/s], ``p_in`` [Pa], ``h_in`` [J/kg] (or ``T_in`` [K]),
        ``mdot_coolant`` [kg/s], ``T_coolant_in`` [K].
    params : Parameters
        Plate geometry (``params.chiller``).
    fluid : Fluid
        Refrigerant properties.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` [W] (< 0: heat into the refrigerant), ``h_in``, ``h_out``
        [J/kg], ``T_out`` [K], ``p_out`` [Pa], ``x_out`` [1],
        ``T_coolant_out`` [K], ``dp`` [Pa], ``capacity_ratio`` [1] (plate
        area over the area needed to evaporate to saturated vapour),
        ``h_out_continued`` [J/kg] (``h_out`` for a superheated outlet; for
        a two-phase outlet the superheated side's heat rate per unit area at
        the phase boundary continued linearly to the negative area ``1 -
        1/capacity_ratio``: C1 across the boundary, as the evaporator's) and
        ``status`` (int8, see :data:`FLAGS`; 0 and 11 are valid).
    """
    p_in = np.asarray(inputs["p_in"], float)
    h_in = inlet_enthalpy(inputs, fluid)
    # An evaporator needs a saturation state at its inlet pressure.
    inlet_bad = ~np.isfinite(h_in) | ~((p_in > fluid.p_triple) & (p_in < fluid.p_crit))
    # Compiled on tabulated properties where numba is (the array solve is its reference).
    solve = solve_chiller_compiled if numba_enabled() else solve_chiller
    res = solve(
        fluid,
        params.chiller,
        p_in,
        np.where(inlet_bad, np.nan, h_in),
        inputs["mdot"],
        inputs["mdot_coolant"],
        inputs["T_coolant_in"],
    )
    status = first_code(
        [
            (inlet_bad | res["coolant_outside"], STATUS_OUTSIDE_FLUID_RANGE),
            (res["bad_flow"], STATUS_FLOW_NOT_POSITIVE),
            (res["coolant_freezes"], STATUS_COOLANT_FREEZES),
            (res["bad_direction"], STATUS_NOT_COLDER_THAN_COOLANT),
            (res["bad_dp"], STATUS_DP_EXCEEDS_INLET),
            (res["bad_props"], STATUS_PROPERTY_FAILED),
        ],
        p_in.size,
    )
    status[(status == 0) & res["outside_range"]] = STATUS_CORRELATION_OUTSIDE_RANGE
    out = {k: np.asarray(res[k], float).copy() for k in OUTPUTS if k not in ("status", "h_in")}
    out["h_in"] = h_in
    out = {k: out[k] for k in OUTPUTS if k != "status"}
    finish_status(status, out, BENCH.valid_flags)
    out["status"] = status
    return out


FLAGS = {
    **COMMON_FLAGS,
    STATUS_NOT_COLDER_THAN_COOLANT: "refrigerant_inlet_not_colder_than_coolant",
    STATUS_DP_EXCEEDS_INLET: "pressure_drop_exceeds_inlet_pressure",
    STATUS_COOLANT_FREEZES: "coolant_below_freezing_point",
    STATUS_FLOW_NOT_POSITIVE: "mass_flow_not_positive",
    STATUS_CORRELATION_OUTSIDE_RANGE: "valid_correlation_outside_range",
}

BENCH = Bench(
    name="chiller",
    title="evtms chiller bench: brazed-plate R134a evaporator cooling MEG 50 % coolant",
    axes=("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=chiller_heat_rate,
    parameters=PlateHXParams,
    valid_flags=(0, STATUS_CORRELATION_OUTSIDE_RANGE),
    variables={
        "Q": ("W", "heat flow from refrigerant to coolant"),
        "T_coolant_out": ("K", "coolant temperature leaving the chiller"),
        "capacity_ratio": ("1", "plate area over the area needed to evaporate to saturated vapour"),
    },
    optional_outputs=("capacity_ratio", "h_out_continued"),
    surface_axes=(("p_in", "T_coolant_in"), ("mdot_coolant", "T_coolant_in")),
    presets={
        # A small grid about the sizing point (1 degC evaporating, coolant 30 degC).
        "thesis": {
            "mdot": (0.01, 0.02, 0.03, 0.04),
            "p_in": pressure_nodes(np.array([-10.0, 0.0, 10.0])),
            "h_in": (220e3, 250e3),
            "mdot_coolant": (0.05, 0.1, 0.2),
            "T_coolant_in": (293.15, 303.15, 313.15, 323.15),
        },
        # Cycle envelope: evaporating -35 to 29 degC every 2 K (as the evaporator's), coolant
        # 0-50 degC every 2 K at 0.05-0.5 kg/s (the battery pump gives 0.13-0.43 kg/s), and
        # refrigerant flows from 0.37 g/s (a branch of two in parallel may take little: the
        # physics holds a nearly shut chiller branch at 0.1-0.3 g/s where the LUT cycle, from
        # 1 g/s, had to close it; three more nodes on the 1-150 g/s ladder). With the
        # coolant every 5 K, 6 coolant flows and 10 refrigerant flows from 3 g/s, the LUT cycle's
        # suction pressure was up to 5 % off the direct physics (the response hinges on
        # T_coolant_in - T_sat and pinches where the coolant's capacity rate limits). At the
        # branch states of a cabin+chiller cycle (outlet 5-10 K superheated) h_out_continued
        # curves most along h_in (a slightly colder inlet already leaves two-phase) and along
        # T_coolant_in; 7 enthalpies (not 5) and the coolant every 2 K (not 2.5 K), paid for
        # with 6 coolant flows (not 7, the flattest axis), cut its rms error there from 1.1 to
        # 0.7 kJ/kg and the worst error in Q_chiller of a 60-point cycle check from 9 to 5 %.
        # Below 0 degC (every 3 K, then 2 K near 0) for the heat pump, whose chiller draws on the
        # e-drive loop down to -25 degC in the cold (the system spec's hp map). Refrigerant flows
        # 1.18x apart (37, not 19 at 1.40x): at the heat pump's e-drive loop of -16 to 6 degC the
        # chiller evaporates 10-25 K below its coolant and the suction pressure follows the outlet
        # steeply; with the outlet pressure curvature-corrected as well, the hp cycle's worst
        # Q_chiller error on 100 random points fell from 1.30 to 0.95 % (p_A 0.95 to 0.71 %);
        # 1.9 million points, about 15 s compiled.
        "cycle": {
            "mdot": tuple(0.001 * (150.0 ** (1 / 30)) ** np.arange(-6, 31)),
            "p_in": pressure_nodes(np.arange(-35.0, 30.0, 2.0)),
            "h_in": tuple(np.linspace(200e3, 350e3, 7)),
            "mdot_coolant": tuple(np.geomspace(0.05, 0.5, 6)),
            "T_coolant_in": tuple(np.concatenate((np.arange(-25.0, -9.0, 3.0), np.arange(-8.0, 50.1, 2.0))) + 273.15),
        },
    },
)
