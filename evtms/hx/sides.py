"""Secondary streams of a refrigerant heat exchanger: liquid coolant, dry air, moist air.

The refrigerant-side zone marches see the other stream only through a small
protocol. The counter-flow core (:mod:`evtms.hx.counterflow`) takes a
:class:`SecondaryStream`: mass flow, inlet state, enthalpy-temperature
relation and resistance over the whole area; :class:`CoolantSide` is the
liquid water-glycol of a chiller. The cross-flow core
(:mod:`evtms.hx.crossflow`) takes a :class:`evtms.hx.crossflow.CrossflowSide`:
inlet temperature, capacity rate and resistance, the zone model it gives a
zone and what it records of a solved one; :class:`AirSide` is dry air
(sensible only: the condenser), :class:`MoistAirSide` air that may condense
on the coil (the evaporator).

Moist air: a zone at one refrigerant temperature (two-phase) is dry along
the air's path until its surface reaches the air's dew point and wet beyond
(the partly wet coil, :meth:`MoistAirSide.zone_model`); the wet part follows
the enthalpy-potential method of Threlkeld (1970) in the effectiveness-NTU
form of Braun, Klein and Mitchell (1989). Zones whose refrigerant warms or
cools are evaluated both dry and wet, and the air loses the larger heat rate,
Braun et al.'s rule for partly wet coils. The moisture condensed follows
from the effective surface state of the wet analysis; the condensate drains
off at that surface's temperature, so the refrigerant gains the air's loss
less the condensate's enthalpy. The zones' outlet streams mix; where the
mixture lies beyond saturation the excess water condenses and the air leaves
saturated, the energy balance kept (:func:`condense_excess`).

References
----------
ASHRAE (2017). Handbook - Fundamentals, ch. 1 (Psychrometrics).
Braun, J. E. (1988). Methodologies for the design and control of central
cooling plants. PhD thesis, University of Wisconsin-Madison.
Braun, J. E., Klein, S. A., Mitchell, J. W. (1989). Effectiveness models for
cooling towers and cooling coils. ASHRAE Trans. 95(2), 164-174.
Elmahdy, A. H., Mitalas, G. P. (1977). A simple model for cooling and
dehumidifying coils for use in calculating energy requirements for
buildings. ASHRAE Trans. 83(2), 103-117.
Threlkeld, J. L. (1970). Thermal Environmental Engineering, 2nd ed.,
Prentice-Hall, ch. 13.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from evtms.fluid import (
    Coolant,
    SaturatedAir,
    humid_air_temperature,
    water_liquid_enthalpy,
)
from evtms.hx.crossflow import ZoneHeatRate


class SecondaryStream(Protocol):
    """What the zone march needs to know of the secondary stream, per point.

    Attributes
    ----------
    mdot : numpy.ndarray
        Mass flow [kg/s], > 0.
    T_in : numpy.ndarray
        Inlet temperature [K].
    h_in : numpy.ndarray
        Inlet specific enthalpy [J/kg].
    R : numpy.ndarray
        Thermal resistance of this side over the whole exchanger area
        (convection and fouling) [K/W].
    """

    mdot: np.ndarray
    T_in: np.ndarray
    h_in: np.ndarray
    R: np.ndarray

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] at specific enthalpy ``h`` [J/kg]."""
        ...

    def capacity_rate(self) -> np.ndarray:
        """Heat capacity rate at the inlet, ``mdot c_p`` [W/K]."""
        ...


@dataclass
class CoolantSide:
    """A liquid coolant stream (water-glycol) through the exchanger.

    It serves both cores: the counter-flow one (:class:`SecondaryStream`:
    ``mdot``, ``h_in``, :meth:`temperature`) and the cross-flow one
    (:class:`evtms.hx.crossflow.CrossflowSide`: ``C``, :meth:`zone_model`,
    :meth:`account`), with a constant heat capacity at the inlet there.

    Attributes
    ----------
    coolant : Coolant
        Property tables of the coolant.
    mdot : numpy.ndarray
        Coolant mass flow [kg/s].
    T_in : numpy.ndarray
        Coolant inlet temperature [K].
    R : numpy.ndarray
        Coolant-side resistance over the whole area [K/W].
    """

    coolant: Coolant
    mdot: np.ndarray
    T_in: np.ndarray
    R: np.ndarray

    @property
    def h_in(self) -> np.ndarray:
        """Inlet specific enthalpy [J/kg]."""
        return self.coolant.enthalpy(self.T_in)

    @property
    def C(self) -> np.ndarray:
        """Capacity rate at the inlet, ``mdot c_p(T_in)`` [W/K]."""
        return self.capacity_rate()

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] at specific enthalpy ``h`` [J/kg] (the coolant's table, exact inverse of its enthalpy)."""
        return self.coolant.temperature(h)

    def temperature_table(self) -> tuple[np.ndarray, np.ndarray]:
        """The table :meth:`temperature` interpolates linearly: enthalpies [J/kg], temperatures [K].

        The counter-flow core's compiled heat-rate search reads it.
        """
        return self.coolant.h, self.coolant.T

    def capacity_rate(self) -> np.ndarray:
        """``mdot c_p(T_in)`` [W/K]."""
        return self.mdot * self.coolant.properties(self.T_in)["CP"]

    def zone_model(self, idx: np.ndarray, C_ref: np.ndarray, R_ref: np.ndarray, Tr0: np.ndarray) -> ZoneHeatRate:
        """Cross-flow zone model of points ``idx`` (sensible, constant heat capacity)."""
        return ZoneHeatRate(C_ref=C_ref, R_tot=self.R[idx] + R_ref, C_air=self.C[idx], dT=np.abs(self.T_in[idx] - Tr0))

    def account(self, idx: np.ndarray, model: ZoneHeatRate, f: np.ndarray) -> None:
        """A liquid keeps nothing of a zone."""


def latent_heat_water(T: np.ndarray) -> np.ndarray:
    """Latent heat of condensation of water [J/kg] at ``T`` [K] (ASHRAE Fundamentals' linear fit)."""
    return 2.501e6 - 2369.0 * (T - 273.15)


#: Highest outlet degree of saturation ``w / w_sat(T)`` [1] of the wet coil: saturation
#: less a margin above the saturated-air tables' error (about 1e-6, ``evtms.fluid``), so
#: no outlet reads supersaturated against ``HAPropsSI``.
OUTLET_SATURATION_MAX = 1.0 - 1e-5
#: Fixed-point steps for the outlet state after condensing; each gains a factor of about 100.
_FOG_STEPS = 6


def supersaturated(w: np.ndarray, T: np.ndarray, sat_air: SaturatedAir) -> np.ndarray:
    """Points whose humidity ratio ``w`` [kg/kg] exceeds :data:`OUTLET_SATURATION_MAX` of saturation at ``T`` [K]."""
    with np.errstate(invalid="ignore"):
        return w > OUTLET_SATURATION_MAX * sat_air.humidity_ratio(T)


def condense_excess(h: np.ndarray, w: np.ndarray, sat_air: SaturatedAir) -> tuple[np.ndarray, np.ndarray]:
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


@dataclass
class Moisture:
    """Moisture removed by one zone, from its effective surface state (Braun et al. 1989, eqs. 25-28).

    Attributes
    ----------
    air_h, air_w : numpy.ndarray
        Entering air's enthalpy [J/kg dry air] and humidity ratio [kg/kg dry air].
    m_air : numpy.ndarray
        Dry-air flow through the whole coil [kg/s].
    decay : numpy.ndarray
        ``exp(-NTU_o)`` [1] over the wet part of the air's path, with the
        air-side number of transfer units ``NTU_o = 1 / (R_air C_air)`` over
        the whole path (the same for every zone).
    sat_air : SaturatedAir
        Saturated-air curve at the air pressure.
    wet_h : numpy.ndarray
        Enthalpy [J/kg dry air] of the air where the wet part begins: ``air_h``
        unless the zone is dry over the first part of the path.
    wets : numpy.ndarray
        1 where the zone may condense, 0 where its whole surface stays above the
        dew point (partly wet zones, :meth:`MoistAirSide.zone_model`).
    """

    air_h: np.ndarray
    air_w: np.ndarray
    m_air: np.ndarray
    decay: np.ndarray
    sat_air: SaturatedAir
    wet_h: np.ndarray
    wets: np.ndarray

    def subset(self, sub: np.ndarray) -> Moisture:
        return Moisture(
            self.air_h[sub],
            self.air_w[sub],
            self.m_air[sub],
            self.decay[sub],
            self.sat_air,
            self.wet_h[sub],
            self.wets[sub],
        )

    def condensate(self, f: np.ndarray, q_air: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Condensate [kg/s], effective surface temperature [K] and condensate enthalpy flow [W].

        For a zone of coil fraction ``f`` whose air loses ``q_air`` [W]: the
        air leaves at ``h_a,out = h_a,in - q_air / (f m_a)``; over the wet
        part of its path, entered at ``h_a,w`` (:attr:`wet_h`), the effective
        surface lies at ``h_s,eff = h_a,w - (h_a,w - h_a,out) / (1 -
        exp(-NTU_o))``, saturated at ``T_s,eff``; the air leaves at ``w_out =
        w_s,eff + (w_in - w_s,eff) exp(-NTU_o)`` (``NTU_o`` of that part);
        the zone is wet where that lies below ``w_in`` (the effective surface
        below the entering dew point) and the condensate leaves at ``T_s,eff``.
        """
        sat = self.sat_air
        with np.errstate(divide="ignore", invalid="ignore"):
            h_a_out = self.air_h - q_air / np.where(f > 0, f * self.m_air, 1.0)
            h_s_eff = self.wet_h - (self.wet_h - h_a_out) / (1.0 - self.decay)
        T_s_eff = sat.temperature(h_s_eff)
        w_s_eff = sat.humidity_ratio(T_s_eff)
        w_out = w_s_eff + (self.air_w - w_s_eff) * self.decay
        m_w = np.where((f > 0) & (self.wets > 0), f * self.m_air * np.maximum(self.air_w - w_out, 0.0), 0.0)
        H_w = np.where(m_w > 0, m_w * water_liquid_enthalpy(T_s_eff), 0.0)
        return m_w, T_s_eff, H_w


@dataclass
class AirSide:
    """Air crossing a coil without condensing (sensible heat only): the condenser's.

    Attributes
    ----------
    T_in : numpy.ndarray
        Entering-air temperature [K].
    air : dict of str to numpy.ndarray
        Entering moist-air state per point (:func:`evtms.fluid.humid_air_inlet`
        keys: ``w``, ``h``, ``cp``, ...).
    m_da : numpy.ndarray
        Dry-air mass flow [kg/s].
    C : numpy.ndarray
        Capacity rate ``m_da cp`` [W/K].
    R : numpy.ndarray
        Air-side resistance (fins, convection, fouling) over the coil [K/W].
    p : float
        Air pressure [Pa].
    """

    T_in: np.ndarray
    air: dict[str, np.ndarray]
    m_da: np.ndarray
    C: np.ndarray
    R: np.ndarray
    p: float

    def __post_init__(self) -> None:
        n = self.T_in.size
        #: Condensate [kg/s], its enthalpy flow [W] and latent heat [W]; coldest effective surface [K].
        self.m_cond = np.zeros(n)
        self.cond_enthalpy = np.zeros(n)
        self.latent = np.zeros(n)
        self.T_surface_eff = np.full(n, np.inf)

    def zone_model(self, idx: np.ndarray, C_ref: np.ndarray, R_ref: np.ndarray, Tr0: np.ndarray) -> ZoneHeatRate:
        """Sensible cross-flow zone model of points ``idx``."""
        return ZoneHeatRate(C_ref=C_ref, R_tot=self.R[idx] + R_ref, C_air=self.C[idx], dT=np.abs(self.T_in[idx] - Tr0))

    def account(self, idx: np.ndarray, model: ZoneHeatRate, f: np.ndarray) -> None:
        """Dry air keeps nothing of a zone."""

    def outlet(self, Q_signed: np.ndarray) -> dict[str, np.ndarray]:
        """Leaving air, given the heat ``Q_signed`` [W] from the refrigerant to the air.

        Returns ``h_air_out`` [J/kg dry air], ``w_air_out`` [kg/kg dry air],
        ``T_air_out`` [K] and ``m_condensate_outlet`` (condensed where the
        zones' outlet streams mix, kg/s).
        """
        air, m_da = self.air, self.m_da
        # Air leaving: refrigerant heat plus the enthalpy carried off by condensate.
        h_air_out = air["h"] + (Q_signed - self.cond_enthalpy) / m_da
        w_air_out = np.where(self.m_cond > 0, air["w"] - self.m_cond / m_da, air["w"])
        T_air_out = humid_air_temperature(h_air_out, w_air_out, self.p, w_common=air["w"])
        return {
            "h_air_out": h_air_out,
            "w_air_out": w_air_out,
            "T_air_out": T_air_out,
            "m_condensate_outlet": np.zeros(self.T_in.size),
        }


@dataclass
class MoistAirSide(AirSide):
    """Air that may condense on the coil: the evaporator's (wet-coil enthalpy potential, condensate).

    Attributes
    ----------
    sat_air : SaturatedAir
        Saturated-air curve at the air pressure (besides :class:`AirSide`'s).
    """

    sat_air: SaturatedAir | None = None

    def zone_model(self, idx: np.ndarray, C_ref: np.ndarray, R_ref: np.ndarray, Tr0: np.ndarray) -> ZoneHeatRate:
        r"""The dry model with its wet twin (Braun et al. 1989) and the zone's moisture bookkeeping.

        A zone at one refrigerant temperature ``T_r`` (two-phase: ``C_ref``
        infinite) is partly wet: along the air's path through the coil the
        air cools as ``T_a - T_r = (T_a,in - T_r) exp(-NTU x)`` (``NTU = 1 /
        (R_tot C_air)``, ``x`` the fraction of the path) and the surface lies
        at ``T_s - T_r = (T_a - T_r) R_ref / R_tot``; it is dry up to the
        depth ``x_d`` where ``T_s`` falls to the entering air's dew point and
        wet beyond (Elmahdy and Mitalas 1977; Braun 1988, the
        partially wet coil). The zone's rate is the dry analysis over ``x_d``
        plus the wet one over ``1 - x_d`` from the air state at the boundary,
        with the saturated-air slope ``c_s`` the secant between ``T_r`` and the
        dew point, the wet surface's temperature range: the two analyses' heat
        fluxes are then equal at the boundary, so the rate changes smoothly as
        the air's humidity moves the boundary through the coil (the larger of
        the two rates has a corner there, which a LUT interpolates poorly).
        Zones whose refrigerant temperature changes (vapour, liquid) keep the
        larger-rate rule with ``c_s`` the secant to the entering air temperature.

        References
        ----------
        Braun, J. E. (1988). Methodologies for the design and control of central
        cooling plants. PhD thesis, University of Wisconsin-Madison.
        Elmahdy, A. H., Mitalas, G. P. (1977). A simple model for cooling and
        dehumidifying coils for use in calculating energy requirements for
        buildings. ASHRAE Trans. 83(2), 103-117.
        """
        model = super().zone_model(idx, C_ref, R_ref, Tr0)
        air, sat_air, Ta = self.air, self.sat_air, self.T_in[idx]
        h_a, w_a, m_da, C_a = air["h"][idx], air["w"][idx], self.m_da[idx], self.C[idx]
        ntu_air = 1.0 / (self.R[idx] * C_a)
        h_s_r = sat_air.enthalpy(Tr0)
        partly = np.isinf(C_ref)
        T_dew = sat_air.dew_point(w_a)
        # Secant of h_sat(T) from T_r to the entering air (Braun et al. 1989), or to the
        # dew point (at least one table step above T_r) for a partly wet zone.
        T_top = np.where(partly, np.maximum(T_dew, Tr0 + 0.05), Ta)
        c_s = (sat_air.enthalpy(T_top) - h_s_r) / np.maximum(T_top - Tr0, 1e-9)
        # Dry depth: where the surface reaches the dew point (1: dry, 0: wet from the face).
        dT = model.dT
        with np.errstate(divide="ignore", invalid="ignore"):
            at_dew = (T_dew - Tr0) * model.R_tot / R_ref  # air-refrigerant difference there [K]
            depth = np.log(dT / at_dew) * model.R_tot * C_a
        depth = np.where(at_dew <= 0.0, 1.0, np.where(at_dew >= dT, 0.0, np.minimum(depth, 1.0)))
        depth = np.where(partly, depth, np.nan)
        dry_part = np.where(partly, 1.0 - np.exp(-depth / (model.R_tot * C_a)), 0.0)
        wet_h = h_a - C_a / m_da * dT * dry_part  # air entering the wet part
        # Only zones at one refrigerant temperature carry a dry depth; where none do, the
        # model skips the partly wet analysis (the single-phase zones' bisection).
        model.dry_depth = depth if partly.any() else None
        model.wet = ZoneHeatRate(
            C_ref=C_ref / c_s,
            R_tot=air["cp"][idx] * self.R[idx] + c_s * R_ref,  # (J/kg)/W
            C_air=m_da,
            dT=np.maximum(wet_h - h_s_r, 0.0),
        )
        # A wet part thinner than 1e-9 of the coil drains nothing measurable, and its decay
        # would round to 1 (0/0 in the effective surface state).
        wets = ~partly | (depth < 1.0 - 1e-9)
        after_dry = partly & wets
        model.moisture = Moisture(
            air_h=h_a,
            air_w=w_a,
            m_air=m_da,
            decay=np.exp(-ntu_air * np.where(after_dry, 1.0 - depth, 1.0)),
            sat_air=sat_air,
            wet_h=np.where(after_dry, wet_h, h_a),
            wets=wets.astype(float),
        )
        return model

    def account(self, idx: np.ndarray, model: ZoneHeatRate, f: np.ndarray) -> None:
        """Moisture removed, from the effective surface state of the zone (Braun et al. 1989, eqs. 25-28).

        For the air's heat rate at the zone's fraction: the refrigerant's
        share plus the condensate's enthalpy (:meth:`ZoneHeatRate.rate`).
        """
        m_w, T_s_eff, H_w = model.moisture.condensate(f, model.air_rate(f))
        condensing = m_w > 0
        self.m_cond[idx] += m_w
        self.cond_enthalpy[idx] += H_w
        self.latent[idx] += np.where(condensing, m_w * latent_heat_water(T_s_eff), 0.0)
        self.T_surface_eff[idx] = np.minimum(self.T_surface_eff[idx], np.where(f > 0, T_s_eff, np.inf))

    def outlet(self, Q_signed: np.ndarray) -> dict[str, np.ndarray]:
        """Leaving air as :meth:`AirSide.outlet`, never supersaturated.

        The zones' outlet streams mix; a mixture of nearly saturated streams
        can lie beyond saturation (the curve is convex). Its excess water
        condenses (:func:`condense_excess`), and the condensate counters
        (``m_cond``, ``cond_enthalpy``, ``latent``) include it.
        """
        out = super().outlet(Q_signed)
        h_air_out, w_air_out, T_air_out = out["h_air_out"], out["w_air_out"], out["T_air_out"]
        m_fog = out["m_condensate_outlet"]
        sat_air, m_da = self.sat_air, self.m_da
        fog = supersaturated(w_air_out, T_air_out, sat_air)
        if fog.any():
            dw, T_c = condense_excess(h_air_out[fog], w_air_out[fog], sat_air)
            m_fog[fog] = m_da[fog] * dw
            self.m_cond[fog] += m_fog[fog]
            self.cond_enthalpy[fog] += m_fog[fog] * water_liquid_enthalpy(T_c)
            self.latent[fog] += m_fog[fog] * latent_heat_water(T_c)
            h_air_out[fog] -= dw * water_liquid_enthalpy(T_c)  # the condensate leaves with its enthalpy
            w_air_out[fog] -= dw
            T_air_out[fog] = humid_air_temperature(h_air_out[fog], w_air_out[fog], self.p)
        return out
