"""Water-cooled condenser (WCC) bench: the chiller's brazed-plate core condensing R134a into the heating loop.

The refrigerant (the compressor's discharge) enters at ``(p_in, h_in)``,
superheated or two-phase, with mass flow ``mdot`` and condenses in the
chiller's chevron-plate pack (:class:`evtms.benches.chiller.PlateHXParams`,
75 x 250 mm plates, 60 deg chevrons, 2 mm channels); the coolant,
monoethylene glycol 50 % by mass in water (:class:`evtms.fluid.Coolant`),
enters at ``T_coolant_in`` with mass flow ``mdot_coolant`` and flows against
it. The steady state comes from the counter-flow moving-boundary core
(:func:`evtms.hx.counterflow.solve_counterflow_condenser`, the evaporator's
solver mirrored in enthalpy and temperature): desuperheating vapour,
condensing two-phase and subcooling liquid zones, each with its own
refrigerant-side coefficient, the coolant passing all of them in series.

Correlations (:mod:`evtms.hx.plate`): single-phase channels on both sides by
Martin (1996), as the chiller (viscosity ratio 1); condensation by Yan, Lio
and Lin (1999), ``Nu = 4.118 Re_eq^0.4 Pr_l^(1/3)`` with the local
equivalent mass flux ``G_eq = G [1 - x + x (rho_l/rho_v)^0.5]``, averaged
(Gauss-Legendre) over the condensing zone's quality range: from the inlet
quality (1 for a superheated inlet) to 0, or to the outlet quality where the
outlet is two-phase (a second pass, with the quality of the first). The
coolant coefficient is evaluated at the coolant's inlet temperature, then at
the mean of inlet and outlet. Heat transfer is evaluated at the inlet
pressure; the pressure drop sets the outlet pressure at which the outlet
state is reported.

Two-phase friction (A): Yan, Lio and Lin also fitted a condensation friction
factor, but its form could not be checked against their text here, so it is
not used. The condensing zone's frictional gradient is instead the
all-liquid one of the equivalent mass flux (the Akers et al. 1959 idea their
heat-transfer correlation rests on): ``dp/dz = xi(Re_eq) G_eq^2 / (2 rho_l
D_h)``, ``xi`` Martin's friction factor, averaged over the zone's qualities.
It meets both single-phase limits in dynamic head (``G_eq^2/rho_l`` is
``G^2/rho_l`` at ``x = 0`` and ``G^2/rho_v`` at ``x = 1``). The refrigerant
drop of a plate condenser is a few kPa against a 1-2 MPa discharge, so this
choice moves the outlet's saturation temperature by hundredths of a kelvin.
Ports: 1.4 velocity heads each (Shah and Focke 1988), as the chiller.

Validity: Martin compared his equations with data of Re 200 to 10,000; Yan,
Lio and Lin's data cover channel mass fluxes of 60 to 120 kg/(m2 s)
(:data:`evtms.hx.plate.YAN_LIO_LIN_G_RANGE`). The heat pump's refrigerant
flows of 2-60 g/s give 1-29 kg/(m2 s) in the default pack (14 refrigerant
channels) and its coolant flows Re of about 13 to 550, so most points use a correlation outside its data: they are
valid with status 11 (``valid_correlation_outside_range``), the correlations
evaluated as published.

States the model does not take (NaN and a status code): a subcooled-liquid
inlet (nothing for a condenser to do; status 7), an inlet pressure at or
above the critical (no saturation to condense at; status 8), non-positive
flows (6), a coolant below its freezing point (5) or beyond its property
table at inlet or outlet (1), and a coolant not colder than the refrigerant's
inlet temperature (3; its saturation temperature for a two-phase inlet): no
heat would leave the refrigerant.

A coolant between the saturation and a superheated inlet's temperature only
desuperheats: the refrigerant leaves as vapour, at the coolant's temperature
at the most (the core's vapour zone ends there, Bell et al. 2015), and the
capacity ratio is 0 (no area condenses it). Such a point is valid: ahead of
the air condenser (the ``cabin+wcc`` chain) a WCC on a coolant warmer than
the ambient air does exactly this, and its heat rate tends continuously to
the condensing one's as the coolant falls to the saturation temperature, so
a LUT cell across that edge interpolates it.

Energy: ``Q = mdot (h_in - h_out) = mdot_coolant (h_c,out - h_c,in)`` (> 0,
heat out of the refrigerant), both to round-off, in the coolant's tabulated
enthalpy (:meth:`evtms.fluid.Coolant.enthalpy`). Second law: the refrigerant
never leaves colder than the coolant enters, nor the coolant warmer than the
refrigerant enters (the core needs infinite area for either).

Computation: where numba is, per point in machine code on tabulated
refrigerant properties (:func:`solve_wcc_compiled`,
:mod:`evtms.benches._wcc_kernel`), within 1e-4 of CoolProp's; otherwise, and
as its reference, the NumPy path on CoolProp (:func:`solve_wcc`).

References
----------
Yan, Y.-Y., Lio, H.-C., Lin, T.-F. (1999). Condensation heat transfer and
pressure drop of refrigerant R-134a in a plate heat exchanger. Int. J. Heat
Mass Transfer 42(6), 993-1006.
Martin, H. (1996). A theoretical approach to predict the performance of
chevron-type plate heat exchangers. Chem. Eng. Process. 35(4), 301-310.
Akers, W. W., Deans, H. A., Crosser, O. K. (1959). Condensing heat transfer
within horizontal tubes. Chem. Eng. Prog. Symp. Ser. 55(29), 171-176.
Shah, R. K., Focke, W. W. (1988). Plate heat exchangers and their design
theory. In: Heat Transfer Equipment Design, Hemisphere, 227-254.
Bell, I. H. et al. (2015). A generalized moving-boundary algorithm to predict
the heat transfer rate of counterflow heat exchangers for any phase
configuration. Appl. Therm. Eng. 79, 192-201.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

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
from evtms.benches.chiller import (
    KERNEL_GAUSS,
    PlateHXParams,
    kernel_coolant_tables,
    kernel_geometry,
    martin_htc,
    plate_geometry,
    plate_outlet,
    refrigerant_props,
    solve_plate_points,
)
from evtms.benches.condenser import inlet_enthalpy
from evtms.fluid import Fluid, coolant
from evtms.hx import plate, tube
from evtms.hx.counterflow import LIQUID, TWO_PHASE, VAPOUR, RefrigerantPath, solve_counterflow_condenser
from evtms.hx.sides import CoolantSide

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters

#: Default plate count (the system spec's sizing rule, section 5.6): the smallest count that
#: condenses 5 kW of R134a at 45 degC saturation (1.160 MPa) entering as 70 degC vapour
#: (449.4 kJ/kg), against MEG 50 % entering at 30 degC at 0.2 kg/s. The refrigerant flow is the
#: one for which 5 kW takes the vapour to saturated liquid at 45 degC (263.9 kJ/kg at the inlet
#: pressure): 5 kW / 185.5 kJ/kg = 26.96 g/s; at that flow Q >= 5 kW is the same as
#: capacity_ratio >= 1. Found by solving the point for 6 to 39 plates (:func:`solve_wcc`):
#: 28 plates give 4.95 kW (outlet x = 0.013), 29 plates 5.00 kW (capacity ratio 1.0004,
#: UA 409 W/K, coolant out at 37.4 degC, refrigerant drop 0.4 kPa), 30 plates 5.05 kW.
#: ``tests/test_wcc.py`` pins the point.
DEFAULT_PLATES = 29

STATUS_COOLANT_NOT_BELOW_INLET = 3
STATUS_DP_EXCEEDS_INLET = 4
STATUS_COOLANT_FREEZES = 5
STATUS_FLOW_NOT_POSITIVE = 6
STATUS_INLET_SUBCOOLED = 7
STATUS_SUPERCRITICAL = 8
#: Valid point where a correlation (Martin, Yan-Lio-Lin) runs outside its data's range.
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

#: Passes over the coolant's mean temperature and the condensing zone's quality range.
_PASSES = 2
#: A coolant outlet this close to the top of its property table [K] is taken as beyond it.
_COOLANT_TOP_MARGIN = 1e-3


def _condensing_zone(G, D_h, sat, x_hi, x_lo, angle):
    """Mean condensing coefficient [W/(m2 K)] and frictional gradient [Pa/m] over quality ``x_lo..x_hi``.

    Gauss-Legendre (:data:`evtms.hx.tube.GAUSS_NODES`) over the zone's qualities. The coefficient
    is Yan, Lio and Lin's (1999); the gradient the all-liquid one of the equivalent mass flux with
    Martin's (1996) friction factor (the module's note on friction).
    """
    x = x_lo[:, None] + (x_hi - x_lo)[:, None] * tube.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    G2 = G[:, None]
    Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
    h = plate.yan_lio_lin_condensation_htc(x, G2, D_h, col["mu_l"], col["rho_l"], col["rho_v"], col["k_l"], Pr_l)
    G_eq = plate.equivalent_mass_flux(G2, x, col["rho_l"], col["rho_v"])
    Re_eq = G_eq * D_h / col["mu_l"]
    xi = plate.martin_friction_factor(Re_eq, angle)
    grad = xi * G_eq**2 / (2.0 * col["rho_l"] * D_h)
    w = tube.GAUSS_WEIGHTS
    return np.sum(h * w, axis=-1), np.sum(grad * w, axis=-1)


def solve_wcc(
    fluid: Fluid,
    hx: PlateHXParams,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mdot_coolant: np.ndarray,
    T_coolant_in: np.ndarray,
) -> dict[str, np.ndarray]:
    """Steady-state response of the plate condenser at arrays of refrigerant and coolant inlet conditions.

    Parameters
    ----------
    fluid : Fluid
        Refrigerant properties.
    hx : PlateHXParams
        Plate geometry, walls, fouling and the coolant's glycol fraction.
    p_in : numpy.ndarray
        Refrigerant inlet pressure [Pa].
    h_in : numpy.ndarray
        Refrigerant inlet specific enthalpy [J/kg] (superheated or two-phase).
    mdot : numpy.ndarray
        Refrigerant mass flow [kg/s], > 0.
    mdot_coolant : numpy.ndarray
        Coolant mass flow [kg/s], > 0.
    T_coolant_in : numpy.ndarray
        Coolant inlet temperature [K].

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` heat from refrigerant to coolant [W] (> 0), ``h_out`` [J/kg],
        ``p_out`` [Pa], ``dp`` [Pa], ``T_out`` [K], ``x_out`` [1],
        ``T_coolant_out`` [K], ``h_coolant_in``, ``h_coolant_out`` coolant
        enthalpies [J/kg], ``UA`` overall conductance [W/K] (the zones'
        ``Q_z`` over their log-mean differences), ``fractions`` zone area
        fractions (n, 3) in (liquid, two-phase, vapour) order,
        ``capacity_ratio`` [1] (plate area over the area needed to condense
        to saturated liquid), ``h_out_continued`` [J/kg], ``Re_coolant`` [1],
        and the masks ``outside_range`` (a correlation outside its data),
        ``inlet_subcooled``, ``supercritical``, ``not_below_inlet``,
        ``bad_dp``, ``bad_flow``, ``coolant_freezes``, ``coolant_outside``
        (coolant inlet or outlet beyond its property table) and ``bad_props``.
    """
    p_in, h_in, mdot, m_c, T_c_in = (
        np.asarray(a, float).reshape(-1).copy() for a in (p_in, h_in, mdot, mdot_coolant, T_coolant_in)
    )
    geo = plate_geometry(hx)
    A, D_h, angle = geo["area"], geo["D_h"], hx.chevron_angle
    cool = coolant(mass_fraction=hx.coolant_mass_fraction)
    bad_flow = ~((mdot > 0) & (m_c > 0))
    mdot = np.where(bad_flow, np.nan, mdot)
    m_c = np.where(bad_flow, np.nan, m_c)
    coolant_freezes = T_c_in < cool.T_freeze
    coolant_outside = ~coolant_freezes & ~(T_c_in <= cool.T_max)  # above the table's range, or not a number
    T_c_in = np.where(coolant_freezes | coolant_outside, np.nan, T_c_in)

    # --- refrigerant states --------------------------------------------------
    supercritical = p_in >= fluid.p_crit
    sat = fluid.saturation(p_in)  # NaN at and above the critical pressure
    T_sat, h_l, h_v = sat["T"], sat["h_l"], sat["h_v"]
    inlet_subcooled = h_in < h_l
    # What the core cannot take leaves the solve as NaN (Q = 0 there, blanked by its status).
    h_in_ok = np.where(inlet_subcooled, np.nan, h_in)
    inlet = fluid.state("PH", p_in, h_in_ok, ("T", "D"))
    T_in = inlet["T"]
    not_below_inlet = ~(T_c_in < T_in) & np.isfinite(T_c_in + T_in)
    T_c_ok = np.where(not_below_inlet, np.nan, T_c_in)
    # The least enthalpy the refrigerant can reach, at the coolant's inlet temperature: subcooled
    # liquid, or vapour where the coolant is not below the saturation (h_v as it tends to it).
    h_at_c = fluid.state("PT", p_in, T_c_ok, ("H",))["H"]
    h_at_c = np.where(T_c_ok >= T_sat, np.fmax(h_at_c, h_v), h_at_c)
    G = mdot / geo["flow_ref"]
    G_c = m_c / geo["flow_coolant"]
    bad_props = ~np.isfinite(T_in + T_sat + h_at_c) & ~inlet_subcooled & ~not_below_inlet

    # Single-phase refrigerant coefficients at each zone's mean temperature (Martin 1996): the
    # desuperheating zone from the inlet to saturation, the subcooling zone from saturation
    # towards the coolant's inlet temperature.
    superheated = h_in_ok > h_v
    # The vapour zone ends at the saturation, or at the coolant's inlet temperature where that is warmer.
    T_vap = 0.5 * (T_in + np.fmax(T_sat, T_c_ok))
    vap = refrigerant_props(fluid, p_in, np.where(superheated, T_vap, np.nan), sat, "v")
    h_vap, Re_vap = martin_htc(G, D_h, vap, angle)
    # (At the saturation where the coolant is not below it: no subcooling zone, but finite values.)
    liq = refrigerant_props(fluid, p_in, 0.5 * (T_sat + np.fmin(T_c_ok, T_sat)), sat, "l")
    h_liq, Re_liq = martin_htc(G, D_h, liq, angle)
    R_fixed = geo["R_wall"] + hx.fouling_ref / A
    h_lv = h_v - h_l
    x_hi = np.clip((np.minimum(h_in_ok, h_v) - h_l) / h_lv, 0.0, 1.0)
    x_lo = np.zeros_like(x_hi)

    T_c_mean = T_c_ok
    for _ in range(_PASSES):  # coolant at its inlet, then its mean; quality range to 0, then to the outlet's
        c_props = cool.properties(T_c_mean)
        h_c, Re_c = martin_htc(G_c, D_h, c_props, angle)
        R_c = 1.0 / (h_c * A) + hx.fouling_coolant / A
        h_tp, grad_tp = _condensing_zone(G, D_h, sat, x_hi, x_lo, angle)
        R_ref = np.stack([R_fixed + 1.0 / (h * A) for h in (h_liq, h_tp, h_vap)], axis=1)
        ref = RefrigerantPath(mdot, h_in_ok, T_in, T_sat, h_l, h_v, h_at_c, R_ref)
        side = CoolantSide(cool, m_c, T_c_ok, R_c)
        res = solve_counterflow_condenser(ref, side)
        T_c_mean = np.where(np.isfinite(res.T_secondary_out), 0.5 * (T_c_ok + res.T_secondary_out), T_c_ok)
        x_lo = np.where(np.isfinite(res.h_out), np.clip((res.h_out - h_l) / h_lv, 0.0, x_hi), 0.0)

    Q = res.Q
    f = res.fractions
    h_out = res.h_out

    # --- pressure drop over the zone lengths, plus the ports -------------------
    L = f * hx.plate_length
    grad_l = plate.martin_friction_factor(Re_liq, angle) * G**2 / (2.0 * liq["D"] * D_h)
    grad_v = plate.martin_friction_factor(Re_vap, angle) * G**2 / (2.0 * vap["D"] * D_h)
    dp = grad_l * L[:, LIQUID] + grad_tp * L[:, TWO_PHASE] + grad_v * L[:, VAPOUR]
    dp, p_out, bad_dp, x_out, T_out = plate_outlet(fluid, geo, sat, p_in, h_out, mdot, inlet["D"], dp)
    T_c_out = res.T_secondary_out
    coolant_outside |= np.isfinite(T_c_ok) & ~(T_c_out < cool.T_max - _COOLANT_TOP_MARGIN)

    used = f > 0
    outside = plate.martin_outside_range(Re_c, angle)
    outside |= used[:, LIQUID] & plate.martin_outside_range(Re_liq, angle)
    outside |= used[:, VAPOUR] & plate.martin_outside_range(Re_vap, angle)
    outside |= used[:, TWO_PHASE] & plate.yan_lio_lin_outside_range(G)
    with np.errstate(divide="ignore", invalid="ignore"):
        UA_total = np.sum(f / (R_ref + R_c[:, None]), axis=1)
    bad_props |= ~np.isfinite(T_out + x_out + T_c_out + dp)
    return {
        "Q": Q,
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
        "outside_range": outside,
        "inlet_subcooled": inlet_subcooled,
        "supercritical": supercritical,
        "not_below_inlet": not_below_inlet,
        "bad_dp": bad_dp,
        "bad_flow": bad_flow,
        "coolant_freezes": coolant_freezes,
        "coolant_outside": coolant_outside,
        "bad_props": bad_props,
    }


def solve_wcc_compiled(
    fluid: Fluid,
    hx: PlateHXParams,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mdot_coolant: np.ndarray,
    T_coolant_in: np.ndarray,
) -> dict[str, np.ndarray]:
    """:func:`solve_wcc` per point in machine code, on tabulated refrigerant properties.

    The kernel (:mod:`evtms.benches._wcc_kernel`) reads the refrigerant tables
    of :mod:`evtms.fluid_tables` and the coolant's own tables, as the compiled
    chiller does; points whose states leave the refrigerant tables are solved
    by :func:`solve_wcc` with ``fluid`` itself. Same parameters and outputs as
    :func:`solve_wcc`; the results equal ``solve_wcc`` fed with those tables
    (:class:`evtms.fluid_tables_dome.DomeTabulatedFluid`) to round-off and
    CoolProp's within the tables' tolerance. Needs numba.
    """
    from evtms.benches import _wcc_kernel as kernel

    inputs = (p_in, h_in, mdot, mdot_coolant, T_coolant_in)
    return solve_plate_points(kernel, kernel_constants(fluid, hx), solve_wcc, fluid, hx, *inputs)


def kernel_constants(fluid: Fluid, hx: PlateHXParams) -> tuple:
    """The compiled WCC's arguments after the inputs (:func:`evtms.benches._wcc_kernel.solve_points`):
    geometry, coolant tables, limits, property tables."""
    from evtms.fluid_tables import tables_for

    cool, T_freeze, T_max = kernel_coolant_tables(hx.coolant_mass_fraction)
    return (
        kernel_geometry(hx),
        cool,
        _mirrored_coolant_table(hx.coolant_mass_fraction),
        T_freeze,
        T_max,
        fluid.p_triple,
        fluid.p_crit,
        float(fluid.saturation_curve().p[0]),
        plate.YAN_LIO_LIN_G_RANGE,
        tables_for(fluid).arrays,
        KERNEL_GAUSS,
    )


@functools.lru_cache(maxsize=4)
def _mirrored_coolant_table(mass_fraction: float) -> tuple:
    """The coolant's (h, T) table reflected (``-h`` rising, ``-T``), as the condensing solve reads it
    (:func:`evtms.hx.counterflow.solve_counterflow_condenser`)."""
    from evtms.hx._counterflow_kernels import bucket_table

    table = coolant(mass_fraction=mass_fraction).tables()
    return bucket_table(-table["h"][::-1], -table["T"][::-1])


def wcc_heat_rate(inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid) -> dict[str, np.ndarray]:
    """Steady-state water-cooled condenser response over arrays of bench inputs.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``mdot`` [kg/s], ``p_in`` [Pa], ``h_in`` [J/kg] (or ``T_in`` [K]),
        ``mdot_coolant`` [kg/s], ``T_coolant_in`` [K].
    params : Parameters
        Plate geometry (``params.wcc``).
    fluid : Fluid
        Refrigerant properties.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` [W] (> 0: heat out of the refrigerant into the coolant),
        ``h_in``, ``h_out`` [J/kg], ``T_out`` [K], ``p_out`` [Pa], ``x_out``
        [1], ``T_coolant_out`` [K], ``dp`` [Pa], ``capacity_ratio`` [1] (plate
        area over the area needed to condense to saturated liquid; the
        receiver's closure is ``capacity_ratio = 1``), ``h_out_continued``
        [J/kg] (``h_out`` for a subcooled outlet; for a two-phase outlet the
        subcooled side's heat rate per unit area at the phase boundary
        continued linearly to the negative area ``1 - 1/capacity_ratio``: C1
        across the boundary, as the chiller's and the condenser's;
        ``capacity_ratio`` is 0 and ``h_out_continued`` equals ``h_out``
        where the coolant cannot take the latent heat with any area, its
        outlet reaching the saturation temperature first) and
        ``status`` (int8, see :data:`FLAGS`; 0 and 11 are valid).
    """
    p_in = np.asarray(inputs["p_in"], float)
    h_in = inlet_enthalpy(inputs, fluid)
    supercritical = p_in >= fluid.p_crit
    inlet_bad = ~np.isfinite(h_in) | ~(p_in > fluid.p_triple)
    # Compiled on tabulated properties where numba is (the array solve is its reference).
    solve = solve_wcc_compiled if numba_enabled() else solve_wcc
    res = solve(
        fluid,
        params.wcc,
        p_in,
        np.where(inlet_bad | supercritical, np.nan, h_in),
        inputs["mdot"],
        inputs["mdot_coolant"],
        inputs["T_coolant_in"],
    )
    status = first_code(
        [
            (supercritical, STATUS_SUPERCRITICAL),
            (inlet_bad, STATUS_OUTSIDE_FLUID_RANGE),
            (res["bad_flow"], STATUS_FLOW_NOT_POSITIVE),
            (res["coolant_freezes"], STATUS_COOLANT_FREEZES),
            (res["inlet_subcooled"], STATUS_INLET_SUBCOOLED),
            (res["not_below_inlet"], STATUS_COOLANT_NOT_BELOW_INLET),
            (res["coolant_outside"], STATUS_OUTSIDE_FLUID_RANGE),
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


def wcc_plates() -> PlateHXParams:
    """The WCC's default plate pack: the chiller's plates, :data:`DEFAULT_PLATES` of them."""
    return PlateHXParams(n_plates=DEFAULT_PLATES)


FLAGS = {
    **COMMON_FLAGS,
    STATUS_COOLANT_NOT_BELOW_INLET: "coolant_inlet_not_colder_than_refrigerant_inlet",
    STATUS_DP_EXCEEDS_INLET: "pressure_drop_exceeds_inlet_pressure",
    STATUS_COOLANT_FREEZES: "coolant_below_freezing_point",
    STATUS_FLOW_NOT_POSITIVE: "mass_flow_not_positive",
    STATUS_INLET_SUBCOOLED: "refrigerant_inlet_subcooled_liquid",
    STATUS_SUPERCRITICAL: "inlet_pressure_not_below_critical",
    STATUS_CORRELATION_OUTSIDE_RANGE: "valid_correlation_outside_range",
}

BENCH = Bench(
    name="wcc",
    title="evtms water-cooled condenser bench: brazed-plate R134a condenser heating MEG 50 % coolant",
    axes=("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=wcc_heat_rate,
    parameters=wcc_plates,
    valid_flags=(0, STATUS_CORRELATION_OUTSIDE_RANGE),
    variables={
        "Q": ("W", "heat flow from refrigerant to coolant"),
        "T_coolant_out": ("K", "coolant temperature leaving the water-cooled condenser"),
        "capacity_ratio": ("1", "plate area over the area needed to condense to saturated liquid"),
    },
    optional_outputs=("capacity_ratio", "h_out_continued"),
    surface_axes=(("p_in", "T_coolant_in"), ("mdot_coolant", "T_coolant_in")),
    presets={
        # About the heat pump's working range: discharge 0.8-2.2 MPa (31-72 degC saturation),
        # superheated inlets at every pressure, 10-50 g/s, the heating loop's coolant at 20-70 degC.
        # Points whose coolant is not below the refrigerant's inlet temperature are invalid (status 3);
        # between that and the saturation the WCC only desuperheats (capacity ratio 0).
        "thesis": {
            "mdot": (0.01, 0.02, 0.03, 0.05),
            "p_in": (0.8e6, 1.2e6, 1.6e6, 2.2e6),
            "h_in": (440e3, 460e3, 480e3),
            "mdot_coolant": (0.05, 0.1, 0.2, 0.3),
            "T_coolant_in": (293.15, 313.15, 333.15, 343.15),
        },
        # The hp circuit's envelope: discharge saturation 20-92 degC every 4 K (about 0.57-3.38 MPa; with the
        # heating loop at up to 70 degC the physics condenses at up to 91 degC), inlet enthalpy every 10 kJ/kg from
        # just inside the dome (x 0.97 at the lowest pressure, 0.75 at the highest) to 73-126 K superheat;
        # refrigerant 2-150 g/s on a geometric ladder (the compressor gives 60-140 g/s at full speed with the
        # e-drive loop at 20-35 degC, which the hp search visits). The capacity ratio, which the discharge
        # pressure hinges on, is steep where the coolant's capacity rate barely takes the latent heat (low
        # coolant flows, condensing a few kelvin above the coolant): the heating loop's pump at 0.05-0.36
        # kg/s on 11 geometric nodes (not 6) and the coolant every 2.5 K (not 5 K) took the worst LUT error
        # of the hp cycle's discharge pressure, on 100 random points of its envelope with the chiller's
        # physics direct, from 1.74 to 0.51 % and of its COP from 1.96 to 0.87 % (6 coolant flows at 2.5 K:
        # 1.96 / 2.01 %; 11 flows at 5 K: 1.18 / 1.32 %; 11 flows with the pressure every 2 K: 0.62 / 1.08 %;
        # 1.1 million points, about 10 s compiled). The pressure every 2 K (not 4 K): with the chiller's
        # physics in place of its LUT the WCC's part of the hp cycle's worst error fell from 1.02 to 0.50 %
        # (discharge pressure) and from 1.41 to 0.93 % (COP); 2.1 million points, about 19 s compiled.
        # The WCC ahead of the condenser (cabin+wcc) condenses from just above the air, down to 10 degC
        # saturation (the pressure from there), and its heat rate bends where the coolant passes the
        # saturation (below it the WCC condenses too, above it only desuperheats): the coolant every
        # 1.25 K from 10 degC took that circuit's worst LUT error of the COP from 2.14 to 0.90 % and of
        # the WCC's share of the heat from 2.15 to 0.83 % on 100 random points (hp unchanged within
        # 0.03 %); 4.6 million points.
        "cycle": {
            "mdot": tuple(np.geomspace(0.002, 0.15, 13)),
            "p_in": pressure_nodes(np.arange(10.0, 93.0, 2.0)),
            "h_in": tuple(np.linspace(405e3, 535e3, 14)),
            "mdot_coolant": tuple(np.geomspace(0.05, 0.36, 11)),
            "T_coolant_in": (278.15, 280.65, *(283.15 + 1.25 * np.arange(53))),
        },
    },
)
