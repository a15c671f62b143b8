"""The physics model's solves in the loop (Refrigerant.solve_direct): one solver per map, warm-started.

Each solve of a map reuses that map's solver (its bench models and saturation
curve, made once per Refrigerant) and starts from the map's previous solution;
its targets are those of a cold solve to within the closures' tolerances. The
bench physics on the session's cycle LUTs' parameters, a few seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from evtms.cycle import models
from evtms.fluid import Fluid, SaturationCurve
from evtms.system.maps import MAPS, map_values, operating_inputs
from evtms.system.refrigerant import MAP_NAMES, Refrigerant

AC = next(k for k, v in MAP_NAMES.items() if v == "ac")
#: Two nearby loop points of the ac map (speed, fan, blower, T_amb, T_air_in, RH_air_in), further apart
#: than the physics tolerance (so the second is solved, not reused).
_X1 = np.array([0.60, 0.5, 0.7, 303.15, 300.15, 0.5])
_X2 = np.array([0.65, 0.5, 0.74, 303.15, 299.85, 0.51])


@pytest.fixture()
def refrigerant(cycle_luts_dir):
    sat = SaturationCurve(Fluid())
    return Refrigerant(maps={}, sat_T=sat.T, sat_p=sat.p, coolant_mdot_max=0.2, folder=cycle_luts_dir)


def test_one_solver_per_map_and_warm_solves(refrigerant, monkeypatch):
    made = []
    original = models.DirectModels.__init__

    def counting(self, *args, **kwargs):
        made.append(1)
        original(self, *args, **kwargs)

    monkeypatch.setattr(models.DirectModels, "__init__", counting)
    y1, fallback1, solved1 = refrigerant.solve_direct(AC, _X1)
    y2, fallback2, solved2 = refrigerant.solve_direct(AC, _X2)
    assert solved1 and solved2 and not fallback1 and not fallback2
    assert len(made) == 1  # the bench models (and the saturation curve) made once, not per solve
    assert ("warm", "ac") in refrigerant.memo
    # The warm-started second solve gives a cold solve's targets (to the closures' tolerances).
    solver = refrigerant.memo[("solver", "cabin")]
    axes = MAPS["ac"].axes
    inputs = operating_inputs("ac", {a: np.array([v]) for a, v in zip(axes, _X2, strict=True)}, refrigerant.settings)
    from evtms.cycle.solver import OperatingPoints

    cold, _, _ = map_values(solver.solve(OperatingPoints(**inputs)))
    assert y2 == pytest.approx(cold[0], rel=1e-4)


def test_a_point_within_the_tolerance_is_reused(refrigerant):
    y1, _, solved1 = refrigerant.solve_direct(AC, _X1)
    y2, _, solved2 = refrigerant.solve_direct(AC, _X1 + np.array([0.005, 0, 0, 0, 0.05, 0]))
    assert solved1 and not solved2
    assert np.array_equal(y1, y2)
