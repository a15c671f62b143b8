"""Air-to-refrigerant coil: moving-boundary effectiveness-NTU with moist air.

Shared by the condenser and the evaporator benches. The coil is a single row
of flat multiport tubes in cross flow, refrigerant in all tubes in parallel:
the refrigerant side (:class:`evtms.hx.crossflow.TubeSide`) marched through
its zones by the cross-flow core (:func:`evtms.hx.crossflow.march_crossflow`)
against an air side (:class:`evtms.hx.sides.AirSide` for the condenser,
:class:`evtms.hx.sides.MoistAirSide` for the evaporator); this module derives
both from the coil's parameters and reports the outlet states.
Along the tubes the refrigerant passes through up to three zones (vapour,
two-phase, liquid; in the order its enthalpy moves). Each zone covers a
fraction ``f`` of the tube length and so of the face area and air flow; it is
an effectiveness-NTU exchanger of ``f`` times the coil's UA, with both streams
unmixed (Incropera et al. 2007, eq. 11.32). The fractions follow from the
zone heat loads, solved by bisection, which is the moving-boundary method of
Simscape's two-phase/moist-air heat exchangers (MathWorks 2024) in steady
state.

Single-phase zones use a secant heat capacity of the refrigerant over the
zone's temperature span (to its phase boundary, or to the entering-air
temperature for the last zone), so no zone can move more heat than the
second law allows: the refrigerant never leaves a condenser colder, nor an
evaporator warmer, than the entering air.

Air side: louvred fins, Colburn factor of Chang and Wang (1997) at the core
velocity (:func:`evtms.hx.fins.louvered_fin_htc`), the fin
geometry from the coil parameters (:func:`coil_geometry`). Its data cover
louver-pitch Reynolds numbers 100 to 3000; ``air_outside_range`` marks the
points outside, which the benches flag.

Moist air (evaporator): the two-phase zone, at one refrigerant temperature,
is dry along the air's path until its surface falls to the air's dew point
and wet beyond (the partly wet coil of Elmahdy and Mitalas 1977 and Braun
1988); the wet part follows the enthalpy-potential method of Threlkeld (1970)
in the effectiveness-NTU form of Braun, Klein and Mitchell (1989). The vapour
and liquid zones are evaluated both dry and wet, and the air loses the larger
heat rate, Braun et al.'s rule for partly wet coils
(:meth:`evtms.hx.sides.MoistAirSide.zone_model`). The moisture condensed
follows from the effective surface state of the wet analysis; the
condensate drains off at that surface's temperature, so the refrigerant
gains the air's loss less the condensate's enthalpy (Braun et al. give the
refrigerant the whole loss; with the condensate's enthalpy on top, air at
blower 0.1 left up to 0.25 K colder than the refrigerant on 4,000 random
points of the cycle envelope).
The zones' outlet streams mix; where the mixture lies beyond saturation (a
mixture of nearly saturated streams can, the saturation curve being convex;
humid air on a very cold coil does so strongly) the excess water condenses
and the air leaves saturated, the energy balance kept
(:func:`evtms.hx.sides.condense_excess`).

Heat transfer is evaluated at the inlet pressure; the pressure drop (Haaland
single-phase friction, Mueller-Steinhagen-Heck two-phase friction, over the
zone lengths) sets the outlet pressure at which the outlet state is reported.

References
----------
ASHRAE (2017). Handbook - Fundamentals, ch. 1 (Psychrometrics).
Braun, J. E. (1988). Methodologies for the design and control of central
cooling plants. PhD thesis, University of Wisconsin-Madison.
Braun, J. E., Klein, S. A., Mitchell, J. W. (1989). Effectiveness models for
cooling towers and cooling coils. ASHRAE Trans. 95(2), 164-174.
Chang, Y.-J., Wang, C.-C. (1997). A generalized heat transfer correlation for
louver fin geometry. Int. J. Heat Mass Transfer 40(3), 533-544.
Elmahdy, A. H., Mitalas, G. P. (1977). A simple model for cooling and
dehumidifying coils for use in calculating energy requirements for
buildings. ASHRAE Trans. 83(2), 103-117.
Threlkeld, J. L. (1970). Thermal Environmental Engineering, 2nd ed.,
Prentice-Hall, ch. 13.
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th ed.
MathWorks (2024). Condenser Evaporator (2P-MA), Simscape Fluids reference.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from evtms._jit import numba_enabled
from evtms.fluid import Fluid, humid_air_inlet, quality, saturated_air
from evtms.hx.crossflow import CAPACITY_RATIO_MAX, TubeSide, march_crossflow
from evtms.hx.fins import LouveredFin, chang_wang_outside_range, louvered_fin_htc
from evtms.hx.sides import OUTLET_SATURATION_MAX, AirSide, MoistAirSide
from evtms.hx.sides import condense_excess as _condense_excess
from evtms.params import Environment, Relation, area, count, fouling, fraction, length, param

__all__ = [
    "CAPACITY_RATIO_MAX",
    "OUTLET_SATURATION_MAX",
    "CoilGeometry",
    "CoilParams",
    "_condense_excess",
    "coil_geometry",
    "solve_coil",
]


@dataclass(frozen=True)
class CoilParams:
    """Geometry and heat-transfer data shared by the two air-cooled coils.

    Flat multiport tubes with louvred fins, air in cross flow, refrigerant in
    all tubes in parallel. Areas as in the Simscape blocks.

    Attributes
    ----------
    n_tubes : int
        Number of flat tubes [1], 1 to 1000; ``n_tubes * tube_thickness < core_height``.
    core_length : float
        Tube length across the air stream [m], (0, 10].
    core_height : float
        Core height [m], (0, 10].
    tube_depth : float
        Tube width along the air flow [m], (0, 1].
    tube_thickness : float
        Tube outer thickness [m], (0, 0.1].
    n_channels : int
        Refrigerant channels per tube [1], 1 to 1000.
    fin_spacing : float
        Fin spacing [m], (0, 0.1].
    area_air_free : float
        Minimum free-flow area on the air side [m2], (0, 1000], at most the
        frontal area ``core_length * core_height``.
    area_air_primary : float
        Air-side primary (tube) area [m2], (0, 1000].
    area_air_fin : float
        Air-side fin area [m2], (0, 1000].
    area_ref : float
        Refrigerant-side heat-transfer area [m2], (0, 1000].
    fan_flow_max : float
        Air volume flow at fan/blower fraction 1 [m3/s], (0, 100].
    fin_efficiency : float
        Fin efficiency [1], (0, 1].
    fouling_air, fouling_ref : float
        Fouling factors [m2 K/W], [0, 0.01) (0.1 m2K/kW = 1e-4 m2K/W).
    wall_thickness : float
        Tube wall thickness [m], (0, 0.01], less than half the tube thickness and depth.
    wall_conductivity : float
        Tube wall conductivity [W/(m K)], (0, 2000].
    roughness : float
        Channel wall roughness for the friction factor [m], [0, 0.001].
    nu_laminar : float
        Fully developed laminar Nusselt number, constant wall temperature [1], (0, 100].
    louver_angle : float
        Louver angle of the fins [rad], (0, pi/2); 27 deg by default, typical of
        automotive louvred fins.
    louver_pitch : float
        Louver pitch along the air flow [m], (0, 0.1], less than ``tube_depth``.
    louver_length : float
        Louver length across the fin [m], (0, 1], less than the fin length
        ``core_height / n_tubes - tube_thickness`` (7.75 mm condenser, 8 mm evaporator).
    fin_thickness : float
        Fin thickness [m], (0, 0.01], less than ``fin_spacing``.

    Notes
    -----
    ``fin_spacing`` is the fin pitch: with the defaults the fin area
    ``n_tubes (core_length / fin_spacing) 2 (core_height / n_tubes - tube_thickness) tube_depth``
    is the Simscape block's 23.4 m2 (condenser) and 7.2 m2 (evaporator). The
    louvred-fin air side (Chang and Wang 1997, :func:`evtms.hx.fins.chang_wang_j`)
    takes the tube pitch ``core_height / n_tubes``, the fin length (tube pitch
    minus ``tube_thickness``) and the flow depth ``tube_depth`` from these
    parameters, and the louver geometry from the four above.
    """

    n_tubes: int = count(40)
    core_length: float = length(1.26)
    core_height: float = length(0.39)
    tube_depth: float = length(0.015, 1.0)
    tube_thickness: float = length(0.002, 0.1)
    n_channels: int = count(12)
    fin_spacing: float = length(0.5e-3, 0.1)
    area_air_free: float = area(0.391)
    area_air_primary: float = area(1.48)
    area_air_fin: float = area(23.4)
    area_ref: float = area(2.22)
    fan_flow_max: float = param(0.88, 0.0, 100.0, "m3/s", lo_open=True)
    fin_efficiency: float = fraction(0.7)
    fouling_air: float = fouling(1e-4)
    fouling_ref: float = fouling(1e-4)
    wall_thickness: float = length(0.1e-3, 0.01)
    wall_conductivity: float = param(240.0, 0.0, 2000.0, "W/(m K)", lo_open=True)
    roughness: float = param(15e-6, 0.0, 1e-3, "m")
    nu_laminar: float = param(3.66, 0.0, 100.0, lo_open=True)
    louver_angle: float = param(0.47123889803846897, 0.0, 1.5707963267948966, "rad", lo_open=True, hi_open=True)
    louver_pitch: float = length(1.0e-3, 0.1)
    louver_length: float = length(6.5e-3, 1.0)
    fin_thickness: float = length(0.1e-3, 0.01)

    RELATIONS: ClassVar[tuple[Relation, ...]] = (
        Relation("wall_thickness", "<", lambda c: c.tube_thickness / 2, "tube_thickness / 2", ("tube_thickness",)),
        Relation("wall_thickness", "<", lambda c: c.tube_depth / 2, "tube_depth / 2", ("tube_depth",)),
        Relation(
            "n_tubes",
            "<",
            lambda c: c.core_height / c.tube_thickness,
            "core_height / tube_thickness",
            ("core_height", "tube_thickness"),
        ),
        Relation(
            "area_air_free",
            "<=",
            lambda c: c.core_length * c.core_height,
            "core_length * core_height",
            ("core_length", "core_height"),
        ),
        Relation(
            "louver_length",
            "<",
            lambda c: c.core_height / c.n_tubes - c.tube_thickness,
            "core_height / n_tubes - tube_thickness",
            ("core_height", "n_tubes", "tube_thickness"),
        ),
        Relation("louver_pitch", "<", lambda c: c.tube_depth, "tube_depth", ("tube_depth",)),
        Relation("fin_thickness", "<", lambda c: c.fin_spacing, "fin_spacing", ("fin_spacing",)),
    )


@dataclass(frozen=True)
class CoilGeometry:
    """Derived coil geometry.

    Attributes
    ----------
    D_h : float
        Hydraulic diameter of one refrigerant channel [m].
    flow_area : float
        Total refrigerant flow cross-section of all channels [m2].
    tube_length : float
        Refrigerant path length through the coil [m].
    area_air : float
        Total air-side area, primary plus fins [m2].
    eta_surface : float
        Air-side overall surface efficiency [1].
    fin : evtms.hx.fins.LouveredFin
        Louvred-fin geometry of the air side (Chang and Wang 1997).
    R_wall : float
        Conduction resistance of the tube wall [K/W].
    """

    D_h: float
    flow_area: float
    tube_length: float
    area_air: float
    eta_surface: float
    fin: LouveredFin
    R_wall: float


@functools.lru_cache(maxsize=64)
def coil_geometry(coil: CoilParams) -> CoilGeometry:
    """Derive channel and air-side geometry from the coil parameters.

    Channels are rectangles filling the tube's inner section (the webs between
    them are neglected): width ``(depth - 2 t_wall) / n_channels``, height
    ``thickness - 2 t_wall``. Overall surface efficiency
    ``eta_o = 1 - A_fin / A_air (1 - eta_fin)`` (Incropera et al. 2007, eq. 11.3).
    Louvred fins: fin pitch ``fin_spacing``, tube pitch ``core_height /
    n_tubes``, fin length the tube pitch minus ``tube_thickness``, flow depth
    ``tube_depth``.
    """
    tube_pitch = coil.core_height / coil.n_tubes
    width = (coil.tube_depth - 2 * coil.wall_thickness) / coil.n_channels
    height = coil.tube_thickness - 2 * coil.wall_thickness
    area_air = coil.area_air_primary + coil.area_air_fin
    return CoilGeometry(
        D_h=2 * width * height / (width + height),
        flow_area=coil.n_tubes * coil.n_channels * width * height,
        tube_length=coil.core_length,
        area_air=area_air,
        eta_surface=1.0 - coil.area_air_fin / area_air * (1.0 - coil.fin_efficiency),
        fin=LouveredFin(
            louver_angle=coil.louver_angle,
            louver_pitch=coil.louver_pitch,
            louver_length=coil.louver_length,
            fin_pitch=coil.fin_spacing,
            fin_length=tube_pitch - coil.tube_thickness,
            flow_depth=coil.tube_depth,
            tube_pitch=tube_pitch,
            fin_thickness=coil.fin_thickness,
        ),
        R_wall=coil.wall_thickness / (coil.wall_conductivity * coil.area_ref),
    )


#: The coil modes :func:`solve_coil` marches compiled by default (numba enabled).
COMPILED_MODES = ("condenser", "evaporator")


def _air_inlet_arrays(T: np.ndarray, RH: np.ndarray, p: float) -> dict[str, np.ndarray]:
    """Moist-air inlet properties per point, computed once per distinct (T, RH).

    The pairs are packed into complex numbers (:func:`evtms.fluid._unique_rows`' way): a
    cycle solver's one-point calls spent 0.1 ms in ``np.unique(axis=0)``."""
    packed = np.asarray(T, float) + 1j * np.asarray(RH, float)
    if packed.size and (packed == packed[0]).all():  # one air state (a cycle solver's call)
        uniq, inverse = packed[:1], np.zeros(packed.size, np.intp)
    else:
        uniq, inverse = np.unique(packed, return_inverse=True)
    rows = [humid_air_inlet(float(v.real), p, float(v.imag)) for v in uniq]
    if not rows:  # no points: empty arrays with the same keys
        return {key: np.empty(0) for key in ("w", "h", "cp", "rho", "mu", "k", "T_dew", "Pr")}
    return {key: np.array([r[key] for r in rows])[inverse.reshape(-1)] for key in rows[0]}


def solve_coil(
    fluid: Fluid,
    coil: CoilParams,
    env: Environment,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    air_fraction: np.ndarray,
    mode: str,
    T_air: np.ndarray | float | None = None,
    RH_air: np.ndarray | float | None = None,
    compiled: bool | None = None,
) -> dict[str, np.ndarray]:
    """Steady-state coil response at arrays of refrigerant and air inlet conditions.

    Parameters
    ----------
    fluid : Fluid
        Refrigerant property source.
    coil : CoilParams
        Geometry and heat-transfer parameters.
    env : Environment
        Entering air (pressure, temperature, relative humidity).
    p_in : numpy.ndarray
        Refrigerant inlet pressure [Pa].
    h_in : numpy.ndarray
        Refrigerant inlet specific enthalpy [J/kg].
    mdot : numpy.ndarray
        Refrigerant mass flow [kg/s], > 0.
    air_fraction : numpy.ndarray
        Fan or blower fraction of the maximum air volume flow [1].
    mode : {"condenser", "evaporator"}
        ``"condenser"``: heat leaves the refrigerant, dry air.
        ``"evaporator"``: heat enters the refrigerant, moist air may condense.
    T_air, RH_air : numpy.ndarray or float, optional
        Entering-air temperature [K] and relative humidity [1] per point;
        ``env.T`` and ``env.RH`` if not given (``env.p`` is the air pressure).
    compiled : bool, optional
        Whether the march runs per point in machine code on tabulated refrigerant
        properties (:mod:`evtms.hx._coil_kernels`, :mod:`evtms.fluid_tables`: within the
        tables' tolerance of CoolProp, states beyond them on CoolProp) or as the NumPy
        array march on ``fluid`` (the reference). By default compiled where numba is
        enabled (:func:`evtms._jit.numba_enabled`) for the modes of :data:`COMPILED_MODES`.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` heat from refrigerant to air [W], ``Q_latent`` [W] (<= 0),
        ``h_out`` [J/kg], ``p_out`` [Pa], ``dp`` [Pa], ``T_out`` [K],
        ``x_out`` [1], ``h_out_continued`` [J/kg] (``h_out`` where the outlet
        reaches the coil's last zone, else continued linearly past the phase
        boundary), ``T_air_out`` [K], ``T_surface_min`` coldest wall
        surface [K], ``T_surface_eff`` coldest zone-mean effective surface of
        the wet-coil method [K] (evaporator), ``T_dew_air_in`` [K],
        ``m_condensate`` [kg/s], ``H_condensate`` enthalpy flow of the
        condensate leaving [W], ``h_air_out`` [J/kg dry air],
        ``w_air_out`` [kg/kg dry air], ``m_dry_air`` [kg/s],
        ``m_condensate_outlet`` the part of ``m_condensate`` that condensed
        where the zones' outlet air mixes supersaturated [kg/s], ``Re_Lp``
        the air side's louver-pitch Reynolds number [1], and the boolean masks
        ``air_outside_range`` (``Re_Lp`` outside the Chang and Wang range),
        ``bad_direction`` (the air cannot take or give heat in the required
        direction), ``bad_dp`` (pressure drop at or above inlet pressure) and
        ``bad_props`` (a property evaluation failed).
    """
    if mode not in ("condenser", "evaporator"):
        raise ValueError(f"mode must be 'condenser' or 'evaporator', not {mode!r}")
    p_in, h_in, mdot, air_fraction = (np.asarray(a, float).reshape(-1) for a in (p_in, h_in, mdot, air_fraction))
    n = p_in.size
    T_air = np.broadcast_to(np.asarray(env.T if T_air is None else T_air, float), (n,))
    RH_air = np.broadcast_to(np.asarray(env.RH if RH_air is None else RH_air, float), (n,))
    side, tubes, Re_Lp = _coil_sides(coil, env, air_fraction, T_air, RH_air, mode == "evaporator")
    if compiled is None:
        compiled = numba_enabled() and mode in COMPILED_MODES
    if not compiled:
        return _solve_numpy(fluid, side, tubes, p_in, h_in, mdot, mode, Re_Lp)
    out, fallback = _solve_compiled(fluid, side, tubes, p_in, h_in, mdot, mode, Re_Lp)
    if fallback.any():  # states beyond the property tables: CoolProp's path, point by point as ever
        idx = np.nonzero(fallback)[0]
        side_fb, tubes_fb, _ = _coil_sides(coil, env, air_fraction[idx], T_air[idx], RH_air[idx], mode == "evaporator")
        sub = _solve_numpy(fluid, side_fb, tubes_fb, p_in[idx], h_in[idx], mdot[idx], mode, Re_Lp[idx])
        for key, value in sub.items():
            out[key][idx] = value
    return out


def air_stream(
    coil: CoilParams, env: Environment, volume_flow: np.ndarray, T_air: np.ndarray, RH_air: np.ndarray
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The air side of a louvred-fin core at its entering state and volume flow.

    The dry-air mass flow ``m_da = rho V / (1 + w)`` [kg/s] at the entering state,
    its capacity rate ``C_air = m_da c_p`` [W/K] (``c_p`` per kg of dry air), and
    the air side's thermal resistance ``R_air = 1 / (eta_o h A) + R_f / A`` [K/W]
    with the louvred-fin coefficient of Chang and Wang (1997) at the core
    velocity ``V / area_air_free`` (:func:`evtms.hx.fins.louvered_fin_htc`).

    Parameters
    ----------
    coil : CoilParams
        Core geometry.
    env : Environment
        Air pressure (``env.p``).
    volume_flow : numpy.ndarray
        Air volume flow at the entering state [m3/s].
    T_air, RH_air : numpy.ndarray
        Entering-air temperature [K] and relative humidity [1].

    Returns
    -------
    tuple
        The entering air's properties (:func:`evtms.fluid.humid_air_inlet` per
        point), ``m_da`` [kg/s], ``C_air`` [W/K], ``R_air`` [K/W] and the louver-pitch
        Reynolds number ``Re_Lp`` [1] (flagged by the benches outside the correlation's data).
    """
    geo = coil_geometry(coil)
    air = _air_inlet_arrays(T_air, RH_air, env.p)
    m_da = air["rho"] * volume_flow / (1.0 + air["w"])
    C_air = m_da * air["cp"]
    h_o, Re_Lp = louvered_fin_htc(volume_flow / coil.area_air_free, air["rho"], air["mu"], air["k"], air["Pr"], geo.fin)
    R_air = 1.0 / (geo.eta_surface * h_o * geo.area_air) + coil.fouling_air / geo.area_air
    return air, m_da, C_air, R_air, Re_Lp


def _coil_sides(
    coil: CoilParams, env: Environment, air_fraction: np.ndarray, T_air: np.ndarray, RH_air: np.ndarray, wet: bool
) -> tuple[AirSide, TubeSide, np.ndarray]:
    """The air side (dry or moist), the tube side and the air's louver-pitch Reynolds number per point."""
    geo = coil_geometry(coil)
    air, m_da, C_air, R_air, Re_Lp = air_stream(coil, env, air_fraction * coil.fan_flow_max, T_air, RH_air)
    if wet:
        side = MoistAirSide(T_air, air, m_da, C_air, R_air, env.p, sat_air=saturated_air(env.p))
    else:
        side = AirSide(T_air, air, m_da, C_air, R_air, env.p)
    tubes = TubeSide(
        D_h=geo.D_h,
        flow_area=geo.flow_area,
        length=geo.tube_length,
        area=coil.area_ref,
        roughness=coil.roughness / geo.D_h,
        nu_laminar=coil.nu_laminar,
        R_wall=geo.R_wall + coil.fouling_ref / coil.area_ref,
    )
    return side, tubes, Re_Lp


def _solve_numpy(
    fluid: Fluid,
    side: AirSide,
    tubes: TubeSide,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mode: str,
    Re_Lp: np.ndarray,
) -> dict[str, np.ndarray]:
    """:func:`solve_coil` by the array march (:func:`evtms.hx.crossflow.march_crossflow`)."""
    sign = -1.0 if mode == "condenser" else 1.0  # direction of the refrigerant's enthalpy change
    res = march_crossflow(fluid, tubes, side, p_in, h_in, mdot, mode)
    h_out = res.h_out

    # --- outlet states -----------------------------------------------------
    p_out = p_in - res.dp
    bad_dp = ~(p_out > fluid.p_triple)
    p_ok = np.where(bad_dp, np.nan, p_out)
    # Saturation at the outlet pressure from the fluid's tabulated curve (within
    # 1 J/kg of CoolProp below 3 MPa); a two-phase outlet sits at T_sat, so only
    # single-phase outlets need a (p, h) flash.
    curve = fluid.saturation_curve()
    x_out = quality(h_out, curve.liquid_enthalpy(p_ok), curve.vapour_enthalpy(p_ok))
    T_out = curve.temperature(p_ok)
    single = ~((x_out >= 0.0) & (x_out <= 1.0))
    T_out[single] = fluid.state("PH", p_ok[single], h_out[single], ("T",))["T"]
    march = {
        "Q": res.Q,
        "dp": res.dp,
        "h_out": h_out,
        "h_out_continued": res.h_out_continued,
        "capacity_ratio": res.capacity_ratio,
        "T_surface_min": res.T_surface_min,
        "bad_direction": res.bad_direction,
        "bad_props": res.bad_props,
        "p_out": p_out,
        "x_out": x_out,
        "T_out": T_out,
    }
    return _outputs(side, march, sign, bad_dp, Re_Lp)


def march_arguments(fluid: Fluid, side: AirSide, tubes: TubeSide) -> tuple[np.ndarray, np.ndarray, tuple]:
    """What the compiled march (:func:`evtms.hx._coil_kernels.march_point`) takes besides the
    refrigerant inlet: the air columns of its points per point (``POINTS`` after ``mdot``), the
    ``tube`` array (``TUBE``) and the saturated-air curve ``(T, h, w)`` (zeros for dry air)."""
    air = side.air
    columns = (side.T_in, side.C, side.R, air["h"], air["w"], side.m_da, air["cp"])
    per_point = np.empty((np.size(side.C), len(columns)))
    for k, column in enumerate(columns):
        per_point[:, k] = column
    tube = np.array(
        [tubes.D_h, tubes.flow_area, tubes.length, tubes.area, tubes.roughness, tubes.nu_laminar, tubes.R_wall]
        + [fluid.p_triple]
    )
    sat_air = side.sat_air if isinstance(side, MoistAirSide) else None
    curve = (sat_air.T, sat_air.h, sat_air.w) if sat_air is not None else (np.zeros(2), np.zeros(2), np.zeros(2))
    return per_point, tube, tuple(np.ascontiguousarray(c, float) for c in curve)


def march_inputs(
    fluid: Fluid, coil: CoilParams, env: Environment, air_fraction, T_air, RH_air, mode: str
) -> tuple[np.ndarray, np.ndarray, tuple]:
    """:func:`march_arguments` of the coil ``coil`` in ``mode`` at its entering air (fraction of
    the fan's flow [1], temperature [K] and relative humidity [1] per point), as :func:`solve_coil`
    computes them."""
    air_fraction, T_air, RH_air = np.broadcast_arrays(
        *(np.asarray(a, float).reshape(-1) for a in (air_fraction, T_air, RH_air))
    )
    side, tubes, _ = _coil_sides(coil, env, air_fraction, T_air, RH_air, mode == "evaporator")
    return march_arguments(fluid, side, tubes)


def _solve_compiled(
    fluid: Fluid,
    side: AirSide,
    tubes: TubeSide,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mode: str,
    Re_Lp: np.ndarray,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`solve_coil` by the compiled march on tabulated properties
    (:func:`evtms.hx._coil_kernels.march_points`), and the mask of the points it leaves to
    :func:`_solve_numpy` (states beyond the tables)."""
    from evtms.fluid_tables import tables_for
    from evtms.hx import _coil_kernels as kernels

    sign = -1.0 if mode == "condenser" else 1.0
    moist = isinstance(side, MoistAirSide)
    air, tube, curve = march_arguments(fluid, side, tubes)
    points = np.empty((p_in.size, len(kernels.POINTS)))
    for k, column in enumerate((p_in, h_in, mdot)):
        points[:, k] = column
    points[:, 3:] = air
    rows = kernels.march_points(points, tube, mode == "condenser", moist, *tables_for(fluid).arrays, *curve)
    res = {name: rows[:, k] for k, name in enumerate(kernels.COLUMNS)}
    for name in ("bad_direction", "bad_props"):
        res[name] = res[name] > 0
    side.m_cond[:] = res["m_cond"]
    side.cond_enthalpy[:] = res["cond_enthalpy"]
    side.latent[:] = res["latent"]
    side.T_surface_eff[:] = res["T_surface_eff"]
    bad_dp = ~(res["p_out"] > fluid.p_triple)
    return _outputs(side, res, sign, bad_dp, Re_Lp), res["fallback"] > 0


def _outputs(
    side: AirSide, march: dict[str, np.ndarray], sign: float, bad_dp: np.ndarray, Re_Lp: np.ndarray
) -> dict[str, np.ndarray]:
    """:func:`solve_coil`'s outputs from the march's and the air side's (leaving air, condensate)."""
    Q_signed = -sign * march["Q"]  # > 0 when heat flows from refrigerant to air
    air_out = side.outlet(Q_signed)
    bad_props = march["bad_props"] | ~np.isfinite(march["T_out"] + march["x_out"] + air_out["T_air_out"])
    return {
        "Q": Q_signed,
        "Q_latent": -side.latent,
        "h_out": march["h_out"],
        "p_out": march["p_out"],
        "dp": march["dp"],
        "T_out": march["T_out"],
        "x_out": march["x_out"],
        "T_air_out": air_out["T_air_out"],
        "T_surface_min": march["T_surface_min"],
        "T_surface_eff": side.T_surface_eff,
        "T_dew_air_in": side.air["T_dew"],
        "m_condensate": side.m_cond,
        "H_condensate": side.cond_enthalpy,
        "h_air_out": air_out["h_air_out"],
        "m_dry_air": side.m_da,
        "w_air_out": air_out["w_air_out"],
        "m_condensate_outlet": air_out["m_condensate_outlet"],
        "Re_Lp": Re_Lp,
        "air_outside_range": chang_wang_outside_range(Re_Lp),
        "h_out_continued": march["h_out_continued"],
        "capacity_ratio": march["capacity_ratio"],
        "bad_direction": march["bad_direction"],
        "bad_dp": bad_dp,
        "bad_props": bad_props,
    }
