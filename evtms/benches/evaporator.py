"""Evaporator bench: flat-tube evaporator cooling moist cabin air.

The refrigerant enters at ``(p_in, T_in)`` (or ``h_in``, the usual two-phase
inlet of a running cycle) with mass flow ``mdot``; air at the bench
environment is drawn across the coil by the blower at fraction ``blower`` of
its maximum flow. The moving-boundary coil of :mod:`evtms.benches.coil`
(the condenser's, not a copy) resolves liquid, two-phase and vapour zones in
that order; boiling follows Gungor and Winterton (1987); the air side is moist
and, where the coil surface is below the dew point, wet: the enthalpy-potential
method of Threlkeld (1970) in the form of Braun, Klein and Mitchell (1989)
gives the total and, through the effective surface state, the moisture
condensed; the two-phase zone is dry up to where its surface meets the dew
point along the air's path and wet beyond (the partly wet coil,
:meth:`evtms.hx.sides.MoistAirSide.zone_model`). ``Q_latent`` is the latent heat of that condensate (<= 0, part of
``Q``).

Inlet states the thesis grid produces and how they are treated:

- superheated vapour (``T_in`` above saturation): sensible heating of the
  vapour only, outlet superheated;
- subcooled liquid (``T_in`` below saturation at ``p_in``): the liquid warms to
  saturation, then boils, then superheats, as far as the coil area allows.

Energy: ``Q = mdot (h_in - h_out)`` (< 0), and the air loses
``m_da (h_air_in - h_air_out)`` = ``-Q`` plus the enthalpy carried away by the
liquid condensate. The air leaving is the mixture of the zones' outlet
streams; where that mixture would be supersaturated (the saturation curve is
convex, so mixing nearly saturated streams can overshoot it, and humid air
crossing a coil far below its dew point does so strongly: before this was
handled, up to RH 1.033 on the thesis grid and up to 3.6 times the
saturation humidity ratio at -35 degC evaporating in the cycle envelope),
the excess water condenses and the air leaves saturated at the temperature
that keeps the energy balance (:func:`evtms.hx.sides.condense_excess`),
never above saturation.

Frost: where the coldest coil surface is below 0 degC, ``status`` is
``valid_frost_risk`` (code 10): the point is valid (finite values), but ice
would build up on the fins over time and the steady state would not last.
The condensate is still taken as liquid water there. The air side is the
condenser's louvred-fin correlation (Chang and Wang 1997), valid for
louver-pitch Reynolds numbers 100 to 3000; below or above, the point is
valid with status 11 (``valid_air_correlation_outside_range``), or 12 if it
also risks frost. The blower's air flows give Re_Lp of about 15 (blower 0.1)
to 160 (blower 1). Chang and Wang's data are for dry fins; the wet surface
takes the same coefficient.

``T_res`` (downstream reservoir) has no effect in steady state; the axis is
kept for parity with the thesis.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from evtms.benches.base import (
    COMMON_FLAGS,
    Bench,
    finish_status,
    pressure_nodes,
)
from evtms.benches.coil import CoilParams
from evtms.benches.condenser import (
    COIL_OUTPUTS,
    STATUS_AIR_CORRELATION_OUTSIDE_RANGE,
    STATUS_DP_EXCEEDS_INLET,
    coil_bench_outputs,
)
from evtms.fluid import Fluid

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters


def evaporator_coil() -> CoilParams:
    """The evaporator's default coil: :class:`CoilParams` at the cabin evaporator's size."""
    return CoilParams(
        n_tubes=20,
        core_length=0.75,
        core_height=0.20,
        area_air_free=0.120,
        area_air_primary=0.432,
        area_air_fin=7.2,
        area_ref=0.66,
        fan_flow_max=0.3,
    )


STATUS_NOT_COLDER_THAN_AIR = 3
STATUS_FROST_RISK = 10
STATUS_FROST_RISK_AIR_OUTSIDE_RANGE = 12
#: Status codes of the valid points that risk frost.
FROST_RISK_FLAGS = (STATUS_FROST_RISK, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE)
FREEZING_POINT = 273.15  # K

# The coil's outputs with the latent part of Q after Q.
OUTPUTS = ("status", "Q", "Q_latent", *(k for k in COIL_OUTPUTS if k != "Q"))


def evaporator_heat_rate(inputs: dict[str, np.ndarray], params: Parameters, fluid: Fluid) -> dict[str, np.ndarray]:
    """Steady-state evaporator response over arrays of bench inputs.

    Parameters
    ----------
    inputs : dict of str to numpy.ndarray
        ``mdot`` [kg/s], ``blower`` [1], ``p_in`` [Pa], ``T_in`` [K] or
        ``h_in`` [J/kg], ``T_res`` [K] (no effect); optionally ``T_air_in``
        [K] and ``RH_air_in`` [1] (else the environment's air).
    params : Parameters
        Coil geometry (``params.evaporator``) and the entering air.
    fluid : Fluid
        Refrigerant properties.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Q`` [W] (< 0: heat into the refrigerant), ``Q_latent`` [W] (<= 0),
        ``h_in``, ``h_out`` [J/kg], ``T_out`` [K], ``p_out`` [Pa],
        ``x_out`` [1], ``T_air_out`` [K], ``dp`` [Pa], ``capacity_ratio`` [1]
        (coil length over the length needed to evaporate to saturated vapour),
        ``h_out_continued`` [J/kg] (``h_out`` for a superheated outlet; for a
        two-phase outlet the superheated zone's heat rate continued linearly
        to the negative length ``1 - 1/capacity_ratio``: smooth where
        ``h_out`` has its kink, for the cycle's superheat closure) and
        ``status`` (int8, see :data:`FLAGS`; 0, 10, 11 and 12 are valid, 10
        and 12 risk frost, 11 and 12 use the air-side correlation outside its
        range).
    """
    out, status, res = coil_bench_outputs(inputs, params, fluid, "evaporator")
    out["Q_latent"] = np.asarray(res["Q_latent"], float).copy()
    cold = res["T_surface_min"] < FREEZING_POINT
    status[(status == 0) & cold] = STATUS_FROST_RISK
    status[(status == STATUS_AIR_CORRELATION_OUTSIDE_RANGE) & cold] = STATUS_FROST_RISK_AIR_OUTSIDE_RANGE
    finish_status(status, out, BENCH.valid_flags)
    out["status"] = status
    return out


FLAGS = {
    **COMMON_FLAGS,
    STATUS_NOT_COLDER_THAN_AIR: "refrigerant_inlet_not_colder_than_air",
    STATUS_DP_EXCEEDS_INLET: "pressure_drop_exceeds_inlet_pressure",
    STATUS_FROST_RISK: "valid_frost_risk_surface_below_0C",
    STATUS_AIR_CORRELATION_OUTSIDE_RANGE: "valid_air_correlation_outside_range",
    STATUS_FROST_RISK_AIR_OUTSIDE_RANGE: "valid_frost_risk_air_correlation_outside_range",
}

#: The cycle grid's geometric flow ladder [kg/s] (16 nodes over 3-150 g/s) and its ratio [1].
_LADDER_NODES = np.geomspace(0.003, 0.15, 16)
_LADDER = _LADDER_NODES[1] / _LADDER_NODES[0]

BENCH = Bench(
    name="evaporator",
    title="evtms evaporator bench: flat-tube R134a evaporator with moist air",
    axes=("mdot", "blower", "p_in", "T_in", "T_res"),
    outputs=OUTPUTS,
    flags=FLAGS,
    evaluate=evaporator_heat_rate,
    parameters=evaporator_coil,
    extra_axes=("T_air_in", "RH_air_in"),
    optional_outputs=("capacity_ratio", "h_out_continued"),
    surface_axes=(("p_in", "T_in"), ("p_in", "h_in")),
    valid_flags=(0, STATUS_FROST_RISK, STATUS_AIR_CORRELATION_OUTSIDE_RANGE, STATUS_FROST_RISK_AIR_OUTSIDE_RANGE),
    presets={
        "thesis": {
            "mdot": (0.004526, 0.0062, 0.00743, 0.0077),
            "blower": (0.2, 0.3, 0.4, 0.5),
            "p_in": (0.05e6, 0.1e6, 0.2e6, 0.25e6),
            "T_in": (235.0, 250.0, 265.0, 275.0),
            "T_res": (250.0, 265.0, 280.0),
        },
        # Cycle envelope (README): cabin air 10-50 degC at RH 0.2-0.8, blower 0.1-1,
        # evaporating -35 to 41 degC. Air every 2 K over 15-35 degC: with 4 K the LUT cycle's suction
        # pressure was up to 1.2 % off the direct physics, with 2 K within 0.8 % (README,
        # accuracy). Flow and pressure nodes only where the cycle runs: mdot is the
        # 16-node geometric 3-150 g/s ladder less 3.9, 6.6 and 116 g/s (13 nodes), the
        # saturation temperature every 2 K from -21 to 25 degC plus -35, -28 and 29 degC
        # (27 nodes; the accuracy benchmark's evaporator inlets: -20.7 to 23.9 degC).
        # 1.62 million points instead of 2.44 (`evtms bench evaporator --grid cycle
        # --workers 2`, two cores, back to back: 36.5 s instead of 52.1 s; 84 MB instead
        # of 123 MB) with the same accuracy: `python3 benchmarks/accuracy_cycle.py LUTS
        # --points 100 --topology cabin` worst p_A 1.75 %, p_B 1.38 %, Q_evap 1.50 %
        # (1.48 % before), COP 2.64 %, valve_opening 1.98 % (1.96 %), status equal in 97
        # points as before; at 200 points and for cabin+chiller the worst figures equal the 2.44-million
        # grid's. Coarser axes that did not hold (same benchmark, 100 points unless
        # said): RH 5 nodes (COP 4.1 %), blower 9 (p_A 2.1 %), mdot 12 geometric (COP
        # 3.3 %), h_in 4 (COP 4.2 %), air every 2.5 K (200 points: COP 2.78 % vs 2.47 %).
        # Extended for the system simulator (spec 2.5): air also at 10, 40, 45 and 50 degC;
        # saturation 29-41 degC every 3 K (a hot soak at speed 0.1 evaporates at up to 38 degC;
        # at 50/50 degC, speed 0.1, p_A was 1.8 % off the direct physics with nodes 34 and 40,
        # 1.1 % every 3 K, 0.0 % every 2 K, which overflows the 16,384-point chunk of one mdot
        # and blower); h_in from 185 kJ/kg (liquid condensing at -9.5 degC, a -10 degC ambient)
        # in 5 nodes: 6 (185 and the old 200-350) kept the old figures but cost 20 % more
        # points and split every chunk in two (evaporator bench 108-138 s instead of 77 s).
        # 2.54 million points, 125 MB, 62.7 s (was 1.62 million, 84 MB, 32.4 s back to back:
        # the new points cost more each); same benchmark: p_A 2.10 %
        # (median 0.24 % vs 0.20 %), p_B 1.72 %, Q_evap 1.62 %, COP 2.07 %, valve_opening
        # 2.14 %, status equal in 98; with --wide (ambient -10-50, cabin 10-50 degC) p_A
        # 1.65 %, COP 5.38 %, status equal in 97.
        # Down to 1.37 g/s (the ladder continued by three nodes; 3.12 million points, 151 MB, 62 s): in
        # the cabin+chiller circuit at low speed the chiller takes most of the flow and the cabin
        # branch runs below 3 g/s; with the ladder ending at 3 g/s the LUT cycle closed that valve
        # where the physics passed 2.5 g/s (Q_evap 0 instead of -417 W, p_A 4.8 % off). With them,
        # 100 random cabin+chiller points: p_A worst 1.21 % (was 4.83 %), status equal in 98 (97).
        # 3.9 and 6.6 g/s back (18 nodes, 3.52 million points): with two branches the cabin branch
        # often runs at 6-7 g/s, where the 5.05-8.51 g/s cell put its outlet 0.3-1 kJ/kg off the
        # physics; the worst COP error of the 100 cabin+chiller points fell from 1.30 to 1.00 %
        # and the points with the split over 1 % of the total cooling from 11 to 4.
        # The ladder at half the ratio (1.14x apart) where the vapour zone's Nusselt number has its
        # corners, Re 2300 and 4000 (about 8-11 and 14-19 g/s): 6.6-31 g/s; 1.3x apart below and
        # above (25 nodes). There the outlet's response to the flow sets a valve's flow: with the
        # 1.3x ladder throughout, 100 random cabin+chiller points split the cooling between the
        # branches up to 2.7 % off the direct physics (at 9-18 g/s).
        # Humidity every 0.05 and h_in nodes closer over the liquid lines' 230-300 kJ/kg: the
        # two-phase zone wets from the air's exit side as the humidity rises (evtms.hx.sides,
        # the partly wet coil), and the outlet's response turns from flat to steep within a few
        # hundredths of RH; with humidity every 0.1 the worst split of the 100 cabin+chiller
        # points was 1.32 %, with the h_in nodes evenly spaced 1.64 %. 9.07 million points, 420 MB;
        # `evtms bench evaporator --grid cycle --workers 2` about 120 s. A sixth h_in node at
        # 321 kJ/kg (10.9 million points, 112 s) took the cabin valve opening's worst from 1.67
        # to 1.52 % only: the rest is spread over the blower, flow and air temperature axes.
        # Each axis thinned to every other node in turn (benchmarks/grid_study.py, the cycle guide's
        # table): every one raised some worst error by a third or more, so the grid stays. The nodes the
        # interpolant needs least dropped first (benchmarks/grid_curvature.py): at 20 % fewer points the
        # cabin branch's heat in the parallel circuit rose 7-10 % at the 90th percentile in every sample,
        # where the flow that holds the setpoint runs through the nodes dropped (2.3 and 8.5 g/s).
        "cycle": {
            "mdot": tuple(0.003 * np.sqrt(_LADDER) ** np.r_[-6:6:2, 6:19, 20:31:2]),
            "blower": tuple(np.geomspace(0.1, 1.0, 12)),
            "p_in": pressure_nodes(np.r_[-35.0, -28.0, np.arange(-21.0, 26.0, 2.0), np.arange(29.0, 42.0, 3.0)]),
            "h_in": (185e3, 232.5e3, 262.5e3, 292.5e3, 350e3),
            "T_res": (280.0,),
            "T_air_in": tuple(np.r_[10.0, np.arange(15.0, 35.1, 2.0), 40.0, 45.0, 50.0] + 273.15),
            "RH_air_in": tuple(np.linspace(0.2, 0.8, 13)),
        },
    },
)
