"""Warm-started cycle solves (a previous solve's solution as the closures' start) against cold ones.

The closures are root-finds of monotonic residuals: started from the solution
of a nearby point they must end on the same roots, to within the closures'
tolerances (suction: |superheat residual| < OUTER_FTOL = 1e-4 K, i.e. a few
1e-5 K of suction saturation, about 1e-6 of the pressure; a floating
superheat to 1e-4 in ln(opening), about 0.01 K), with the same statuses, in
fewer component calls. The bench physics (DirectModels), a few seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from evtms.cycle.models import DirectModels
from evtms.cycle.solver import STATUS_CONVERGED, STATUS_VALVE_SATURATED, CycleSolver, OperatingPoints
from evtms.cycle.state import WarmStart
from evtms.fluid import SaturationCurve

#: A drive's consecutive refrigerant points (compressor speeding up, blower rising, cabin cooling):
#: the valve saturates along the way (its superheat floats from the third point on).
_SPEED = (0.6815, 0.734, 0.7538, 0.7437, 0.7237)
_BLOWER = (0.88, 0.96, 1.0, 1.0, 1.0)
_T_CABIN = (302.6715, 302.4316, 302.1555, 301.8514, 301.5276)
_RH_CABIN = (0.4904, 0.4936, 0.4973, 0.5012, 0.5053)


def _point(j: int) -> OperatingPoints:
    return OperatingPoints(
        speed=_SPEED[j],
        fan=0.3333,
        blower=_BLOWER[j],
        T_amb=303.15,
        RH_amb=0.4,
        T_cabin=_T_CABIN[j],
        RH_cabin=_RH_CABIN[j],
        superheat=10.0,
    )


class _Counted(DirectModels):
    """The bench physics, counting the component calls."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.calls = 0

    def _run(self, component, inputs):
        self.calls += 1
        return super()._run(component, inputs)


@pytest.fixture(scope="module")
def solves(params, fluid):
    """Each point solved cold, and warm from the previous point's solution: (results, calls) of both."""
    sat = SaturationCurve(fluid)
    out = {}
    for mode in ("cold", "warm"):
        models = _Counted(params, fluid)
        # The Python searches (the compiled cold closure makes no model calls of this kind).
        solver = CycleSolver(models, sat, "cabin", closure="python")
        results, warm = [], None
        for j in range(len(_SPEED)):
            results.append(solver.solve(_point(j), warm=warm if mode == "warm" else None))
            warm = solver.warm_start
        out[mode] = (results, models.calls)
    return out


def test_warm_solves_end_on_the_cold_roots(solves):
    cold, warm = solves["cold"][0], solves["warm"][0]
    for c, w in zip(cold, warm, strict=True):
        assert c.status.tolist() == w.status.tolist()
        # Holding the setpoint: pressures to a few 1e-5 K of saturation temperature (the suction
        # closure's tolerance). Floating: the superheat to its search's tolerance (1e-4 in
        # ln(opening), about 0.01 K), which moves the suction saturation by up to 0.005 K.
        floating = c.status[0] == STATUS_VALVE_SATURATED
        rel = 2e-4 if floating else 1e-5
        assert w["p_A"] == pytest.approx(c["p_A"], rel=rel)
        assert w["p_B"] == pytest.approx(c["p_B"], rel=rel)
        assert w["mdot"] == pytest.approx(c["mdot"], rel=10 * rel)
        assert w["superheat_actual"] == pytest.approx(c["superheat_actual"], abs=0.01)


def test_the_sequence_holds_and_floats_the_superheat(solves):
    """Both kinds of solve are exercised: the valve holding its setpoint, and saturated."""
    statuses = {int(r.status[0]) for r in solves["cold"][0]}
    assert STATUS_CONVERGED in statuses and STATUS_VALVE_SATURATED in statuses


def test_warm_solves_need_fewer_component_calls(solves):
    assert solves["warm"][1] < 0.6 * solves["cold"][1]


def test_a_far_warm_start_still_finds_the_root(params, fluid):
    """A warm start from a far point (another speed, ambient and cabin) holds no sign change in its
    first brackets: the searches fall back to the whole range and end on the cold root."""
    sat = SaturationCurve(fluid)
    solver = CycleSolver(DirectModels(params, fluid), sat, "cabin")
    far = solver.solve(OperatingPoints(speed=0.3, fan=0.8, blower=0.4, T_amb=293.15, T_cabin=295.15))
    assert far.status[0] == STATUS_CONVERGED
    point = OperatingPoints(speed=0.9, fan=0.5, blower=0.6, T_amb=308.15, T_cabin=303.15)
    warm = solver.solve(point, warm=solver.warm_start)
    cold = solver.solve(point)
    assert warm.status.tolist() == cold.status.tolist()
    assert warm["p_A"] == pytest.approx(cold["p_A"], rel=1e-5)
    assert warm["p_B"] == pytest.approx(cold["p_B"], rel=1e-5)


def test_warm_start_of_another_batch_is_refused(params, fluid):
    solver = CycleSolver(DirectModels(params, fluid), SaturationCurve(fluid), "cabin")
    with pytest.raises(ValueError, match="warm start of 3 points for 1 points"):
        solver.solve(_point(0), warm=WarmStart.blank(3))


def test_a_failed_point_leaves_no_warm_start(params, fluid):
    """A point the cycle cannot solve (a cabin colder than any evaporation the search allows)
    leaves NaN: the next solve starts that point cold."""
    solver = CycleSolver(DirectModels(params, fluid), SaturationCurve(fluid), "cabin")
    res = solver.solve(OperatingPoints(speed=0.5, T_amb=303.15, T_cabin=200.0))
    assert res.status[0] != STATUS_CONVERGED
    assert np.isnan(solver.warm_start.t_A[0]) and np.isnan(solver.warm_start.p_B[0])


def test_parallel_branches_warm_start_the_split(params, fluid):
    """Cabin and chiller in parallel: warm from the previous point, the same roots and flow split
    as cold (the split to its closure's tolerance), in a fraction of the branch calls."""
    sat = SaturationCurve(fluid)
    models = _Counted(params, fluid)
    solver = CycleSolver(models, sat, "cabin+chiller")
    near = {"fan": 0.5, "blower": 0.6, "T_amb": 303.15, "mdot_coolant": 0.15}
    solver.solve(OperatingPoints(speed=0.5, T_cabin=300.15, T_coolant_in=303.15, **near))
    point = OperatingPoints(speed=0.53, T_cabin=300.0, T_coolant_in=303.0, **near)
    start, models.calls = solver.warm_start, 0
    warm = solver.solve(point, warm=start)
    warm_calls, models.calls = models.calls, 0
    cold = solver.solve(point)
    assert warm.status.tolist() == cold.status.tolist() == [STATUS_CONVERGED]
    for k in ("p_A", "p_B"):
        assert warm[k] == pytest.approx(cold[k], rel=1e-5)
    assert warm["mdot_chiller"] == pytest.approx(cold["mdot_chiller"], rel=1e-4)
    assert warm_calls < 0.5 * models.calls
