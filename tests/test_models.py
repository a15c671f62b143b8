"""The simulator's three models (issue 16): LUT maps, physics solved in the loop, mode-model surrogates.

The refrigerant maps are test_simulate's synthetic ones. The physics model's
resumable loop is checked by a stand-in solver that returns the maps' own
value at the requested inputs: with zero tolerance the physics run must
reproduce the LUT run bit for bit; the surrogate loop by networks whose
output is known in closed form.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system.maps import map_interp
from evtms.system.mode_model import (
    DYNAMICS_FEATURES,
    DYNAMICS_TARGETS,
    POWER_FEATURES,
    STATE_NAMES,
    ModeModels,
    Network,
    training_pairs,
)
from evtms.system.refrigerant import MAP_NAMES, Refrigerant
from evtms.system.simulate import check_model, simulate
from tests.test_simulate import WLTC, parked
from tests.test_simulate import refrigerant as _refrigerant_fixture  # noqa: F401 - the module's fixture

refrigerant = _refrigerant_fixture
SHORT = dataclasses.replace(WLTC, time=WLTC.time[:401], speed=WLTC.speed[:401], grade=WLTC.grade[:401])


class MapPhysics(Refrigerant):
    """Physics stand-in: the 'direct solve' is the map itself, so physics and LUT runs must agree."""

    def solve_direct(self, map_id, x):
        name = MAP_NAMES[map_id]
        n = len(self.maps[name].axes)
        y = np.zeros(L.N_Y)
        map_interp(*self.maps[name].packed(), np.ascontiguousarray(x[:n]), y)
        self.memo.setdefault("calls", []).append(map_id)
        return y, False, True

    def check_physics(self):
        pass


def _physics(refrigerant: Refrigerant, tol: float | None) -> MapPhysics:
    """The stand-in, with every input tolerance ``tol`` (None: the model's own, PHYSICS_TOLERANCE)."""
    phys = MapPhysics(refrigerant.maps, refrigerant.sat_T, refrigerant.sat_p, refrigerant.coolant_mdot_max)
    if tol is not None:
        object.__setattr__(phys, "tolerances", lambda: np.full((3, 6), tol))
    return phys


@pytest.mark.parametrize("T_amb, soak", [(308.15, 318.15), (268.15, None)])
def test_physics_with_zero_tolerance_reproduces_the_lut_run_exactly(refrigerant, T_amb, soak):
    lut = simulate(SHORT, T_amb, refrigerant, sun=600.0, soak_cabin=soak)
    phys = _physics(refrigerant, 0.0)
    r = simulate(SHORT, T_amb, phys, sun=600.0, soak_cabin=soak, model="physics")
    for name, values in lut.records.items():
        np.testing.assert_array_equal(r.records[name], values, err_msg=name)
    np.testing.assert_array_equal(r.mode, lut.mode)
    compressor_steps = int(np.sum(lut.records["compressor_speed"][1:] > 0))
    # Every compressor step is one request (the stand-in never reuses): the resume does not skip or repeat.
    assert r.summary["physics_solves"] == compressor_steps == len(phys.memo.get("calls", []))
    if T_amb > 300:
        assert compressor_steps > 100


def test_physics_tolerance_trades_solves_for_a_bounded_difference(refrigerant):
    lut = simulate(SHORT, 308.15, refrigerant, sun=600.0, soak_cabin=318.15)
    loose = simulate(SHORT, 308.15, _physics(refrigerant, None), sun=600.0, soak_cabin=318.15, model="physics")
    assert 0 < loose.summary["physics_solves"] < 0.5 * np.sum(lut.records["compressor_speed"] > 0)
    # Inputs held within 0.02 (commands) and 0.25 K of the solved point: the cabin stays within half a kelvin.
    assert np.max(np.abs(loose.records["T_cabin"] - lut.records["T_cabin"])) < 0.5
    assert loose.ledgers["cabin"] < 1e-9 and loose.ledgers["refrigerant"] < 1e-9


def _random_network(rng, n_in, n_out, activation, widths=(7, 5)):
    sizes = [n_in, *widths, n_out]
    return Network(
        activation,
        [rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)],
        [rng.normal(size=b) for b in sizes[1:]],
        rng.normal(size=n_in),
        rng.uniform(0.5, 2.0, n_in),
        rng.normal(size=n_out),
        rng.uniform(0.5, 2.0, n_out),
        np.full(n_in, -1.0),
        np.full(n_in, 1.0),
    )


@pytest.mark.parametrize("activation", ["relu", "tanh"])
def test_compiled_network_equals_numpy_inference_and_flags_its_range(activation):
    rng = np.random.default_rng(3)
    net = _random_network(rng, 6, 4, activation)
    packed = np.concatenate([np.zeros(5), net.packed()])
    h0, h1, out = np.empty(L._MLP_WIDTH), np.empty(L._MLP_WIDTH), np.empty(4)
    for x in rng.uniform(-1.5, 1.5, (50, 6)):
        outside = L.mlp_eval(packed, 5, x, out, h0, h1)
        np.testing.assert_allclose(out, net.predict(x)[0], rtol=1e-12, atol=1e-12)
        assert outside == bool(np.any(np.abs(x) > 1.0))


def _constant(n_in: int, values, lo=-1e12, hi=1e12) -> Network:
    """A network whose output is ``values`` whatever its input (zero weights)."""
    values = np.asarray(values, float)
    return Network(
        "relu",
        [np.zeros((n_in, 3)), np.zeros((3, values.size))],
        [np.zeros(3), np.zeros(values.size)],
        np.zeros(n_in),
        np.ones(n_in),
        values,
        np.ones(values.size),
        np.full(n_in, lo),
        np.full(n_in, hi),
    )


def test_surrogate_integrates_the_predicted_rates_and_powers_the_battery(refrigerant):
    rates = np.zeros(len(STATE_NAMES))
    rates[STATE_NAMES.index("T_battery")] = 1e-3  # K/s
    rates[STATE_NAMES.index("T_cabin")] = -2e-3
    models = ModeModels(
        {L.BC: _constant(len(POWER_FEATURES), [1500.0])},
        {L.BC: _constant(len(DYNAMICS_FEATURES), rates)},
    )
    off = simulate(parked(600.0), 303.15, refrigerant, mode="off")
    r = simulate(parked(600.0), 303.15, refrigerant, mode="bc", model="surrogate", mode_models=models)
    t = r.records["time"]
    np.testing.assert_allclose(r.records["T_battery"], 303.15 + 1e-3 * t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.records["T_cabin"], 303.15 - 2e-3 * t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.records["T_coolant"], 303.15, rtol=0, atol=1e-12)
    # The compressor runs (BC), and its predicted power plus pump and fan load the battery.
    on = r.records["compressor_speed"][1:] > 0
    assert on.all()
    np.testing.assert_allclose(r.records["P_compressor"][1:], 1500.0)
    assert r.summary["battery_energy_kWh"] > off.summary["battery_energy_kWh"] + 1500.0 * 600 / 3.6e6 * 0.99
    # The filtered heat flows are the model's states (rate 0 here); what it does not model is NaN.
    np.testing.assert_array_equal(r.records["Q_evaporator"][1:], 0.0)
    assert np.all(np.isnan(r.records["Q_condenser"][1:])) and np.all(np.isnan(r.records["p_discharge"][1:]))
    assert set(r.ledgers) == {"vehicle", "battery_electrical", "system"} and max(r.ledgers.values()) < 1e-9
    assert r.summary["surrogate_out_of_range_fraction"] == 0.0


def test_surrogate_flags_steps_outside_the_training_range(refrigerant):
    n_p, n_d = len(POWER_FEATURES), len(DYNAMICS_FEATURES)
    rate = np.zeros(len(STATE_NAMES))
    rate[0] = 0.01  # the battery warms 1 K per 100 s; trained up to 305 K
    hi = np.full(n_d, 1e12)
    hi[0] = 305.0
    models = ModeModels({L.OFF: _constant(n_p, [0.0])}, {L.OFF: _constant(n_d, rate, hi=1e12)})
    models.dynamics[L.OFF] = dataclasses.replace(models.dynamics[L.OFF], x_max=hi)
    r = simulate(parked(600.0), 300.15, refrigerant, mode="off", model="surrogate", mode_models=models)
    flagged = (r.flags & L.F_SURROGATE_OOR) > 0
    beyond = r.records["T_battery"] > 305.0 + 0.01  # a step starting beyond 305 K
    assert flagged[1:].any() and not flagged[1:40].any()
    assert np.all(flagged[beyond][1:])
    assert 0.0 < r.summary["surrogate_out_of_range_fraction"] < 1.0


def test_surrogate_refuses_models_that_lack_a_mode_it_may_need(refrigerant):
    n_p, n_d = len(POWER_FEATURES), len(DYNAMICS_FEATURES)
    models = ModeModels({L.CC: _constant(n_p, [0.0])}, {L.CC: _constant(n_d, np.zeros(len(STATE_NAMES)))})
    check_model("surrogate", "cc", models, refrigerant)
    with pytest.raises(EvtmsInputError, match="lack mode.*BC"):
        check_model("surrogate", "bc", models, refrigerant)
    with pytest.raises(EvtmsInputError, match="that mode auto can use"):
        check_model("surrogate", "auto", models, refrigerant)
    with pytest.raises(EvtmsInputError, match="needs mode models"):
        check_model("surrogate", "cc", None, refrigerant)
    with pytest.raises(EvtmsInputError, match="unknown; allowed: lut, physics, surrogate"):
        check_model("neural", "cc", None, refrigerant)


def test_training_pairs_are_the_loop_steps_split_by_mode(refrigerant):
    r = simulate(SHORT, 308.15, refrigerant, sun=600.0, soak_cabin=318.15, keep_trace=True)
    pairs = training_pairs(r.trace)
    assert sum(p[0].shape[0] for p in pairs.values()) == r.trace["dts"].size
    for code, (xp, yp, xd, yd) in pairs.items():
        assert xp.shape[1] == len(POWER_FEATURES) and xd.shape[1] == len(DYNAMICS_FEATURES)
        assert yp.shape[1] == 1 and yd.shape[1] == len(DYNAMICS_TARGETS)
        assert np.all(np.isfinite(xd)) and np.all(np.isfinite(yd))
        if code == L.OFF:
            np.testing.assert_array_equal(yp, 0.0)
    # Rates times dt integrate back to the states.
    states, dts, modes = r.trace["states"], r.trace["dts"], r.trace["modes"]
    code = int(modes[10])
    k = int(np.sum(modes[:10] == code))
    col = STATE_NAMES.index("T_cabin")
    step = pairs[code][3][k, col] * dts[10]
    assert step == pytest.approx(states[11, L.S_TA] - states[10, L.S_TA], rel=1e-12, abs=1e-15)


def test_surrogate_holds_a_state_its_mode_never_moved_and_keeps_flows_non_negative(refrigerant):
    n_p, n_d = len(POWER_FEATURES), len(DYNAMICS_FEATURES)
    rates = np.zeros(len(STATE_NAMES))
    rates[STATE_NAMES.index("T_coolant")] = 1e-2  # predicted, but the coolant never moved in training
    rates[STATE_NAMES.index("Q_chiller")] = -5.0  # would go below zero
    rates[STATE_NAMES.index("T_battery")] = 1e-3
    dyn = _constant(n_d, rates)
    lo, hi = dyn.x_min.copy(), dyn.x_max.copy()
    k = STATE_NAMES.index("T_coolant")
    lo[k] = hi[k] = 303.15
    models = ModeModels({L.OFF: _constant(n_p, [0.0])}, {L.OFF: dataclasses.replace(dyn, x_min=lo, x_max=hi)})
    r = simulate(parked(300.0), 303.15, refrigerant, mode="off", model="surrogate", mode_models=models)
    np.testing.assert_array_equal(r.records["T_coolant"], 303.15)
    np.testing.assert_allclose(r.records["T_battery"][-1], 303.15 + 0.3, atol=1e-9)
    assert np.all(r.records["Q_chiller"][1:] >= 0.0)
    assert not np.any(r.flags & L.F_SURROGATE_OOR)
