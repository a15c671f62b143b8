"""Cross-flow moving-boundary core: refrigerant zones in series, the secondary stream across them in parallel.

Along the tubes the refrigerant passes through up to three zones (vapour,
two-phase, liquid; in the order its enthalpy moves). Each zone covers a
fraction ``f`` of the tube length and so of the face area and of the
secondary flow (air crossing the coil); it is an effectiveness-NTU exchanger
of ``f`` times the coil's conductance, both streams unmixed (Incropera et al.
2007, eq. 11.32). The fractions follow from the zone heat loads, solved by
bisection: the moving-boundary method of Simscape's two-phase heat
exchangers (MathWorks 2024) in steady state.

Single-phase zones use a secant heat capacity of the refrigerant over the
zone's temperature span (to its phase boundary, or to the secondary inlet
temperature for the last zone), so no zone can move more heat than the
second law allows.

The refrigerant side is a :class:`TubeSide` (channel geometry and its
correlations); the secondary side is an object with the small protocol of
:class:`CrossflowSide`: its inlet temperature ``T_in``, capacity rate ``C``
and resistance ``R`` per point, the zone model it gives a zone
(:meth:`CrossflowSide.zone_model`, where moist air adds its wet-coil
analysis) and what it records of a solved zone (:meth:`CrossflowSide.account`,
where moist air counts its condensate). :mod:`evtms.hx.sides` has the dry
and moist air sides.

References
----------
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th ed.
MathWorks (2024). Condenser Evaporator (2P-MA), Simscape Fluids reference.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from evtms._jit import numba_enabled
from evtms.fluid import Fluid
from evtms.hx import tube
from evtms.hx.effectiveness import crossflow_effectiveness

#: Halvings of a zone-fraction bracket: 2^-40 of it, 1e-12 of the coil for a zone's share and 1e-9
#: for the fraction needed to finish a phase change (searched up to _F_SEARCH_MAX coils), far
#: below the cycle's closure tolerances (1e-6); 60 (to round-off) cost the sweeps 12 % more time.
_BISECTION_STEPS = 40
#: Largest coil fraction searched for the fraction needed to finish a phase change.
_F_SEARCH_MAX = 1e3
#: Coil fraction at which a zone's heat rate gives its slope at zero length [1].
_F_SLOPE = 1e-6
#: Cap of the capacity ratio (coil fraction available over needed), for finite LUT values.
CAPACITY_RATIO_MAX = 1e3


#: Whether the zone searches run per point in machine code (:func:`per_point_searches`).
_PER_POINT = contextvars.ContextVar("evtms_hx_per_point", default=False)


@contextlib.contextmanager
def per_point_searches() -> Iterator[None]:
    """Within this block the cross-flow core's zone searches run per point, compiled.

    That is 2-3x faster on the few points of a cycle solver's call (a one-point
    evaporator call 6.3 -> 2.8 ms), and about 15 % slower on a sweep's thousands,
    where NumPy's vectorised exp and pow win. A sweep's values must not depend on
    its batch, so the caller chooses (the cycle's direct models do), not the batch
    size. The counter-flow core's compiled search is faster at every size and
    always on.
    """
    token = _PER_POINT.set(True)
    try:
        yield
    finally:
        _PER_POINT.reset(token)


def gauss_mean(values: np.ndarray) -> np.ndarray:
    """Gauss-Legendre mean over the last axis, row by row.

    Written as a sum rather than a BLAS product, whose rounding depends on how
    many rows it is given: a point's value must not depend on its batch (the
    chunked sweeps give identical files in every mode).
    """
    return np.sum(values * tube.GAUSS_WEIGHTS, axis=-1)


def bisect(func: Callable[[np.ndarray], np.ndarray], target: np.ndarray, hi: np.ndarray, steps: int = _BISECTION_STEPS):
    """Vectorised bisection for ``func(f) = target`` on [0, hi]; func increasing in f."""
    lo = np.zeros_like(hi)
    hi = hi.copy()
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        below = func(mid) < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


@dataclass
class ZoneHeatRate:
    """Heat rate [W] of one zone as a function of its coil fraction f (effectiveness-NTU).

    Cross flow, both streams unmixed; the secondary stream through the zone
    is ``f C_air`` and its conductance ``f / R_tot``. ``wet`` holds the same
    model in enthalpy-potential form (capacities in kg/s, potential in J/kg);
    the air then loses the larger of the two (Braun et al. 1989) or, where
    ``dry_depth`` is given (a zone at one refrigerant temperature), the sum
    of the dry analysis over that fraction of the air's path through the coil
    and the wet one over the rest (the partly wet coil,
    :meth:`evtms.hx.sides.MoistAirSide.zone_model`); the
    refrigerant gains that less the enthalpy of the condensate draining off
    the coil (``moisture``, :class:`evtms.hx.sides.Moisture`): the air's
    enthalpy cannot fall below that of saturated air at the refrigerant
    temperature, so neither can the air leaving cross the refrigerant's
    temperature (Braun et al.'s model, which neglects the condensate's
    enthalpy, gives the refrigerant that too and let the air leave up to
    0.25 K colder than the refrigerant at blower 0.1).
    """

    C_ref: np.ndarray
    R_tot: np.ndarray
    C_air: np.ndarray
    dT: np.ndarray
    wet: ZoneHeatRate | None = None
    moisture: Any = None
    #: Fraction [1] of the air's path that is dry, per point (NaN: the larger-rate rule).
    dry_depth: np.ndarray | None = None

    def dry(self, f: np.ndarray) -> np.ndarray:
        C_af = f * self.C_air
        C_min = np.minimum(C_af, self.C_ref)
        C_max = np.maximum(C_af, self.C_ref)
        with np.errstate(divide="ignore", invalid="ignore"):
            ntu = np.where(C_min > 0, f / self.R_tot / np.where(C_min > 0, C_min, 1.0), 0.0)
            cr = np.where(np.isfinite(C_max) & (C_max > 0), C_min / np.where(C_max > 0, C_max, 1.0), 0.0)
            # NaN inputs (points already flagged invalid) stay NaN here, silently.
            return crossflow_effectiveness(ntu, cr) * C_min * self.dT

    def air_rate(self, f: np.ndarray) -> np.ndarray:
        """Heat rate the secondary stream loses [W]: the larger of the dry and wet analyses,
        or the dry part's and the wet part's together where :attr:`dry_depth` is set."""
        if self.wet is None:
            return self.dry(f)
        x = self.dry_depth
        if x is None:
            return np.maximum(self.dry(f), self.wet.dry(f))
        with np.errstate(divide="ignore", invalid="ignore"):
            parts = self.over_depth(x).dry(f) + self.wet.over_depth(1.0 - x).dry(f)
        larger = np.isnan(x)
        if larger.any():
            parts = np.where(larger, np.maximum(self.dry(f), self.wet.dry(f)), parts)
        return parts

    def over_depth(self, depth: np.ndarray) -> ZoneHeatRate:
        """The same zone over a fraction ``depth`` of the air's path: its conductance times ``depth``."""
        return ZoneHeatRate(self.C_ref, self.R_tot / depth, self.C_air, self.dT)

    def rate(self, f: np.ndarray) -> np.ndarray:
        """Heat rate the refrigerant gains [W]: :meth:`air_rate` less the condensate's enthalpy."""
        q = self.air_rate(f)
        if self.moisture is None:
            return q
        H_w = self.moisture.condensate(f, q)[2]
        return q - np.where(np.isfinite(H_w), H_w, 0.0)  # a NaN surface state flags the point later

    def fraction_for(self, target: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Coil fraction in ``[0, hi]`` at which :meth:`rate` is ``target`` [W], by :func:`bisect`.

        Within :func:`per_point_searches` (and with numba) the bisection runs per point
        in machine code (:func:`evtms.hx._kernels.bisect_zone_fraction`, the same
        arithmetic): on the few points of a cycle solver's call NumPy's per-call
        overhead dominates it.
        """
        if not (_PER_POINT.get() and numba_enabled()):
            return bisect(self.rate, target, hi)
        from evtms.hx import _kernels

        n = target.size
        dry = _kernels.columns(n, self.C_ref, self.R_tot, self.C_air, self.dT)
        w = self.wet
        depth = np.nan if self.dry_depth is None else self.dry_depth
        wet = np.full((n, 5), np.nan) if w is None else _kernels.columns(n, w.C_ref, w.R_tot, w.C_air, w.dT, depth)
        if self.moisture is None:
            moist, tables = np.full((n, 6), np.nan), (np.zeros(2), np.zeros(2), np.zeros(2))
        else:
            m = self.moisture
            moist = _kernels.columns(n, m.air_h, m.air_w, m.m_air, m.decay, m.wet_h, m.wets)
            tables = (m.sat_air.T, m.sat_air.h, m.sat_air.w)
        return _kernels.bisect_zone_fraction(
            np.ascontiguousarray(target, float),
            np.ascontiguousarray(hi, float),
            dry,
            wet,
            moist,
            *(np.ascontiguousarray(t, float) for t in tables),
            _BISECTION_STEPS,
        )

    def subset(self, sub: np.ndarray) -> ZoneHeatRate:
        return ZoneHeatRate(
            self.C_ref[sub],
            self.R_tot[sub],
            self.C_air[sub],
            self.dT[sub],
            None if self.wet is None else self.wet.subset(sub),
            None if self.moisture is None else self.moisture.subset(sub),
            None if self.dry_depth is None else self.dry_depth[sub],
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
            f[ok] = self.subset(sub).fraction_for(Q_needed[ok], big[ok])
        return f


class CrossflowSide(Protocol):
    """The secondary stream of a cross-flow coil, as the zone march sees it.

    Attributes
    ----------
    T_in : numpy.ndarray
        Entering temperature [K] per point.
    C : numpy.ndarray
        Capacity rate of the whole stream [W/K].
    R : numpy.ndarray
        Its resistance (convection, fins, fouling) over the whole coil [K/W].
    """

    T_in: np.ndarray
    C: np.ndarray
    R: np.ndarray

    def zone_model(self, idx: np.ndarray, C_ref: np.ndarray, R_ref: np.ndarray, Tr0: np.ndarray) -> ZoneHeatRate:
        """The zone model of points ``idx`` against refrigerant of capacity ``C_ref`` entering at ``Tr0``."""
        ...

    def account(self, idx: np.ndarray, model: ZoneHeatRate, f: np.ndarray) -> None:
        """Record what the stream takes from a solved zone of fraction ``f`` (e.g. condensate)."""
        ...


@dataclass
class TubeSide:
    """Refrigerant in flat multiport tubes, all in parallel.

    Attributes
    ----------
    D_h : float
        Channel hydraulic diameter [m].
    flow_area : float
        Flow cross-section of all channels [m2].
    length : float
        Refrigerant path length [m].
    area : float
        Refrigerant-side area [m2].
    roughness : float
        Relative roughness [1].
    nu_laminar : float
        Laminar Nusselt number [1].
    R_wall : float
        Wall plus refrigerant-side fouling resistance [K/W].
    """

    D_h: float
    flow_area: float
    length: float
    area: float
    roughness: float
    nu_laminar: float
    R_wall: float

    def single_phase_htc(self, G: np.ndarray, props: dict[str, np.ndarray]) -> np.ndarray:
        """Single-phase coefficient [W/(m2 K)]: Gnielinski with Haaland friction, laminar floor."""
        Re = G * self.D_h / props["MU"]
        Pr = props["CP"] * props["MU"] / props["K"]
        f = tube.haaland_friction_factor(Re, self.roughness)
        return tube.single_phase_nusselt(Re, Pr, f, self.nu_laminar) * props["K"] / self.D_h

    def condensation_htc(self, G: np.ndarray, sat: dict[str, np.ndarray], q: np.ndarray) -> np.ndarray:
        """Condensation coefficient [W/(m2 K)] averaged over quality 0..1 (Gauss-Legendre).

        The larger of the shear-driven (Cavallini-Zecchin) and the gravity-driven
        film (Chato) coefficients at heat flux ``q``.
        """
        D, nu_lam = self.D_h, self.nu_laminar
        x = tube.GAUSS_NODES[None, :]
        col = {k: v[:, None] for k, v in sat.items()}
        Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
        nu = tube.cavallini_zecchin_nusselt(
            x, G[:, None], D, col["mu_l"], col["mu_v"], col["rho_l"], col["rho_v"], Pr_l, nu_lam
        )
        shear = gauss_mean(nu) * sat["k_l"] / D
        film = tube.chato_film_condensation_htc(
            q, D, sat["rho_l"], sat["rho_v"], sat["k_l"], sat["mu_l"], sat["cp_l"], sat["h_v"] - sat["h_l"]
        )
        return np.maximum(shear, film)

    def boiling_htc(self, G: np.ndarray, sat: dict[str, np.ndarray], q: np.ndarray) -> np.ndarray:
        """Flow-boiling coefficient [W/(m2 K)] averaged over quality 0..1 at heat flux ``q`` (Gungor-Winterton)."""
        x = tube.GAUSS_NODES[None, :]
        col = {k: v[:, None] for k, v in sat.items()}
        Pr_l = col["cp_l"] * col["mu_l"] / col["k_l"]
        h = tube.gungor_winterton_htc(
            x,
            G[:, None],
            self.D_h,
            q[:, None],
            col["h_v"] - col["h_l"],
            col["mu_l"],
            col["rho_l"],
            col["rho_v"],
            col["k_l"],
            Pr_l,
            self.nu_laminar,
        )
        return gauss_mean(h)

    def two_phase_gradient(self, G, sat, x0, x1):
        """Mean two-phase frictional gradient [Pa/m] over quality x0..x1 (Mueller-Steinhagen and Heck)."""
        x = x0[:, None] + (x1 - x0)[:, None] * tube.GAUSS_NODES[None, :]
        col = {k: v[:, None] for k, v in sat.items()}
        g = tube.muller_steinhagen_heck_gradient(
            np.clip(x, 0.0, 1.0),
            G[:, None],
            self.D_h,
            self.roughness,
            col["mu_l"],
            col["mu_v"],
            col["rho_l"],
            col["rho_v"],
        )
        return gauss_mean(g)


@dataclass
class CrossflowResult:
    """What :func:`march_crossflow` returns, per point.

    Attributes
    ----------
    Q : numpy.ndarray
        Magnitude of the refrigerant's heat rate [W] (>= 0).
    dp : numpy.ndarray
        Frictional pressure drop [Pa].
    h_out, h_out_continued : numpy.ndarray
        Outlet enthalpy, and its continuation past the phase boundary [J/kg].
    capacity_ratio : numpy.ndarray
        Coil over the fraction needed to finish the phase change [1].
    T_surface_min : numpy.ndarray
        Coldest (evaporating) or hottest wall point [K].
    bad_direction, bad_props : numpy.ndarray
        Masks: the secondary stream cannot take or give heat in the required
        direction; a property evaluation failed.
    """

    Q: np.ndarray
    dp: np.ndarray
    h_out: np.ndarray
    h_out_continued: np.ndarray
    capacity_ratio: np.ndarray
    T_surface_min: np.ndarray
    bad_direction: np.ndarray
    bad_props: np.ndarray


def march_crossflow(
    fluid: Fluid,
    tubes: TubeSide,
    side: CrossflowSide,
    p_in: np.ndarray,
    h_in: np.ndarray,
    mdot: np.ndarray,
    mode: str,
) -> CrossflowResult:
    """Solve the refrigerant's zones against a cross-flow secondary stream.

    Parameters
    ----------
    fluid : Fluid
        Refrigerant properties.
    tubes : TubeSide
        Refrigerant channels and their correlations.
    side : CrossflowSide
        The secondary stream (dry or moist air).
    p_in, h_in, mdot : numpy.ndarray
        Refrigerant inlet pressure [Pa], enthalpy [J/kg] and mass flow [kg/s].
    mode : {"condenser", "evaporator"}
        Direction of the refrigerant's enthalpy change.

    Returns
    -------
    CrossflowResult
        Heat rate, pressure drop, outlet enthalpies and the closure variables.
    """
    sign = -1.0 if mode == "condenser" else 1.0  # direction of the refrigerant's enthalpy change
    n = p_in.size
    T_air, C_air, R_air = side.T_in, side.C, side.R
    R_wall_ref = tubes.R_wall

    # --- refrigerant states ------------------------------------------------
    sat = fluid.saturation(p_in)
    T_sat, h_l, h_v = sat["T"], sat["h_l"], sat["h_v"]
    T_in = fluid.state("PH", p_in, h_in, ("T",))["T"]
    h_air_T = fluid.state("PT", p_in, T_air, ("H",))["H"]  # refrigerant at the secondary temperature
    G = mdot / tubes.flow_area
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
    two_phase_htc = tubes.condensation_htc if mode == "condenser" else tubes.boiling_htc
    q = np.full(n, 1000.0)
    for _ in range(5):
        h_tp = two_phase_htc(G, sat, q)
        UA = 1.0 / (R_air + R_wall_ref + 1.0 / (h_tp * tubes.area))
        q = np.maximum(C_air * -np.expm1(-UA / C_air) * np.abs(T_air - T_sat) / tubes.area, 1.0)

    # --- march through the zones -----------------------------------------
    f_rem = np.ones(n)
    done = bad_props | bad_direction
    Q = np.zeros(n)
    dp = np.zeros(n)
    T_surface_min = np.full(n, np.inf)
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
            h_ref = tubes.single_phase_htc(G[idx], props)
            span = T_end - Tr0
            cp_eff = np.where(np.abs(span) > 1e-9, (h_end - hr0) / np.where(span == 0, 1.0, span), props["CP"])
            C_ref = m * cp_eff
        R_ref = R_wall_ref + 1.0 / (h_ref * tubes.area)
        model = side.zone_model(idx, C_ref, R_ref, Tr0)
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
            f_z = np.where(take_all, fr, model.fraction_for(Q_needed, fr))
        Q_z = np.where(take_all, Q_full, Q_needed)

        # Coldest (evaporator) or hottest (condenser) wall point of the zone: at the air inlet face.
        T_wall = Tr0 + (Ta - Tr0) * R_ref / model.R_tot
        T_surface_min[idx] = np.minimum(T_surface_min[idx], np.where(f_z > 0, T_wall, np.inf))
        side.account(idx, model, f_z)

        # Frictional pressure drop over the zone length.
        L = f_z * tubes.length
        if two_phase:
            h_z_end = hr0 + sign * Q_z / m
            x0 = (hr0 - h_l[idx]) / (h_v[idx] - h_l[idx])
            x1 = (h_z_end - h_l[idx]) / (h_v[idx] - h_l[idx])
            grad = tubes.two_phase_gradient(G[idx], {k: v[idx] for k, v in sat.items()}, x0, x1)
        else:
            grad = tube.single_phase_gradient(G[idx], tubes.D_h, tubes.roughness, props["MU"], props["D"])
        dp[idx] += grad * L

        Q[idx] += Q_z
        f_rem[idx] = np.where(take_all, 0.0, fr - f_z)
        done[idx] |= take_all

    # --- outlet enthalpy and the closure variables ---------------------------
    h_out = h_in + sign * Q / mdot
    # Where the outlet stops short of the last zone (a two-phase evaporator outlet, a
    # condenser outlet not fully condensed), continue the last zone's outlet enthalpy
    # to the negative length 1 - f_needed with its zero-length slope: equal to h_out
    # in the last zone and C1-continuous at the phase boundary, so interpolation
    # across that boundary does not see the kink h_out has there.
    short = np.isfinite(last_zone_slope) & np.isfinite(f_needed)
    h_continued = h_out.copy()
    h_continued[short] = (entry_h[order[-1]] + sign * (1.0 - f_needed) * last_zone_slope / mdot)[short]
    capacity_ratio = np.where(
        f_needed > 1.0 / CAPACITY_RATIO_MAX, 1.0 / np.maximum(f_needed, 1e-300), CAPACITY_RATIO_MAX
    )
    return CrossflowResult(
        Q=Q,
        dp=dp,
        h_out=h_out,
        h_out_continued=h_continued,
        capacity_ratio=capacity_ratio,
        T_surface_min=T_surface_min,
        bad_direction=bad_direction,
        bad_props=bad_props,
    )
