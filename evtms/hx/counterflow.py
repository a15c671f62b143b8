"""Counter-flow moving-boundary core: an evaporating refrigerant against a single-phase secondary stream.

The refrigerant passes up to three zones in the order its enthalpy rises
(subcooled liquid, two-phase, superheated vapour); the secondary stream
(:class:`evtms.hx.sides.SecondaryStream`, e.g. the coolant of a chiller)
flows the other way through the same channels, so it meets the refrigerant
outlet first and every zone sees the whole secondary flow, in series. For a
trial heat rate ``Q`` the zone boundaries, both streams' temperatures at
every boundary and each zone's heat load follow from the energy balance;
each zone then needs the conductance ``UA_z = Q_z / LMTD_z`` (counter flow,
exact for streams of constant heat capacity), i.e. the area fraction ``f_z =
UA_z R_z`` of an exchanger whose full-area resistance for that zone is
``R_z``. The total fraction grows with ``Q`` and without bound as the
temperature difference at a zone end closes; the heat rate is the one at
which the fractions fill the exchanger, found by bisection. This is the
moving-boundary method of Bell et al. (2015) for counter-flow exchangers.
Where the exchanger is so large for the flows that the solution lies within
round-off of a pinch (a small refrigerant flow), the area the last
representable heat rate leaves over goes to the zones at the pinch, so the
fractions always sum to 1 (the zone lengths carry the pressure drop).

Single-phase refrigerant zones use a secant heat capacity between the zone's
start and its end, the phase boundary or, where the secondary stream cannot
bring the refrigerant there, the secondary inlet temperature (as the coil
model, :mod:`evtms.benches.coil`, does): the refrigerant's temperature is
linear in its enthalpy within a zone and can never pass the secondary inlet
temperature. Any trial ``Q`` that would cross the two streams' temperatures
at a zone end needs infinite area, so the solution obeys the second law by
construction.

References
----------
Bell, I. H., Quoilin, S., Georges, E., Braun, J. E., Groll, E. A., Horton,
W. T., Lemort, V. (2015). A generalized moving-boundary algorithm to predict
the heat transfer rate of counterflow heat exchangers for any phase
configuration. Appl. Therm. Eng. 79, 192-201.
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th
ed., sec. 11.3 (log-mean temperature difference) and eq. 11.29b.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from evtms._jit import numba_enabled
from evtms.hx.sides import SecondaryStream

#: Bisection steps on the heat rate (each halves the bracket): 2^-40 of the largest rate, 1e-12
#: relative (60, to round-off, cost the chiller's sweeps more time for nothing).
BISECTION_STEPS = 40
#: Zones of the refrigerant, in the order an evaporating refrigerant meets them.
LIQUID, TWO_PHASE, VAPOUR = 0, 1, 2
#: Cap of the capacity ratio (exchanger area available over needed), for finite LUT values.
CAPACITY_RATIO_MAX = 1e3
#: Relative heat-rate step [1] below a pinched solution over which the zones' area growth is measured.
_PINCH_STEP = 1e-6
#: Superheat enthalpy step [J/kg] of the one-sided derivative behind ``h_out_continued``.
_CONTINUATION_STEP = 1.0


@dataclass
class RefrigerantPath:
    """The evaporating refrigerant through the exchanger, per point.

    Attributes
    ----------
    mdot : numpy.ndarray
        Mass flow [kg/s], > 0.
    h_in : numpy.ndarray
        Inlet specific enthalpy [J/kg].
    T_in : numpy.ndarray
        Inlet temperature [K].
    T_sat, h_l, h_v : numpy.ndarray
        Saturation temperature [K] and saturated liquid and vapour enthalpies
        [J/kg] at the (heat-transfer) pressure.
    h_at_secondary : numpy.ndarray
        Refrigerant enthalpy at the secondary inlet temperature [J/kg]: the
        most the refrigerant can reach.
    R : numpy.ndarray
        Refrigerant-side plus wall resistance over the whole area [K/W] of
        each zone, shape ``(n, 3)`` (liquid, two-phase, vapour); the
        secondary stream's ``R`` adds to it.
    """

    mdot: np.ndarray
    h_in: np.ndarray
    T_in: np.ndarray
    T_sat: np.ndarray
    h_l: np.ndarray
    h_v: np.ndarray
    h_at_secondary: np.ndarray
    R: np.ndarray


@dataclass
class CounterflowResult:
    """Solution of :func:`solve_counterflow_evaporator`.

    Attributes
    ----------
    Q : numpy.ndarray
        Heat rate into the refrigerant [W] (>= 0).
    h_out : numpy.ndarray
        Refrigerant outlet enthalpy [J/kg], ``h_in + Q / mdot``.
    h_secondary_out : numpy.ndarray
        Secondary outlet enthalpy [J/kg], ``h_in - Q / mdot``.
    T_secondary_out : numpy.ndarray
        Secondary outlet temperature [K].
    fractions : numpy.ndarray
        Area fraction of each zone [1], shape ``(n, 3)``; they sum to 1.
    f_needed : numpy.ndarray
        Area fraction needed to evaporate to saturated vapour [1] (0 for a
        vapour inlet, inf where the secondary stream cannot do it).
    capacity_ratio : numpy.ndarray
        ``1 / f_needed``, capped at :data:`CAPACITY_RATIO_MAX` [1].
    h_out_continued : numpy.ndarray
        ``h_out`` where the outlet is superheated; for a two-phase outlet the
        superheated side's heat rate per unit area at the boundary continued
        to the negative area ``1 - f_needed`` [J/kg] (C1 across the phase
        boundary).
    bad_direction : numpy.ndarray
        The secondary inlet is not warmer than the refrigerant inlet.
    """

    Q: np.ndarray
    h_out: np.ndarray
    h_secondary_out: np.ndarray
    T_secondary_out: np.ndarray
    fractions: np.ndarray
    f_needed: np.ndarray
    capacity_ratio: np.ndarray
    h_out_continued: np.ndarray
    bad_direction: np.ndarray


def _subset(ref: RefrigerantPath, idx: np.ndarray) -> RefrigerantPath:
    """The points ``idx`` of ``ref``."""
    return RefrigerantPath(*(getattr(ref, f.name)[idx] for f in dataclasses.fields(ref)))


def _subset_stream(sec: SecondaryStream, idx: np.ndarray) -> SecondaryStream:
    """The points ``idx`` of a secondary stream (a dataclass of per-point arrays and shared tables)."""
    changes = {
        f.name: getattr(sec, f.name)[idx]
        for f in dataclasses.fields(sec)
        if isinstance(getattr(sec, f.name), np.ndarray) and getattr(sec, f.name).shape[:1] == sec.mdot.shape
    }
    return dataclasses.replace(sec, **changes)


def _refrigerant_temperature(ref: RefrigerantPath, T_sec_in: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Refrigerant temperature [K] at enthalpy ``h``: linear (secant) in each zone."""
    reachable = T_sec_in > ref.T_sat
    liquid_in = ref.h_in < ref.h_l
    # Liquid: from the inlet to saturation, or to the secondary inlet temperature.
    h_end_l = np.where(reachable, ref.h_l, ref.h_at_secondary)
    T_end_l = np.where(reachable, ref.T_sat, T_sec_in)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope_l = np.where(liquid_in, (T_end_l - ref.T_in) / (h_end_l - ref.h_in), 0.0)
        # Vapour: from saturation (or a vapour inlet) to the secondary inlet temperature.
        vapour_in = ref.h_in >= ref.h_v
        h0_v = np.where(vapour_in, ref.h_in, ref.h_v)
        T0_v = np.where(vapour_in, ref.T_in, ref.T_sat)
        slope_v = (T_sec_in - T0_v) / (ref.h_at_secondary - h0_v)
    T_liq = ref.T_in + (h - ref.h_in) * slope_l
    T_vap = T0_v + (h - h0_v) * slope_v
    return np.where(h < ref.h_l, T_liq, np.where(h <= ref.h_v, ref.T_sat, T_vap))


def _log_mean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Log-mean of positive ``a`` and ``b`` (their mean where they nearly agree, to round-off)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r = b / a
        lm = (b - a) / np.log(r)
    close = np.abs(r - 1.0) < 1e-6
    # Series of (r - 1) / ln r about r = 1: 1 + (r-1)/2 - (r-1)^2/12.
    e = r - 1.0
    return np.where(close, a * (1.0 + e / 2.0 - e * e / 12.0), lm)


def _fractions(ref: RefrigerantPath, sec: SecondaryStream, Q: np.ndarray) -> np.ndarray:
    """Area fraction of each zone [1], shape ``(n, 3)``, for trial heat rates ``Q`` [W]; inf where infeasible.

    The secondary stream's enthalpy at refrigerant enthalpy ``h`` follows from
    the balance of the part of the exchanger between there and the refrigerant
    inlet: ``h_s(h) = h_s,out + mdot (h - h_in) / mdot_s``.
    """
    h_out = ref.h_in + Q / ref.mdot
    h_s_out = sec.h_in - Q / sec.mdot
    ratio = ref.mdot / sec.mdot
    bounds = [ref.h_in, np.clip(ref.h_l, ref.h_in, h_out), np.clip(ref.h_v, ref.h_in, h_out), h_out]
    T_r = [_refrigerant_temperature(ref, sec.T_in, b) for b in bounds]
    T_s = [sec.temperature(h_s_out + ratio * (b - ref.h_in)) for b in bounds]
    T_s[-1] = sec.T_in  # the secondary inlet itself, exactly
    f = np.zeros((Q.size, 3))
    for z in range(3):
        Q_z = ref.mdot * (bounds[z + 1] - bounds[z])
        dT_a, dT_b = T_s[z] - T_r[z], T_s[z + 1] - T_r[z + 1]
        feasible = (dT_a > 0) & (dT_b > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            f_z = Q_z * (ref.R[:, z] + sec.R) / _log_mean(np.where(feasible, dT_a, 1.0), np.where(feasible, dT_b, 1.0))
        f[:, z] = np.where(Q_z > 0, np.where(feasible, f_z, np.inf), 0.0)
    return f


def _fill_pinch(ref: RefrigerantPath, sec: SecondaryStream, Q: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Zone fractions [1], shape ``(n, 3)``, that fill the exchanger at the solved heat rate ``Q`` [W].

    Where the exchanger is large for the flows (a small refrigerant flow), the
    solution lies within round-off of a pinch: a zone end whose temperature
    difference closes (the refrigerant reaching the secondary inlet
    temperature, or the secondary reaching the refrigerant inlet temperature).
    The fractions grow only logarithmically there, so at the last
    representable heat rate they may sum to far less than 1 (a few per cent
    at 1 mg/s), and one step further they are infinite. Physically the
    streams run the rest of the exchanger at a vanishing temperature
    difference, in the zones adjacent to the pinch; near a pinch of
    difference ``e`` each zone's fraction goes as ``a_z ln(1/e) + b_z``, so
    the remaining area goes to the zones in proportion to ``a_z``, i.e. to
    their growth ``df_z/dQ`` just below ``Q`` (measured over a step of
    :data:`_PINCH_STEP` of ``Q``, which widens the pinch by orders of
    magnitude while changing the non-divergent parts ``b_z`` negligibly).
    Without this the zone lengths, and with them the pressure drop, are those
    of an arbitrary fraction of the exchanger, or infinite.
    """
    missing = 1.0 - f.sum(axis=1)
    gap = (Q > 0) & (missing > 0) & np.isfinite(missing)
    if not gap.any():
        return f
    idx = np.nonzero(gap)[0]
    growth = f[idx] - _fractions(_subset(ref, idx), _subset_stream(sec, idx), Q[idx] * (1.0 - _PINCH_STEP))
    growth = np.where(np.isfinite(growth), np.maximum(growth, 0.0), 0.0)
    total = growth.sum(axis=1)
    # The fractions grow with Q wherever Q > 0; should none grow, leave them rather than divide by zero.
    share = np.divide(growth, total[:, None], out=np.zeros_like(growth), where=total[:, None] > 0)
    f = f.copy()
    f[idx] += missing[idx, None] * share
    return f


def _largest_fitting_heat_rate(ref: RefrigerantPath, sec: SecondaryStream, hi: np.ndarray) -> np.ndarray:
    """The largest heat rate [W] in ``[0, hi]`` at which the zone fractions sum to less than 1.

    A stream with a tabulated enthalpy-temperature relation (``temperature_table()``, the
    coolant) takes the compiled per-point search (the same arithmetic; 8x faster on one
    point, where NumPy's per-call overhead dominates); any other, or any without numba
    (``EVTMS_NO_NUMBA=1``), the array bisection.
    """
    table = getattr(sec, "temperature_table", None)
    if table is not None and numba_enabled():  # as plain Python the per-point loop would crawl
        from evtms.hx import _kernels

        n = hi.size
        R = np.asarray(ref.R, float)
        ref_rows = _kernels.columns(
            n, ref.mdot, ref.h_in, ref.T_in, ref.T_sat, ref.h_l, ref.h_v, ref.h_at_secondary, R[:, 0], R[:, 1], R[:, 2]
        )
        sec_rows = _kernels.columns(n, sec.mdot, sec.T_in, sec.h_in, sec.R)
        tab_h, tab_T = (np.ascontiguousarray(t, float) for t in table())
        return _kernels.bisect_counterflow_heat_rate(
            BISECTION_STEPS, np.ascontiguousarray(hi, float), ref_rows, sec_rows, tab_h, tab_T
        )
    lo = np.zeros(hi.size)
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        below = _fractions(ref, sec, mid).sum(axis=1) < 1.0
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return lo


def solve_counterflow_evaporator(ref: RefrigerantPath, sec: SecondaryStream) -> CounterflowResult:
    """Heat rate of a counter-flow exchanger evaporating ``ref`` against the warmer stream ``sec``.

    Parameters
    ----------
    ref : RefrigerantPath
        The refrigerant, its saturation state and zone resistances.
    sec : SecondaryStream
        The secondary stream: mass flow, inlet state, enthalpy-temperature
        relation and its resistance over the whole area.

    Returns
    -------
    CounterflowResult
        Heat rate, outlet states of both streams, zone fractions and the
        smooth closure variables of the evaporator benches. Points whose
        inputs are not finite, or whose secondary inlet is not warmer than the
        refrigerant inlet (``bad_direction``), have ``Q = 0``.
    """
    bad_direction = ~(sec.T_in - ref.T_in > 0)
    ok = ~bad_direction & np.isfinite(ref.h_at_secondary + ref.R.sum(axis=1) + sec.R + sec.h_in)
    # Upper bound: the refrigerant leaves at the secondary inlet temperature.
    hi = np.where(ok, ref.mdot * (ref.h_at_secondary - ref.h_in), 0.0)
    ok &= hi > 0
    hi = np.where(ok, hi, 0.0)
    # The largest heat rate found to fit; the bound itself may not, where a zone end closes
    # and the fractions are infinite.
    Q = np.where(ok, _largest_fitting_heat_rate(ref, sec, hi), 0.0)
    fractions = _fill_pinch(ref, sec, Q, _fractions(ref, sec, Q))
    h_out = ref.h_in + Q / ref.mdot
    h_s_out = sec.h_in - Q / sec.mdot

    # Area needed to finish the evaporation: the same balance at Q_v = mdot (h_v - h_in).
    reachable = ok & (sec.T_in > ref.T_sat)
    Q_v = ref.mdot * np.maximum(ref.h_v - ref.h_in, 0.0)
    f_needed = np.where(reachable, _fractions(ref, sec, np.where(reachable, Q_v, 0.0)).sum(axis=1), np.inf)
    f_needed = np.where(ok & (ref.h_in >= ref.h_v), 0.0, f_needed)
    with np.errstate(divide="ignore"):
        capacity_ratio = np.where(
            f_needed > 1.0 / CAPACITY_RATIO_MAX, 1.0 / np.maximum(f_needed, 1e-300), CAPACITY_RATIO_MAX
        )
    # Where the outlet stops short of the vapour zone, continue its outlet enthalpy to the
    # negative area 1 - f_needed with the slope the superheated side has at the boundary:
    # there a vapour zone of heat rate dQ needs the area df = dQ f'(Q_v+), f' the one-sided
    # derivative of the fractions at Q_v (the vapour zone's own area and, counter flow, the
    # extra area the two-phase zone needs with the coolant it has cooled). Equal to h_out at
    # the boundary and C1-continuous there, as the coil's continuation is.
    short = reachable & np.isfinite(f_needed) & (f_needed > 1.0)
    h_continued = h_out.copy()
    if short.any():
        idx = np.nonzero(short)[0]
        sub_ref, sub_sec = _subset(ref, idx), _subset_stream(sec, idx)
        dQ = ref.mdot[idx] * _CONTINUATION_STEP
        f_plus = _fractions(sub_ref, sub_sec, Q_v[idx] + dQ).sum(axis=1)
        rate = dQ / (f_plus - f_needed[idx])  # heat rate per unit area fraction [W]
        # Should the pinch lie within the step, fall back to the vapour zone alone.
        rate = np.where(
            np.isfinite(rate) & (rate > 0), rate, (sec.T_in - ref.T_sat)[idx] / (ref.R[idx, VAPOUR] + sec.R[idx])
        )
        h_continued[idx] = ref.h_v[idx] + (1.0 - f_needed[idx]) * rate / ref.mdot[idx]
    return CounterflowResult(
        Q=Q,
        h_out=h_out,
        h_secondary_out=h_s_out,
        T_secondary_out=sec.temperature(h_s_out),
        fractions=fractions,
        f_needed=f_needed,
        capacity_ratio=capacity_ratio,
        h_out_continued=h_continued,
        bad_direction=bad_direction,
    )


@dataclass
class _MirroredStream:
    """A secondary stream seen through the mirror ``h -> -h``, ``T -> -T`` (:func:`solve_counterflow_condenser`).

    A colder stream being heated becomes a warmer one being cooled; its
    enthalpy-temperature relation is the original one reflected, and its
    table (kept in a tuple, so no per-point subset touches it) still rises in
    enthalpy, as the compiled search reads it.
    """

    mdot: np.ndarray
    T_in: np.ndarray
    h_in: np.ndarray
    R: np.ndarray
    table: tuple[np.ndarray, ...]
    original: SecondaryStream

    def temperature(self, h: np.ndarray) -> np.ndarray:
        return -self.original.temperature(-np.asarray(h, float))

    def temperature_table(self) -> tuple[np.ndarray, np.ndarray]:
        return self.table[0], self.table[1]


def _mirror_stream(sec: SecondaryStream) -> _MirroredStream:
    h, T = sec.temperature_table()  # a tabulated stream (the coolant): its reflection is a table too
    table = (-np.asarray(h, float)[::-1], -np.asarray(T, float)[::-1])
    return _MirroredStream(sec.mdot, -sec.T_in, -sec.h_in, sec.R, table, sec)


def solve_counterflow_condenser(ref: RefrigerantPath, sec: SecondaryStream) -> CounterflowResult:
    """Heat rate of a counter-flow exchanger condensing ``ref`` against the colder stream ``sec``.

    The condensing problem is the evaporating one reflected in enthalpy and
    temperature (``h -> -h``, ``T -> -T``): the refrigerant's enthalpy then
    rises through the reflected zones (desuperheating vapour as the
    reflected "liquid", two-phase, subcooled liquid as the reflected
    "vapour", with ``h_l`` and ``h_v`` exchanging roles), the colder
    secondary stream becomes a warmer one, and every temperature difference,
    log-mean, zone fraction and the second-law bound carry over unchanged.
    So one algorithm (:func:`solve_counterflow_evaporator`, Bell et al. 2015)
    solves both, and the condenser obeys the second law by the same
    construction: the refrigerant never leaves colder than the secondary
    enters, nor the secondary warmer than the refrigerant enters.

    Parameters
    ----------
    ref : RefrigerantPath
        The condensing refrigerant: its inlet (superheated or two-phase),
        saturation state, ``h_at_secondary`` its enthalpy at the secondary
        inlet temperature (the least it can reach) and ``R`` per zone in the
        order (liquid, two-phase, vapour).
    sec : SecondaryStream
        The colder secondary stream (a coolant being heated).

    Returns
    -------
    CounterflowResult
        ``Q`` heat out of the refrigerant [W] (>= 0), ``h_out`` and the
        secondary's outlet, ``fractions`` in (liquid, two-phase, vapour)
        order, ``f_needed`` the area fraction needed to condense to saturated
        liquid and ``capacity_ratio`` its inverse, ``h_out_continued``
        (``h_out`` for a subcooled outlet; for a two-phase one continued past
        the saturated-liquid boundary to the negative area ``1 - f_needed``,
        with the subcooled side's slope), ``bad_direction`` (the secondary
        inlet is not colder than the refrigerant inlet).
    """
    mirrored_ref = RefrigerantPath(
        mdot=ref.mdot,
        h_in=-ref.h_in,
        T_in=-ref.T_in,
        T_sat=-ref.T_sat,
        h_l=-ref.h_v,
        h_v=-ref.h_l,
        h_at_secondary=-ref.h_at_secondary,
        R=np.asarray(ref.R, float)[:, ::-1],
    )
    res = solve_counterflow_evaporator(mirrored_ref, _mirror_stream(sec))
    return CounterflowResult(
        Q=res.Q,
        h_out=-res.h_out,
        h_secondary_out=-res.h_secondary_out,
        T_secondary_out=-res.T_secondary_out,
        fractions=res.fractions[:, ::-1],
        f_needed=res.f_needed,
        capacity_ratio=res.capacity_ratio,
        h_out_continued=-res.h_out_continued,
        bad_direction=res.bad_direction,
    )
