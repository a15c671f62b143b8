"""Air-to-refrigerant coil: moving-boundary effectiveness-NTU with moist air.

Shared by the condenser and the evaporator benches. The coil is a single row
of flat multiport tubes in cross flow, refrigerant in all tubes in parallel.
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
velocity (:func:`evtms.benches.correlations.louvered_fin_htc`), the fin
geometry from the coil parameters (:func:`coil_geometry`). Its data cover
louver-pitch Reynolds numbers 100 to 3000; ``air_outside_range`` marks the
points outside, which the benches flag.

Moist air (evaporator): each zone is evaluated both dry (sensible) and wet
with the enthalpy-potential method of Threlkeld (1970) in the
effectiveness-NTU form of Braun, Klein and Mitchell (1989), and the air loses
the larger heat rate, their recommended rule for partly wet coils. The
moisture condensed follows from the effective surface state of the same
method; the condensate drains off at that surface's temperature, so the
refrigerant gains the air's loss less the condensate's enthalpy (Braun et
al. give the refrigerant the whole loss; with the condensate's enthalpy on
top, air at blower 0.1 left up to 0.25 K colder than the refrigerant on
4,000 random points of the cycle envelope).
The zones' outlet streams mix; where the mixture lies beyond saturation (a
mixture of nearly saturated streams can, the saturation curve being convex;
humid air on a very cold coil does so strongly) the excess water condenses
and the air leaves saturated, the energy balance kept
(:func:`_condense_excess`).

Heat transfer is evaluated at the inlet pressure; the pressure drop (Haaland
single-phase friction, Mueller-Steinhagen-Heck two-phase friction, over the
zone lengths) sets the outlet pressure at which the outlet state is reported.

References
----------
ASHRAE (2017). Handbook - Fundamentals, ch. 1 (Psychrometrics).
Braun, J. E., Klein, S. A., Mitchell, J. W. (1989). Effectiveness models for
cooling towers and cooling coils. ASHRAE Trans. 95(2), 164-174.
Chang, Y.-J., Wang, C.-C. (1997). A generalized heat transfer correlation for
louver fin geometry. Int. J. Heat Mass Transfer 40(3), 533-544.
Threlkeld, J. L. (1970). Thermal Environmental Engineering, 2nd ed.,
Prentice-Hall, ch. 13.
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th ed.
MathWorks (2024). Condenser Evaporator (2P-MA), Simscape Fluids reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evtms.benches import correlations as corr
from evtms.fluid import (
    Fluid,
    SaturatedAir,
    humid_air_inlet,
    humid_air_temperature,
    quality,
    saturated_air,
    water_liquid_enthalpy,
)
from evtms.params import CoilParams, Environment

_BISECTION_STEPS = 60


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
    fin : evtms.benches.correlations.LouveredFin
        Louvred-fin geometry of the air side (Chang and Wang 1997).
    R_wall : float
        Conduction resistance of the tube wall [K/W].
    """

    D_h: float
    flow_area: float
    tube_length: float
    area_air: float
    eta_surface: float
    fin: corr.LouveredFin
    R_wall: float


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
        fin=corr.LouveredFin(
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


def _gauss_mean(values: np.ndarray) -> np.ndarray:
    """Gauss-Legendre mean over the last axis, row by row.

    Written as a sum rather than a BLAS product, whose rounding depends on how
    many rows it is given: a point's value must not depend on its batch (the
    chunked sweeps give identical files in every mode).
    """
    return np.sum(values * corr.GAUSS_WEIGHTS, axis=-1)


def _single_phase_htc(G, D, rough, props, nu_lam):
    """Refrigerant single-phase heat-transfer coefficient [W/(m2 K)]."""
    Re = G * D / props["MU"]
    Pr = props["CP"] * props["MU"] / props["K"]
    f = corr.haaland_friction_factor(Re, rough)
    return corr.single_phase_nusselt(Re, Pr, f, nu_lam) * props["K"] / D


def _condensation_htc(G, D, sat, q, nu_lam):
    """Condensation coefficient [W/(m2 K)] averaged over quality 0..1 (Gauss-Legendre).

    The larger of the shear-driven (Cavallini-Zecchin) and the gravity-driven
    film (Chato) coefficients at heat flux ``q``.
    """
    x = corr.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
    nu = corr.cavallini_zecchin_nusselt(
        x, G[:, None], D, col["mu_l"], col["mu_v"], col["rho_l"], col["rho_v"], Pr_l, nu_lam
    )
    shear = _gauss_mean(nu) * sat["k_l"] / D
    film = corr.chato_film_condensation_htc(
        q, D, sat["rho_l"], sat["rho_v"], sat["k_l"], sat["mu_l"], sat["cp_l"], sat["h_v"] - sat["h_l"]
    )
    return np.maximum(shear, film)


def _boiling_htc(G, D, sat, q, nu_lam):
    """Flow-boiling coefficient [W/(m2 K)] averaged over quality 0..1 at heat flux ``q``."""
    x = corr.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
    h = corr.gungor_winterton_htc(
        x,
        G[:, None],
        D,
        q[:, None],
        col["h_v"] - col["h_l"],
        col["mu_l"],
        col["rho_l"],
        col["rho_v"],
        col["k_l"],
        Pr_l,
        nu_lam,
    )
    return _gauss_mean(h)


def _two_phase_gradient(G, D, rough, sat, x0, x1):
    """Mean two-phase frictional gradient [Pa/m] over quality x0..x1."""
    x = x0[:, None] + (x1 - x0)[:, None] * corr.GAUSS_NODES[None, :]
    col = {k: v[:, None] for k, v in sat.items()}
    g = corr.muller_steinhagen_heck_gradient(
        np.clip(x, 0.0, 1.0), G[:, None], D, rough, col["mu_l"], col["mu_v"], col["rho_l"], col["rho_v"]
    )
    return _gauss_mean(g)


def _bisect(func, target, hi, steps=_BISECTION_STEPS):
    """Vectorised bisection for ``func(f) = target`` on [0, hi]; func increasing in f."""
    lo = np.zeros_like(hi)
    hi = hi.copy()
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        below = func(mid) < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _air_inlet_arrays(T: np.ndarray, RH: np.ndarray, p: float) -> dict[str, np.ndarray]:
    """Moist-air inlet properties per point, computed once per distinct (T, RH)."""
    pairs = np.stack([T, RH], axis=1)
    uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)
    rows = [humid_air_inlet(float(t), p, float(rh)) for t, rh in uniq]
    if not rows:  # no points: empty arrays with the same keys
        return {key: np.empty(0) for key in ("w", "h", "cp", "rho", "mu", "k", "T_dew", "Pr")}
    return {key: np.array([r[key] for r in rows])[inverse.reshape(-1)] for key in rows[0]}


def _latent_heat_water(T: np.ndarray) -> np.ndarray:
    """Latent heat of condensation of water [J/kg] at ``T`` [K] (ASHRAE Fundamentals' linear fit)."""
    return 2.501e6 - 2369.0 * (T - 273.15)


#: Highest outlet degree of saturation ``w / w_sat(T)`` [1] of the wet coil: saturation
#: less a margin above the saturated-air tables' error (about 1e-6, ``evtms.fluid``), so
#: no outlet reads supersaturated against ``HAPropsSI``.
OUTLET_SATURATION_MAX = 1.0 - 1e-5
#: Fixed-point steps for the outlet state after condensing; each gains a factor of about 100.
_FOG_STEPS = 6


def _supersaturated(w: np.ndarray, T: np.ndarray, sat_air: SaturatedAir) -> np.ndarray:
    """Points whose humidity ratio ``w`` [kg/kg] exceeds :data:`OUTLET_SATURATION_MAX` of saturation at ``T`` [K]."""
    with np.errstate(invalid="ignore"):
        return w > OUTLET_SATURATION_MAX * sat_air.humidity_ratio(T)


def _condense_excess(h: np.ndarray, w: np.ndarray, sat_air: SaturatedAir) -> tuple[np.ndarray, np.ndarray]:
    r"""Water [kg/kg dry air] that condenses out of supersaturated air, and the temperature [K] it leaves at.

    The air of enthalpy ``h`` [J/kg dry air] and humidity ratio ``w`` ends
    on the outlet limit ``w_t(T) = s w_sat(T)`` (``s`` =
    :data:`OUTLET_SATURATION_MAX`) at the temperature ``T`` where the energy
    balance of the mixing closes with the condensate ``w - w_t(T)`` leaving
    as liquid:

    .. math:: h_t(T) + (w - w_t(T))\, h_{w}(T) = h,\quad
              h_t(T) = h_{sat}(T) - (1 - s)\, w_{sat}(T)\, h_g(T),

    ``h_g = 2.501e6 + 1860 (T - 273.15)`` J/kg the enthalpy of water vapour
    (ASHRAE 2017, ch. 1: ``h = 1.006 t + W (2501 + 1.86 t)`` kJ/kg) and
    ``h_w`` the condensate's (:func:`evtms.fluid.water_liquid_enthalpy`),
    solved by fixed-point iteration on the tabulated saturation curve (the
    condensate term changes by about 1 % of ``dh_sat/dT`` per kelvin, so
    each step gains a factor of about 100). The caller sets the outlet
    enthalpy to ``h - (w - w_t) h_w`` exactly, which keeps the energy balance
    to round-off. Removing the liquid at ``T`` leaves the air's temperature
    as it is: the air settles where adiabatic mixing with the liquid kept
    would (between the mixed streams' temperatures).

    Parameters
    ----------
    h : numpy.ndarray
        Enthalpy of the mixed air [J/kg dry air].
    w : numpy.ndarray
        Its humidity ratio [kg/kg dry air], above the outlet limit.
    sat_air : SaturatedAir
        Saturated-air curve at the air pressure.

    Returns
    -------
    tuple of numpy.ndarray
        Water condensed [kg/kg dry air] (>= 0) and the temperature [K] the
        air and the condensate leave at.
    """
    slack = 1.0 - OUTLET_SATURATION_MAX

    def target(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w_sat = sat_air.humidity_ratio(T)
        return OUTLET_SATURATION_MAX * w_sat, slack * w_sat * (2.501e6 + 1860.0 * (T - 273.15))

    T = sat_air.temperature(h)
    for _ in range(_FOG_STEPS):
        w_t, h_short = target(T)
        T = sat_air.temperature(h - (w - w_t) * water_liquid_enthalpy(T) + h_short)
    w_t, _ = target(T)
    return np.maximum(w - w_t, 0.0), T


#: Largest coil fraction searched for the fraction needed to finish a phase change.
_F_SEARCH_MAX = 1e3
#: Coil fraction at which a zone's heat rate gives its slope at zero length [1].
_F_SLOPE = 1e-6
#: Cap of the capacity ratio (coil fraction available over needed), for finite LUT values.
CAPACITY_RATIO_MAX = 1e3


@dataclass
class _Moisture:
    """Moisture removed by one zone, from its effective surface state (Braun et al. 1989, eqs. 25-28).

    Attributes
    ----------
    air_h, air_w : numpy.ndarray
        Entering air's enthalpy [J/kg dry air] and humidity ratio [kg/kg dry air].
    m_air : numpy.ndarray
        Dry-air flow through the whole coil [kg/s].
    decay : numpy.ndarray
        ``exp(-NTU_o)`` [1], with the air-side number of transfer units
        ``NTU_o = 1 / (R_air C_air)`` (the same for every zone).
    sat_air : SaturatedAir
        Saturated-air curve at the air pressure.
    """

    air_h: np.ndarray
    air_w: np.ndarray
    m_air: np.ndarray
    decay: np.ndarray
    sat_air: SaturatedAir

    def subset(self, sub: np.ndarray) -> _Moisture:
        return _Moisture(self.air_h[sub], self.air_w[sub], self.m_air[sub], self.decay[sub], self.sat_air)

    def condensate(self, f: np.ndarray, q_air: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Condensate [kg/s], effective surface temperature [K] and condensate enthalpy flow [W].

        For a zone of coil fraction ``f`` whose air loses ``q_air`` [W]: the
        air leaves at ``h_a,out = h_a,in - q_air / (f m_a)``; the effective
        surface lies at ``h_s,eff = h_a,in - (h_a,in - h_a,out) / (1 -
        exp(-NTU_o))``, saturated at ``T_s,eff``; the air leaves at ``w_out =
        w_s,eff + (w_in - w_s,eff) exp(-NTU_o)``; the zone is wet where
        that lies below ``w_in`` (the effective surface below the entering
        dew point) and the condensate leaves at ``T_s,eff``.
        """
        sat = self.sat_air
        with np.errstate(divide="ignore", invalid="ignore"):
            h_a_out = self.air_h - q_air / np.where(f > 0, f * self.m_air, 1.0)
        h_s_eff = self.air_h - (self.air_h - h_a_out) / (1.0 - self.decay)
        T_s_eff = sat.temperature(h_s_eff)
        w_s_eff = sat.humidity_ratio(T_s_eff)
        w_out = w_s_eff + (self.air_w - w_s_eff) * self.decay
        m_w = np.where(f > 0, f * self.m_air * np.maximum(self.air_w - w_out, 0.0), 0.0)
        H_w = np.where(m_w > 0, m_w * water_liquid_enthalpy(T_s_eff), 0.0)
        return m_w, T_s_eff, H_w


@dataclass
class _ZoneHeatRate:
    """Heat rate [W] of one zone as a function of its coil fraction f (effectiveness-NTU).

    Cross flow, both streams unmixed; the air stream through the zone is
    ``f C_air`` and its conductance ``f / R_tot``. ``wet`` holds the same
    model in enthalpy-potential form (capacities in kg/s, potential in J/kg);
    the air then loses the larger of the two (Braun et al. 1989), and the
    refrigerant gains that less the enthalpy of the condensate draining off
    the coil (``moisture``): the air's enthalpy cannot fall below that of
    saturated air at the refrigerant temperature, so neither can the air
    leaving cross the refrigerant's temperature (Braun et al.'s model, which
    neglects the condensate's enthalpy, gives the refrigerant that too and
    let the air leave up to 0.25 K colder than the refrigerant at blower 0.1).
    """

    C_ref: np.ndarray
    R_tot: np.ndarray
    C_air: np.ndarray
    dT: np.ndarray
    wet: _ZoneHeatRate | None = None
    moisture: _Moisture | None = None

    def dry(self, f: np.ndarray) -> np.ndarray:
        C_af = f * self.C_air
        C_min = np.minimum(C_af, self.C_ref)
        C_max = np.maximum(C_af, self.C_ref)
        with np.errstate(divide="ignore", invalid="ignore"):
            ntu = np.where(C_min > 0, f / self.R_tot / np.where(C_min > 0, C_min, 1.0), 0.0)
            cr = np.where(np.isfinite(C_max) & (C_max > 0), C_min / np.where(C_max > 0, C_max, 1.0), 0.0)
            # NaN inputs (points already flagged invalid) stay NaN here, silently.
            return corr.crossflow_effectiveness(ntu, cr) * C_min * self.dT

    def air_rate(self, f: np.ndarray) -> np.ndarray:
        """Heat rate the air loses [W]: the larger of the dry and wet analyses."""
        q = self.dry(f)
        return q if self.wet is None else np.maximum(q, self.wet.dry(f))

    def rate(self, f: np.ndarray) -> np.ndarray:
        """Heat rate the refrigerant gains [W]: :meth:`air_rate` less the condensate's enthalpy."""
        q = self.air_rate(f)
        if self.moisture is None:
            return q
        H_w = self.moisture.condensate(f, q)[2]
        return q - np.where(np.isfinite(H_w), H_w, 0.0)  # a NaN surface state flags the point later

    def subset(self, sub: np.ndarray) -> _ZoneHeatRate:
        return _ZoneHeatRate(
            self.C_ref[sub],
            self.R_tot[sub],
            self.C_air[sub],
            self.dT[sub],
            None if self.wet is None else self.wet.subset(sub),
            None if self.moisture is None else self.moisture.subset(sub),
        )

    def fraction_needed(self, Q_needed: np.ndarray, two_phase: bool) -> np.ndarray:
        """Coil fraction the zone needs to move ``Q_needed`` (inf if it never can).

        A two-phase zone's heat rate is proportional to its fraction (its
        effectiveness does not depend on it); a single-phase zone's fraction
        comes by bisection on a hypothetically longer coil.
        """
        finite = np.isfinite(Q_needed)
        if two_phase:
            per_unit = self.rate(np.ones_like(Q_needed))
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(finite & (per_unit > 0), Q_needed / per_unit, np.inf)
        big = np.full_like(Q_needed, _F_SEARCH_MAX)
        ok = finite & (self.rate(big) >= Q_needed)
        f = np.full_like(Q_needed, np.inf)
        if ok.any():
            sub = np.nonzero(ok)[0]
            f[ok] = _bisect(self.subset(sub).rate, Q_needed[ok], big[ok])
        return f


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
    sign = -1.0 if mode == "condenser" else 1.0  # direction of the refrigerant's enthalpy change
    wet = mode == "evaporator"
    p_in, h_in, mdot, air_fraction = (np.asarray(a, float).reshape(-1) for a in (p_in, h_in, mdot, air_fraction))
    n = p_in.size
    geo = coil_geometry(coil)
    rough = coil.roughness / geo.D_h

    # --- air side --------------------------------------------------------
    T_air = np.broadcast_to(np.asarray(env.T if T_air is None else T_air, float), (n,))
    RH_air = np.broadcast_to(np.asarray(env.RH if RH_air is None else RH_air, float), (n,))
    air = _air_inlet_arrays(T_air, RH_air, env.p)
    volume_flow = air_fraction * coil.fan_flow_max
    m_da = air["rho"] * volume_flow / (1.0 + air["w"])
    C_air = m_da * air["cp"]
    # Louvred-fin air side (Chang and Wang 1997) at the core velocity, flagged
    # where Re_Lp lies outside the correlation's data.
    h_o, Re_Lp = corr.louvered_fin_htc(
        volume_flow / coil.area_air_free, air["rho"], air["mu"], air["k"], air["Pr"], geo.fin
    )
    R_air = 1.0 / (geo.eta_surface * h_o * geo.area_air) + coil.fouling_air / geo.area_air
    R_wall_ref = geo.R_wall + coil.fouling_ref / coil.area_ref
    sat_air = saturated_air(env.p) if wet else None

    # --- refrigerant states ------------------------------------------------
    sat = fluid.saturation(p_in)
    T_sat, h_l, h_v = sat["T"], sat["h_l"], sat["h_v"]
    T_in = fluid.state("PH", p_in, h_in, ("T",))["T"]
    h_air_T = fluid.state("PT", p_in, T_air, ("H",))["H"]  # refrigerant at air temperature
    G = mdot / geo.flow_area
    bad_props = ~np.isfinite(T_in + T_sat + h_air_T)

    if mode == "condenser":
        start = np.where(h_in > h_v, 2, np.where(h_in > h_l, 1, 0))
        order = (2, 1, 0)  # vapour -> two-phase -> liquid
    else:
        start = np.where(h_in < h_l, 0, np.where(h_in < h_v, 1, 2))
        order = (0, 1, 2)
    start_pos = np.array([order.index(z) for z in range(3)])[start]  # position of the inlet zone in the march
    bad_direction = ~(sign * (T_air - T_in) > 0)

    # Two-phase refrigerant coefficient over the full coil area. Both film
    # condensation and boiling depend on the wall heat flux, taken as the mean
    # flux of an all-two-phase coil and found by fixed-point iteration.
    two_phase_htc = _condensation_htc if mode == "condenser" else _boiling_htc
    q = np.full(n, 1000.0)
    for _ in range(5):
        h_tp = two_phase_htc(G, geo.D_h, sat, q, coil.nu_laminar)
        UA = 1.0 / (R_air + R_wall_ref + 1.0 / (h_tp * coil.area_ref))
        q = np.maximum(C_air * -np.expm1(-UA / C_air) * np.abs(T_air - T_sat) / coil.area_ref, 1.0)

    # --- march through the zones -----------------------------------------
    f_rem = np.ones(n)
    done = bad_props | bad_direction
    h_cur, T_cur = h_in.copy(), T_in.copy()
    Q = np.zeros(n)
    dp = np.zeros(n)
    m_cond = np.zeros(n)
    cond_enthalpy = np.zeros(n)  # sum of m_w h_w(T_s) [W]
    latent = np.zeros(n)
    T_surface_min = np.full(n, np.inf)
    T_surface_eff = np.full(n, np.inf)
    # Boundary enthalpy a zone of the march starts from when it is not the inlet zone.
    entry_h = {1: h_v, 0: h_l} if mode == "condenser" else {1: h_l, 2: h_v}
    f_needed = np.zeros(n)  # coil fraction needed to finish the phase change
    # Heat rate per coil fraction of the last zone at zero length [W], where the
    # outlet does not reach that zone: it continues the outlet enthalpy past the
    # phase boundary (see ``h_out_continued``).
    last_zone_slope = np.full(n, np.nan)
    for pos, zone in enumerate(order):
        is_last = pos == len(order) - 1
        live = (start_pos <= pos) & ~done & (f_rem > 0)
        # Zones before the last are also evaluated where the coil already ended, as
        # if it were longer: the fraction needed to finish the phase change. The last
        # zone is set up there too, for its slope at zero length.
        ok = (start_pos <= pos) & ~(bad_props | bad_direction)
        path = live | (ok & (not is_last)) | (ok & is_last & done & np.isfinite(f_needed))
        if not path.any():
            continue
        idx = np.nonzero(path)[0]
        Ta, Ts, m = T_air[idx], T_sat[idx], mdot[idx]
        at_start = start[idx] == zone
        Tr0 = np.where(at_start, T_in[idx], Ts)
        hr0 = np.where(at_start, h_in[idx], entry_h[zone][idx]) if zone in entry_h else h_in[idx].copy()
        two_phase = zone == 1
        # The phase boundary ends this zone only if it lies on the refrigerant's way towards the air.
        reachable = np.zeros(idx.size, bool) if is_last else (sign * (Ta - Ts) > 0)
        # Liquid ends at h_l, vapour at h_v; two-phase at h_l when condensing, h_v when boiling.
        boundary_h = (h_l if zone == 0 or (two_phase and mode == "condenser") else h_v)[idx]
        T_end = np.where(reachable, Ts, Ta)
        h_end = np.where(reachable, boundary_h, h_air_T[idx])
        Q_needed = np.where(reachable, m * np.abs(boundary_h - hr0), np.inf)

        if two_phase:
            h_ref = h_tp[idx]
            C_ref = np.full(idx.size, np.inf)
            props = None
        else:
            T_mid = 0.5 * (Tr0 + T_end)
            props = fluid.state("PT", p_in[idx], T_mid, ("D", "CP", "MU", "K"))
            phase = "v" if zone == 2 else "l"
            for key, sk in (("D", "rho"), ("CP", "cp"), ("MU", "mu"), ("K", "k")):
                props[key] = np.where(np.isfinite(props[key]), props[key], sat[f"{sk}_{phase}"][idx])
            h_ref = _single_phase_htc(G[idx], geo.D_h, rough, props, coil.nu_laminar)
            span = T_end - Tr0
            cp_eff = np.where(np.abs(span) > 1e-9, (h_end - hr0) / np.where(span == 0, 1.0, span), props["CP"])
            C_ref = m * cp_eff
        R_ref = R_wall_ref + 1.0 / (h_ref * coil.area_ref)
        model = _ZoneHeatRate(C_ref=C_ref, R_tot=R_air[idx] + R_ref, C_air=C_air[idx], dT=np.abs(Ta - Tr0))
        if wet:
            # Enthalpy potential (Braun et al. 1989): saturated-air enthalpy slope
            # c_s as the secant between refrigerant and entering-air temperature.
            h_s_r = sat_air.enthalpy(Tr0)
            c_s = (sat_air.enthalpy(Ta) - h_s_r) / np.maximum(Ta - Tr0, 1e-9)
            model.wet = _ZoneHeatRate(
                C_ref=C_ref / c_s,
                R_tot=air["cp"][idx] * R_air[idx] + c_s * R_ref,  # (J/kg)/W
                C_air=m_da[idx],
                dT=np.maximum(air["h"][idx] - h_s_r, 0.0),
            )
            model.moisture = _Moisture(
                air_h=air["h"][idx],
                air_w=air["w"][idx],
                m_air=m_da[idx],
                decay=np.exp(-1.0 / (R_air[idx] * C_air[idx])),
                sat_air=sat_air,
            )
        if not is_last:
            f_needed[idx] += model.fraction_needed(Q_needed, two_phase)
        else:
            short = np.nonzero(~live[idx])[0]
            if short.size:  # the heat rate is linear in the fraction at zero length
                small = np.full(short.size, _F_SLOPE)
                last_zone_slope[idx[short]] = model.subset(short).rate(small) / _F_SLOPE

        # From here on, only the zone's share of the real coil.
        sub = np.nonzero(live[idx])[0]
        if sub.size == 0:
            continue
        idx, Ta, Ts, m, Tr0, hr0, Q_needed, R_ref = (a[sub] for a in (idx, Ta, Ts, m, Tr0, hr0, Q_needed, R_ref))
        props = None if props is None else {k: v[sub] for k, v in props.items()}
        model = model.subset(sub)
        fr = f_rem[idx]
        Q_full = model.rate(fr)
        take_all = Q_full <= Q_needed
        f_z = np.where(take_all, fr, 0.0)
        if (~take_all).any():
            f_z = np.where(take_all, fr, _bisect(model.rate, Q_needed, fr))
        Q_z = np.where(take_all, Q_full, Q_needed)

        # Coldest (evaporator) or hottest (condenser) wall point of the zone: at the air inlet face.
        T_wall = Tr0 + (Ta - Tr0) * R_ref / model.R_tot
        T_surface_min[idx] = np.minimum(T_surface_min[idx], np.where(f_z > 0, T_wall, np.inf))

        if wet:
            # Moisture removed, from the effective surface state of the zone (Braun et
            # al. 1989, eqs. 25-28), for the air's heat rate at the zone's fraction: the
            # refrigerant's Q_z plus the condensate's enthalpy (``_ZoneHeatRate.rate``).
            m_w, T_s_eff, H_w = model.moisture.condensate(f_z, model.air_rate(f_z))
            condensing = m_w > 0
            m_cond[idx] += m_w
            cond_enthalpy[idx] += H_w
            latent[idx] += np.where(condensing, m_w * _latent_heat_water(T_s_eff), 0.0)
            T_surface_eff[idx] = np.minimum(T_surface_eff[idx], np.where(f_z > 0, T_s_eff, np.inf))

        # Frictional pressure drop over the zone length.
        L = f_z * geo.tube_length
        if two_phase:
            h_z_end = hr0 + sign * Q_z / m
            x0 = (hr0 - h_l[idx]) / (h_v[idx] - h_l[idx])
            x1 = (h_z_end - h_l[idx]) / (h_v[idx] - h_l[idx])
            grad = _two_phase_gradient(G[idx], geo.D_h, rough, {k: v[idx] for k, v in sat.items()}, x0, x1)
        else:
            grad = corr.single_phase_gradient(G[idx], geo.D_h, rough, props["MU"], props["D"])
        dp[idx] += grad * L

        Q[idx] += Q_z
        h_cur[idx] = hr0 + sign * Q_z / m
        T_cur[idx] = np.where(take_all, np.nan, Ts)
        f_rem[idx] = np.where(take_all, 0.0, fr - f_z)
        done[idx] |= take_all

    # --- outlet states -----------------------------------------------------
    h_out = h_in + sign * Q / mdot
    # Where the outlet stops short of the last zone (a two-phase evaporator outlet, a
    # condenser outlet not fully condensed), continue the last zone's outlet enthalpy
    # to the negative length 1 - f_needed with its zero-length slope: equal to h_out
    # in the last zone and C1-continuous at the phase boundary, so interpolation
    # across that boundary does not see the kink h_out has there.
    short = np.isfinite(last_zone_slope) & np.isfinite(f_needed)
    h_continued = h_out.copy()
    h_continued[short] = (entry_h[order[-1]] + sign * (1.0 - f_needed) * last_zone_slope / mdot)[short]
    p_out = p_in - dp
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
    Q_signed = -sign * Q  # > 0 when heat flows from refrigerant to air
    # Air leaving: refrigerant heat plus the enthalpy carried off by condensate.
    h_air_out = air["h"] + (Q_signed - cond_enthalpy) / m_da
    w_air_out = np.where(m_cond > 0, air["w"] - m_cond / m_da, air["w"])
    T_air_out = humid_air_temperature(h_air_out, w_air_out, env.p, w_common=air["w"])
    m_fog = np.zeros(n)
    if wet:
        # The zones' outlet streams mix; a mixture of nearly saturated streams can lie
        # beyond saturation (the curve is convex). Its excess water condenses.
        fog = _supersaturated(w_air_out, T_air_out, sat_air)
        if fog.any():
            dw, T_c = _condense_excess(h_air_out[fog], w_air_out[fog], sat_air)
            m_fog[fog] = m_da[fog] * dw
            m_cond[fog] += m_fog[fog]
            cond_enthalpy[fog] += m_fog[fog] * water_liquid_enthalpy(T_c)
            latent[fog] += m_fog[fog] * _latent_heat_water(T_c)
            h_air_out[fog] -= dw * water_liquid_enthalpy(T_c)  # the condensate leaves with its enthalpy
            w_air_out[fog] -= dw
            T_air_out[fog] = humid_air_temperature(h_air_out[fog], w_air_out[fog], env.p)
    bad_props |= ~np.isfinite(T_out + x_out + T_air_out)
    return {
        "Q": Q_signed,
        "Q_latent": -latent,
        "h_out": h_out,
        "p_out": p_out,
        "dp": dp,
        "T_out": T_out,
        "x_out": x_out,
        "T_air_out": T_air_out,
        "T_surface_min": T_surface_min,
        "T_surface_eff": T_surface_eff,
        "T_dew_air_in": air["T_dew"],
        "m_condensate": m_cond,
        "H_condensate": cond_enthalpy,
        "h_air_out": h_air_out,
        "m_dry_air": m_da,
        "w_air_out": w_air_out,
        "m_condensate_outlet": m_fog,
        "Re_Lp": Re_Lp,
        "air_outside_range": corr.chang_wang_outside_range(Re_Lp),
        "h_out_continued": h_continued,
        "capacity_ratio": np.where(
            f_needed > 1.0 / CAPACITY_RATIO_MAX, 1.0 / np.maximum(f_needed, 1e-300), CAPACITY_RATIO_MAX
        ),
        "bad_direction": bad_direction,
        "bad_dp": bad_dp,
        "bad_props": bad_props,
    }
