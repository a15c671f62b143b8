"""The LUT cycle over random points of the system simulator's whole envelope, in every topology.

Whatever a point does, the result is a state or a reason: no exception, a
valid point's figures are finite and close the energy balance, an invalid
point's are NaN and its reason says why. These points reach the LUTs' edges
(no-heat cells next to nodes with the refrigerant on the wrong side of a
secondary stream, axis ends, valves at their limits), where the accuracy
tests' narrower envelopes do not go.
"""

from __future__ import annotations

import numpy as np
import pytest

from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
from evtms.cycle.solver import _MIX_TOL, VALID_CYCLE_FLAGS
from evtms.cycle.topology import TOPOLOGIES

#: Figures a valid point must have finite (a closed branch's heat flow is 0, not NaN).
FIGURES = ("p_A", "p_B", "h_A", "h_B", "h_C", "mdot", "mdot_evap", "mdot_chiller", "Q_evap", "Q_chiller", "Q_cond", "W")


def wide_points(n: int, seed: int) -> OperatingPoints:
    """Ambient -10 to 50 degC, cabin air 10-50 degC, coolant 5-45 degC, every actuator 0.1-1; the heat
    pump's heating loop at 20-70 degC, 0.05-0.36 kg/s (drawn last: the other inputs' draws stay as they were)."""
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.1, 1.0, n),
        fan=rng.uniform(0.1, 1.0, n),
        blower=rng.uniform(0.1, 1.0, n),
        T_amb=rng.uniform(263.15, 323.15, n),
        T_cabin=rng.uniform(283.15, 323.15, n),
        RH_cabin=rng.uniform(0.2, 0.8, n),
        mdot_coolant=rng.uniform(0.12, 0.45, n),
        T_coolant_in=rng.uniform(278.15, 318.15, n),
        superheat=rng.uniform(5.0, 10.0, n),
        T_coolant_h_in=rng.uniform(293.15, 343.15, n),
        mdot_coolant_h=rng.uniform(0.05, 0.36, n),
    )


@pytest.mark.parametrize("circuit", [name for name, t in TOPOLOGIES.items() if len(t.chain) == 1])
def test_every_point_of_the_wide_envelope_is_a_state_or_a_reason(cycle_luts_dir, circuit):
    r = run_cycle(wide_points(80, seed=5), load_cycle_luts(cycle_luts_dir, circuit), circuit=circuit)
    valid = np.isin(r["status"], VALID_CYCLE_FLAGS)
    assert 0.5 * valid.size < valid.sum() < valid.size  # most solve; some reach an edge
    for key in FIGURES:
        assert np.isfinite(r[key][valid]).all(), key
        assert np.isnan(r[key][~valid]).all(), key
    assert all(r["reason"][~valid]), "an invalid point without a reason"
    # Physics of every valid state: compression raises the pressure, the condenser gives heat
    # away, the evaporating branches take it in, and energy closes per point.
    assert (r["p_B"][valid] > r["p_A"][valid]).all()
    assert (r["Q_cond"][valid] > 0).all() and (r["W"][valid] > 0).all()
    assert (r["Q_evap"][valid] <= 0).all() and (r["Q_chiller"][valid] <= 0).all()
    assert (r["COP"][valid] > 0).all()
    np.testing.assert_allclose(r["mdot_evap"][valid] + r["mdot_chiller"][valid], r["mdot"][valid], rtol=1e-12)
    # The residual is mdot (h_A - the branch outlets' mixture): bounded by the suction closure's
    # tolerance on that mixture (1 J/kg, about 1 mK of superheat), not by a fraction of the work
    # (at a -8 degC ambient W_fluid is 137 W: 1e-4 of it is 0.3 J/kg of the 45 g/s).
    assert (np.abs(r["balance_residual"][valid]) <= _MIX_TOL * r["mdot"][valid]).all()
