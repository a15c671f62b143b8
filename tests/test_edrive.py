"""E-drive coolant loop (spec v2 5): the four-node network against its exact solution, the jackets, the radiator
table, the pump and fan tables and the relay, the DC-DC loss, and the first model kept as an option.

The drive-cycle cases run on :mod:`test_simulate`'s synthetic cycle maps, which close their energy balance
exactly, so what is checked here is the loop itself.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg
from test_simulate import params, refrigerant  # noqa: F401 - the synthetic maps' fixture

from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import drive_cycle
from evtms.system.edrive import CORE_AIR, CORE_NODES, MOTOR_REQUIREMENT, EdriveParams, core_table, jacket_slots
from evtms.system.params import SystemParams
from evtms.system.simulate import declared_slots, simulate

HWFET = drive_cycle("hwfet")


def _par(system: SystemParams) -> np.ndarray:
    """The loop's parameters the e-drive network reads (declared and jacket slots)."""
    k = system.coolant
    slots = declared_slots(system) | jacket_slots(system.edrive, k.density, k.cp, k.viscosity, k.conductivity)
    par = np.zeros(L.N_P)
    for name, value in slots.items():
        par[getattr(L, f"P_{name}")] = value
    return par


def test_network_follows_its_matrix_exponential():
    # Parked at 0 degC, the motor heated by 1 kW, the DC-DC by 40 W, the radiator bypassed and the pump held at
    # half flow: a linear 4-node network C dT/dt = A T + b, whose exact solution is T_ss + expm(C^-1 A t) (T0 - T_ss).
    system = SystemParams()
    par = _par(system)
    f_inv = par[L.P_F_INV]
    p_loss, q_dcdc, T_amb, dt = 1000.0 / (1.0 - f_inv), 40.0, 273.15, 0.1
    g_m, g_d = L.jacket_conductances(par, 0.5)
    assert g_m > 20.0 and g_d > 10.0
    caps = np.array([par[L.P_C_M], par[L.P_C_I], par[L.P_C_D], par[L.P_C_E]])
    k1 = par[L.P_K1_M]
    A = np.array(
        [
            [-(g_m + k1), 0.0, 0.0, g_m],
            [0.0, -g_d, 0.0, g_d],
            [0.0, 0.0, -g_d, g_d],
            [g_m, g_d, g_d, -(g_m + 2 * g_d)],
        ]
    )
    b = np.array([1000.0 + k1 * T_amb, f_inv * p_loss, q_dcdc, 0.0])
    M = A / caps[:, None]
    T_ss = np.linalg.solve(A, -b)
    T0 = np.full(4, T_amb)
    s0, s1 = np.zeros(L.N_S), np.zeros(L.N_S)
    cols = [L.S_TM, L.S_TI, L.S_TD, L.S_TE]
    s0[cols] = T0
    worst = 0.0
    for n in range(1, 36001):  # one hour
        q_rad = L.edrive_network(par, s0, s1, dt, T_amb, p_loss, q_dcdc, g_m, g_d, 0.0, T_amb, 0.0)
        assert q_rad == 0.0
        s0, s1 = s1, s0
        if n % 600 == 0:
            exact = T_ss + scipy.linalg.expm(M * n * dt) @ (T0 - T_ss)
            worst = max(worst, float(np.max(np.abs(s0[cols] - exact))))
    assert worst <= 0.05
    assert s0[L.S_TM] - T_amb > 20.0  # the motor did warm: the check is not of a network at rest


def test_jacket_conductance_rises_with_flow_and_joins_its_laminar_and_turbulent_forms():
    j = jacket_slots(EdriveParams(), 1070.0, 3300.0, 3.8e-3, 0.38)
    re1, pr, dl, ka = j["JACKET_M_RE1"], j["JACKET_PR"], j["JACKET_M_DL"], j["JACKET_M_KA"]
    u = np.linspace(0.01, 1.0, 200)
    g = np.array([L.jacket_conductance(x, re1, pr, dl, ka) for x in u])
    assert np.all(np.diff(g) > 0)
    assert L.jacket_conductance(0.0, re1, pr, dl, ka) == pytest.approx(2.0 * ka)  # stagnant channels
    # Continuous where the blend begins (Re 2300) and ends (Re 4000).
    for re in (2300.0, 4000.0):
        lo, hi = (L.jacket_conductance(re * (1 + s) / re1, re1, pr, dl, ka) for s in (-1e-9, 1e-9))
        assert hi == pytest.approx(lo, rel=1e-6)
    # The spec's motor jacket: 30 / 36 / 78 W/K at pump 0.3 / 0.5 / 1 (its properties differ a little).
    for x, spec in ((0.3, 30.0), (0.5, 36.0), (1.0, 78.0)):
        assert L.jacket_conductance(x, re1, pr, dl, ka) == pytest.approx(spec, rel=0.2)


@pytest.mark.parametrize("component", ["radiator", "heater_core"])
def test_core_table_is_the_bench_at_its_nodes(component, tmp_path, monkeypatch):
    from evtms.benches.liquid_coil import solve_liquid_coil
    from evtms.benches.parameters import Parameters
    from evtms.params import Environment

    monkeypatch.setenv("EVTMS_CACHE_DIR", str(tmp_path))
    knots, starts, table = core_table(component)
    again = core_table(component)[2]  # from the cache now
    assert np.array_equal(table, again) and any(tmp_path.iterdir())
    nodes = CORE_NODES[component]
    shape = tuple(len(v) for v in nodes.values())
    ua = table[:, 0].reshape(shape)
    assert np.all(np.isfinite(ua)) and np.all(ua > 0)
    rng = np.random.default_rng(7)
    idx = [tuple(int(rng.integers(n)) for n in shape) for _ in range(5)]
    m, T, V = (np.array([nodes[a][i[k]] for i in idx]) for k, a in enumerate(nodes))
    core = getattr(Parameters(), component)
    bench = solve_liquid_coil(core, Environment(), m, T, V, *(np.full(5, v) for v in CORE_AIR))
    assert np.array_equal(np.array([ua[i] for i in idx]), bench["UA"])
    # More air and more coolant conduct more.
    assert np.all(np.diff(ua, axis=2) > 0) and np.all(np.diff(ua, axis=0) > 0)


def test_hwfet_at_40C_motor_below_its_limit_pump_fan_and_radiator_follow_their_tables(refrigerant):  # noqa: F811
    r = simulate(HWFET, 313.15, refrigerant, dt=1.0, keep_trace=True)
    assert max(r.ledgers.values()) <= 1e-9, r.ledgers
    st, out = r.trace["states"], r.trace["out"]
    T_m, T_E = st[:-1, L.S_TM], st[:-1, L.S_TE]  # at each step's start, what the controls saw
    assert r.summary["T_motor_max_degC"] < 130.0
    assert st[-1, L.S_TM] > 313.15 + 5.0 and st[-1, L.S_TE] > 313.15  # the drive's heat reached the loop
    need = np.interp(T_m, MOTOR_REQUIREMENT["T_motor"], MOTOR_REQUIREMENT["command"])
    u = out[:, L.O_U_PUMP_E]
    working = u > 0.0  # the drive works, or the motor needs flow; standing with a cool motor the pump stops
    assert working.mean() > 0.9
    assert np.allclose(u[working], np.clip(need[working], EdriveParams().pump_min, 1.0), rtol=0, atol=1e-12)
    assert np.all(need[~working] == 0.0)
    assert np.all(out[:, L.O_FAN] >= need - 1e-12)
    # The radiator joins above 35 degC, leaves below 20 degC, and never switches between.
    rad = out[:, L.O_RAD_IN]
    on = np.flatnonzero(np.diff(rad) > 0) + 1
    off = np.flatnonzero(np.diff(rad) < 0) + 1
    assert rad[0] == 1.0 and T_E[0] > 308.15  # a 40 degC loop has its radiator in from the start
    assert np.all(T_E[on] > 308.15) and np.all(T_E[off] < 293.15)
    assert np.all(out[rad == 0, L.O_Q_RAD] == 0.0)
    # Heat flows from the warmer stream: behind a working condenser the air can be the warmer one.
    gap = st[1:, L.S_TE] - out[:, L.O_T_AIR_RAD]
    assert np.all(out[:, L.O_Q_RAD] * gap >= 0.0) and np.any(out[rad == 1, L.O_Q_RAD] > 0.0)
    # The condenser ahead of the radiator warms its air.
    cond = out[:, L.O_Q_COND] > 100.0
    assert np.all(out[cond & (rad == 1) & working, L.O_T_AIR_RAD] > 313.15)


def test_low_voltage_loads_pay_the_dcdc_loss_and_heat_it(refrigerant):  # noqa: F811
    r = simulate(drive_cycle("wltc3b"), 303.15, refrigerant, dt=1.0, keep_trace=True)
    out = r.trace["out"]
    eta = EdriveParams().dcdc_efficiency
    lv = out[:, L.O_P_BLOWER] + out[:, L.O_P_FAN] + out[:, L.O_P_PUMP] + out[:, L.O_P_PUMP_H]
    hv = out[:, L.O_P_COMPRESSOR] + out[:, L.O_P_PTC] + out[:, L.O_P_PTCW] + out[:, L.O_P_HEATER]
    assert np.allclose(out[:, L.O_P_HVAC], hv + lv / eta, rtol=1e-12, atol=1e-9)
    assert np.allclose(out[:, L.O_Q_DCDC], (lv + out[:, L.O_P_PUMP_E]) * (1.0 / eta - 1.0), rtol=1e-12, atol=1e-9)
    assert np.sum(out[:, L.O_Q_DCDC]) > 0.0
    assert r.ledgers["edrive"] <= 1e-9 and r.ledgers["system"] <= 1e-9


def test_ambient_model_is_the_first_system_model(refrigerant):  # noqa: F811
    p = params(edrive={"model": "ambient"})
    r = simulate(HWFET, 303.15, refrigerant, p, dt=1.0, keep_trace=True)
    out, st = r.trace["out"], r.trace["states"]
    assert max(r.ledgers.values()) <= 1e-9
    assert np.all(out[:, L.O_Q_DCDC] == 0.0) and np.all(out[:, L.O_P_PUMP_E] == 0.0)
    assert np.all(st[:, [L.S_TM, L.S_TI, L.S_TD, L.S_TE]] == 303.15)
    parts = (L.O_P_COMPRESSOR, L.O_P_PTC, L.O_P_PTCW, L.O_P_HEATER, L.O_P_BLOWER, L.O_P_FAN, L.O_P_PUMP, L.O_P_PUMP_H)
    assert np.allclose(out[:, L.O_P_HVAC], sum(out[:, c] for c in parts), rtol=1e-12, atol=1e-9)
    loop = simulate(HWFET, 303.15, refrigerant, dt=1.0)
    assert loop.summary["edrive_cooling_kWh"] > 0.0 and r.summary["edrive_cooling_kWh"] == 0.0


def test_edrive_parameters_are_checked():
    from evtms.errors import EvtmsInputError

    with pytest.raises(EvtmsInputError, match="radiator_off"):
        params(edrive={"radiator_off": 320.0})
    with pytest.raises(EvtmsInputError, match="model"):
        params(edrive={"model": "oil"})
    assert dataclasses.replace(EdriveParams(), dcdc_efficiency=1.0).dcdc_efficiency == 1.0
