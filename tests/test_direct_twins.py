"""The bench physics' compiled twins as the cycle closure's iterations read them (DirectModels).

``DirectModels`` answers the closure's iterations from the benches' compiled twins
(:mod:`evtms.cycle._direct_kernel`) and its final states from the bench functions: both must give
the same values, the same "no heat flows" and the same reasons, also where a point fails, and the
twins must leave to the bench what only it decides (states beyond the tables, non-finite inputs).
"""

import numpy as np
import pytest

from evtms.benches.parameters import Parameters
from evtms.cycle.models import DirectModels, _twin_outputs
from evtms.fluid import Fluid

N = 400


@pytest.fixture(scope="module")
def models():
    return DirectModels(Parameters(), Fluid())


def _inputs(component: str, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Random bench calls over and beyond a cycle's envelope, a few of them not finite."""
    u = lambda lo, hi: rng.uniform(lo, hi, N)  # noqa: E731
    if component == "compressor":
        out = {"speed": u(0.05, 1.0), "T_in": u(230.0, 350.0), "p_in": u(0.5e5, 1.2e6), "pr": u(1.0, 20.0)}
    elif component in ("condenser", "evaporator"):
        air = "fan" if component == "condenser" else "blower"
        out = {"mdot": u(0.0, 0.12), air: u(0.02, 1.0), "p_in": u(0.6e5, 4.2e6), "h_in": u(150e3, 520e3)}
        out["T_air_in"] = out["T_res"] = u(253.15, 323.15)
        out["RH_air_in"] = u(0.1, 0.9)
    else:
        out = {"mdot": u(0.0, 0.12), "p_in": u(0.6e5, 4.2e6), "h_in": u(150e3, 520e3)}
        out["mdot_coolant"], out["T_coolant_in"] = u(0.0, 0.4), u(240.0, 350.0)
    for v in out.values():  # some not finite, as a failed upstream component leaves them
        v[rng.choice(N, 8, replace=False)] = np.nan
    return out


COMPONENTS = ["compressor", "condenser", "evaporator", "chiller", "wcc"]


@pytest.mark.parametrize("component", COMPONENTS)
def test_the_twins_answer_as_the_bench(models, component):
    inputs = _inputs(component, np.random.default_rng(COMPONENTS.index(component)))
    if component in ("condenser", "evaporator"):  # one air state per call, as a solve calls a coil
        for k in ("T_air_in", "T_res", "RH_air_in", "fan", "blower"):
            if k in inputs:
                inputs[k][:] = inputs[k][0]
    bench = models._run_bench(component, {k: v.copy() for k, v in inputs.items()}, N)
    asked = []
    real = DirectModels._run_bench
    with pytest.MonkeyPatch.context() as mp:  # what the twins leave to the bench: beyond the tables
        mp.setattr(DirectModels, "_run_bench", lambda self, c, x, n: asked.append(n) or real(self, c, x, n))
        twins = models._run_twins(component, {k: v.copy() for k, v in inputs.items()}, N)
    assert 0 < sum(asked) < N / 2
    valid = np.isfinite(bench[_twin_outputs(component)[0]])
    assert 0.1 < valid.mean() < 1.0  # valid points and failing ones both
    for key in _twin_outputs(component):
        np.testing.assert_array_equal(twins[key], bench[key], err_msg=key)
    np.testing.assert_array_equal(twins["no_heat_flow"], bench["no_heat_flow"])
    np.testing.assert_array_equal(twins["reason"], bench["reason"])
    if component == "evaporator":
        np.testing.assert_array_equal(twins["frost_risk"], bench["frost_risk"])
        assert "Q_latent" not in twins  # the bench's alone (its fog correction): the final states'


def test_the_closure_iterates_on_the_twins_and_ends_on_the_bench(models, monkeypatch):
    """A solve's iterations call the twins; its final states the bench functions, every variable."""
    from evtms.cycle.solver import CycleSolver, OperatingPoints
    from evtms.fluid import SaturationCurve

    calls = {"twins": 0, "bench": 0}
    for name in calls:
        real = getattr(DirectModels, f"_run_{name}")
        monkeypatch.setattr(
            DirectModels,
            f"_run_{name}",
            lambda self, *a, _r=real, _n=name: calls.__setitem__(_n, calls[_n] + 1) or _r(self, *a),
        )
    solver = CycleSolver(models, SaturationCurve(models.fluid), "cabin", closure="python")
    res = solver.solve(OperatingPoints(speed=0.6, fan=0.5, blower=0.4, T_amb=303.15, T_cabin=300.15))
    assert res.status[0] == 0 and np.isfinite(res["Q_latent"][0])
    assert calls["twins"] > 10 * calls["bench"] > 0
