"""The controller interface and the predictive cabin controller.

The interface tests run on the synthetic maps of ``test_simulate.py``; the
MPC's on cycle maps built from the session's cycle LUTs (2-3 nodes per axis,
as ``test_climate.py``) and need the optional extra ``mpc`` (CasADi).
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
from conftest import one_error_line
from test_climate import cycle_maps, first, parked  # noqa: F401 - cycle_maps: the small maps' module fixture
from test_simulate import refrigerant as synthetic  # noqa: F401 - the module fixture of synthetic maps
from typer.testing import CliRunner

from evtms.cli import app
from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system.controllers import Decision, period_steps
from evtms.system.drive_cycles import drive_cycle
from evtms.system.simulate import simulate

runner = CliRunner()
WLTC = drive_cycle("wltc3b")


class Fixed:
    """A supervisor that always decides the same (NaN and not ok: it always falls back)."""

    name = "fixed"

    def __init__(self, T_vent: float, blower: float, ok: bool = True, period: float = 10.0) -> None:
        self.T_vent, self.blower, self.ok, self.period = T_vent, blower, ok, period
        self.calls: list[int] = []

    def start(self, context) -> None:
        self.context = context

    def decide(self, n, state, history) -> Decision:
        self.calls.append(n)
        return Decision(self.T_vent, self.blower, 1e-3, self.ok)


def test_periods_start_where_the_clock_crosses_a_multiple_of_the_period():
    assert period_steps(np.arange(0.0, 101.0), 10.0).tolist() == list(range(0, 100, 10))
    edges = np.array([0.0, 4.0, 8.0, 12.0, 16.0, 20.0, 24.0])  # 4-s steps, 10-s periods: at 0, 12 and 20 s
    assert period_steps(edges, 10.0).tolist() == [0, 3, 5]


def test_a_supervisor_writes_what_the_same_inputs_give(synthetic):  # noqa: F811
    """Period by period, a supervisor's constant set points give the run of those set points as inputs, bit for
    bit, and the loop's vent target is the given one."""
    cycle, T = first(WLTC, 300.0), 308.15
    sup = Fixed(287.15, 0.7)
    a = simulate(cycle, T, synthetic, sun=600.0, controller=sup, keep_trace=True)
    b = simulate(cycle, T, synthetic, sun=600.0, inputs={"SP_vent": 287.15, "blower": 0.7}, keep_trace=True)
    assert sup.calls == list(range(0, 300, 10))
    np.testing.assert_array_equal(a.trace["states"], b.trace["states"])
    np.testing.assert_array_equal(a.trace["out"], b.trace["out"])
    assert np.all(a.trace["out"][:, L.O_T_VENT_TARGET] == 287.15)
    assert a.summary["controller"] == "fixed" and a.summary["controller_decisions"] == 30


def test_a_supervised_run_stops_where_the_same_inputs_stop_it(synthetic):  # noqa: F811
    """SOC reaches its floor inside a period: the supervised run ends at the step the same set points as inputs
    end it, with the same states (the runner stops, it does not run the next period)."""
    from test_simulate import params

    low = params(battery={"soc_init": 0.0505, "soc_min": 0.05})
    a = simulate(WLTC, 308.15, synthetic, low, sun=600.0, controller=Fixed(287.15, 0.7), keep_trace=True)
    b = simulate(WLTC, 308.15, synthetic, low, sun=600.0, inputs={"SP_vent": 287.15, "blower": 0.7}, keep_trace=True)
    assert a.summary["termination"] == b.summary["termination"] == "soc_min"
    assert a.summary["steps"] == b.summary["steps"] < WLTC.time[-1] and a.summary["steps"] % 10 != 0
    np.testing.assert_array_equal(a.trace["states"], b.trace["states"])


def test_a_failed_decision_hands_the_period_to_the_rules_with_a_flag(synthetic):  # noqa: F811
    cycle, T = first(WLTC, 200.0), 308.15
    a = simulate(cycle, T, synthetic, sun=600.0, controller=Fixed(math.nan, math.nan, ok=False), keep_trace=True)
    rules = simulate(cycle, T, synthetic, sun=600.0, keep_trace=True)
    np.testing.assert_array_equal(a.trace["states"], rules.trace["states"])
    assert np.all(a.trace["flags"] & L.F_CONTROLLER_FALLBACK)
    assert not np.any(rules.trace["flags"] & L.F_CONTROLLER_FALLBACK)
    assert a.summary["controller_fallbacks"] == 20


def test_a_vent_target_below_freezing_cannot_frost_the_coil(synthetic):  # noqa: F811
    """The supervisor's vent target passes through the rules' evaporator loop and frost relay: asking for 0 degC
    air at full blower for 10 min, the evaporator air stays above the relay's cutoff less its 1-step lag."""
    r = simulate(first(WLTC, 600.0), 308.15, synthetic, sun=600.0, controller=Fixed(273.15, 1.0), keep_trace=True)
    par, out = r.trace["par"], r.trace["out"]
    assert np.nanmin(out[:, L.O_T_EVAP_AIR]) >= par[L.P_TFR_OFF] - 0.5
    assert np.nanmin(out[:, L.O_T_VENT_TARGET]) >= par[L.P_TV_MIN]


# -- the MPC ---------------------------------------------------------------------------------------------------


def _mpc(**options):
    pytest.importorskip("casadi")
    from evtms.system.mpc import CabinMpc, MpcOptions

    return CabinMpc(MpcOptions(**options))


@pytest.mark.parametrize(("T_amb_c", "sun"), [(35.0, 600.0), (-10.0, 0.0)])
def test_mpc_keeps_every_limit_on_a_short_trace(cycle_maps, T_amb_c, sun):  # noqa: F811
    """WLTC's first 10 min: the blower within its range, the vent target within the vent's, no frost, no PTC in
    the heat and no compressor on the cabin coil in the cold, every decision solved in time, ledgers closed."""
    mpc = _mpc(time_budget=10.0)  # a loaded machine must not turn a solve into a fallback here
    r = simulate(first(WLTC, 600.0), T_amb_c + 273.15, cycle_maps, sun=sun, controller=mpc, keep_trace=True)
    par, out, s = r.trace["par"], r.trace["out"], r.summary
    climate = out[:, L.O_MDOT_AIR] > 0
    assert climate.all()
    blower = out[:, L.O_BLOWER]
    assert blower.min() >= par[L.P_BLOWER_MIN] - 1e-9 and blower.max() <= 1.0 + 1e-9
    tv = out[:, L.O_T_VENT_TARGET]
    assert tv.min() >= par[L.P_TV_MIN] and tv.max() <= par[L.P_TV_MAX]
    running = out[:, L.O_COMP_ON] > 0.5
    assert not running.any() or out[running, L.O_T_EVAP_AIR].min() >= par[L.P_TFR_OFF] - 0.5
    assert s["controller_fallbacks"] == 0 and s["controller_decisions"] == 60
    assert s["ledger_worst"] < 1e-9
    if T_amb_c > 20:
        assert np.all(out[:, L.O_P_PTC] == 0.0)
        assert s["T_cabin_end_degC"] < 24.0  # pulled down from 35 degC
    else:
        assert np.all(out[:, L.O_Q_EVAP] == 0.0)
        assert s["T_cabin_end_degC"] > 10.0  # warming from -10 degC


def test_a_solve_over_its_time_budget_falls_back_to_the_rules(cycle_maps):  # noqa: F811
    """A budget no solve meets (1 ms): every period runs on the rules, flagged, and the run is the rules' own."""
    cycle = first(WLTC, 120.0)
    r = simulate(cycle, 308.15, cycle_maps, sun=600.0, controller=_mpc(time_budget=1e-3), keep_trace=True)
    rules = simulate(cycle, 308.15, cycle_maps, sun=600.0, keep_trace=True)
    s = r.summary
    assert s["controller_fallbacks"] == s["controller_decisions"] == 12
    assert np.all(r.trace["flags"] & L.F_CONTROLLER_FALLBACK)
    np.testing.assert_array_equal(r.trace["states"], rules.trace["states"])


def test_mpc_prediction_follows_the_plant_over_its_horizon(cycle_maps):  # noqa: F811
    """The prediction model, fed the plant's own blower and duties (means per MPC step) and its motor power,
    predicts the cabin air of the next 3 min within 0.5 K (at 35 degC with sun after 5 min of pull-down, and at
    -10 degC) and, where the MPC cools it, the battery within 0.2 K."""
    for T_amb, sun in ((308.15, 600.0), (263.15, 0.0)):
        r = simulate(first(WLTC, 600.0), T_amb, cycle_maps, sun=sun, keep_trace=True)
        st, out, dts = r.trace["states"], r.trace["out"], r.trace["dts"]
        mpc = _mpc()
        from evtms.system.controllers import ControlContext

        edges = np.concatenate(([0.0], np.cumsum(dts)))
        zeros = np.zeros(dts.size)
        motor = out[:, L.O_P_MOTOR_EL]  # the preview of the battery's load: the run's own
        mpc.start(ControlContext(r.trace["par"], edges, zeros, motor, zeros > 0, cycle_maps))
        n, N, m = 300, mpc.options.steps, 10
        window = out[n : n + N * m].reshape(N, m, -1).mean(axis=1)
        q_cool = window[:, L.O_Q_EVAP] - window[:, L.O_Q_LATENT]
        q_heat = window[:, L.O_P_PTC] + window[:, L.O_Q_HC]
        x = mpc.predict(n, st[n], out[:n], window[:, L.O_BLOWER], q_cool, q_heat, window[:, L.O_Q_CHILLER])
        plant = st[n + m : n + N * m + 1 : m]
        assert np.max(np.abs(x[:, 0] - plant[:, L.S_TA])) < 0.5, (T_amb, x[:, 0] - plant[:, L.S_TA])
        if T_amb > 295.15:  # the battery is the MPC's in the cooling season only (its heater stays the rules')
            assert np.max(np.abs(x[:, 5] - plant[:, L.S_TB])) < 0.2, (T_amb, x[:, 5] - plant[:, L.S_TB])


def test_mpc_options_out_of_range_are_one_line_errors():
    from evtms.system.mpc import MpcOptions

    for bad, text in (
        ({"horizon": 5.0}, "horizon 5.0"),
        ({"step": 0.1}, "step 0.1"),
        ({"preview": "psychic"}, "preview 'psychic'"),
        ({"horizon": 60.0, "step": 61.0}, "step 61"),
    ):
        with pytest.raises(EvtmsInputError, match=text):
            MpcOptions(**bad)


def test_mpc_without_its_extra_says_how_to_install_it(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "casadi", None)  # import casadi raises ImportError
    from evtms.system.mpc import make_controller

    with pytest.raises(EvtmsInputError, match=r"extra 'mpc'"):
        make_controller("mpc")
    out = tmp_path / "run.nc"
    res = runner.invoke(app, ["simulate", "--cycle", "udds", "--controller", "mpc", "-o", str(out)])
    assert res.exit_code == 2
    one_error_line(res, "extra 'mpc'", "controller rules")
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["simulate", "--cycle", "udds", "--controller", "pid"], ("controller 'pid'", "rules, mpc")),
        (["simulate", "--cycle", "udds", "--controller", "mpc", "--sp-vent", "15"], ("SP_vent", "controller")),
        (["simulate", "--cycle", "udds", "--controller", "mpc", "--sp-evap", "8"], ("SP_evap", "controller rules")),
        (["simulate", "--cycle", "udds", "--controller", "mpc", "--preview", "x"], ("preview 'x'", "perfect")),
        (["report", "compare", "--controllers", "rules,pid"], ("--controllers 'pid'", "rules, mpc")),
        (["simulate", "--cycle", "udds", "--t-amb", "25", "--speed-deviation", "-1"], ("delta_v_ref above 0",)),
        (["report", "compare", "--controllers", "rules", "--approaches", "lut"], ("--approaches",)),
    ],
)
def test_controller_options_refuse_bad_values(tmp_path, args, fragments):
    pytest.importorskip("casadi")
    out = tmp_path / "o"
    res = runner.invoke(app, [*args, "-o", str(out)])
    assert res.exit_code == 2, res.output
    one_error_line(res, *fragments)
    assert not out.exists()


def test_report_compare_controllers_writes_the_table_and_the_figures(small_maps, small_map_luts, tmp_path):
    """Two ambients, the rules and the MPC with and without preview: six rows, the savings against the rules'
    run of the same ambient, solve times for the MPC only, the table and one figure per ambient."""
    pytest.importorskip("casadi")
    out = tmp_path / "ctl"
    args = ["report", "compare", "--controllers", "rules,mpc", "--preview", "perfect,none", "--cycle", "parked:300"]
    res = runner.invoke(app, [*args, "--t-amb", "-10,35", "--luts", str(small_map_luts), "-o", str(out), "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)["rows"]
    assert [(r["T_amb_degC"], r["controller"]) for r in rows] == [
        (t, c) for t in (-10.0, 35.0) for c in ("rules", "mpc, preview perfect", "mpc, preview none")
    ]
    for r in rows:
        base = next(b for b in rows if b["T_amb_degC"] == r["T_amb_degC"] and b["controller"] == "rules")
        if r["controller"] == "rules":
            assert r["hvac_saving_pct"] is None and r["solve_mean_ms"] is None
        else:
            assert r["hvac_saving_pct"] == pytest.approx(100.0 * (1.0 - r["hvac_kWh"] / base["hvac_kWh"]))
            assert r["solve_mean_ms"] > 0.0 and r["fallbacks"] == 0
        assert r["sun_W_m2"] == (600.0 if r["T_amb_degC"] > 22.0 else 0.0)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["controllers.csv", "controllers_parked_300_-10degC.png", "controllers_parked_300_35degC.png"]
    from evtms.workflows.controllers import read_rows

    table = read_rows(out / "controllers.csv")
    assert [r["controller"] for r in table] == [r["controller"] for r in rows]
    assert float(table[1]["hvac_kWh"]) == pytest.approx(rows[1]["hvac_kWh"], rel=1e-5)


def test_a_given_battery_cooling_request_replaces_the_relay_but_not_the_safety_relays(synthetic):  # noqa: F811
    """BC_request 1 cools a 30 degC battery the relay (on at 35) leaves alone; 0 does not stop the critical
    relay cooling a 42 degC one; 1 cannot chill a 12 degC battery (below bc_T_battery_min: the safety relay)."""

    def chilled(T_amb, T_init, request):
        r = simulate(parked(600.0), T_amb, synthetic, T_init=T_init, inputs={"BC_request": request}, keep_trace=True)
        return r.trace["out"][:, L.O_Q_CHILLER] > 0.0, r.trace["flags"]

    rules = simulate(parked(600.0), 303.15, synthetic, T_init=303.15, keep_trace=True)
    assert not np.any(rules.trace["out"][:, L.O_Q_CHILLER] > 0.0)
    on, _ = chilled(303.15, 303.15, 1.0)
    assert on.mean() > 0.5
    critical, _ = chilled(308.15, 315.15, 0.0)
    assert critical.any()
    cold, flags = chilled(283.15, 285.15, 1.0)
    assert not cold.any() and np.any(flags & L.F_SAFETY_RELAY)


def test_the_mpc_chills_nothing_without_a_chiller_to_plan_with():
    """No chiller capacity (no map, or no point of it cooling): the request is the relay's (NaN), never a 1 that
    flips every minute."""
    pytest.importorskip("casadi")
    from evtms.system.mpc import CabinMpc

    mpc = CabinMpc()
    mpc.ctx = type("Ctx", (), {"edges": np.arange(0.0, 1000.0)})()
    mpc._chilling, mpc._chill_since = True, -math.inf
    assert all(math.isnan(mpc._chill_request(n, 0.0, 0.0)) for n in (0, 100, 200))
    assert not mpc._chilling
    assert mpc._chill_request(300, 2.0, 4.0) == 1.0  # above a quarter of a real capacity: on


def test_a_light_cooling_load_is_left_to_the_rules(cycle_maps):  # noqa: F811
    """25 degC without sun: the load needs vent air far warmer than the evaporator's ceiling, a duty the
    compressor meets only by cycling; the MPC hands every period to the rules, unflagged, and the run is theirs."""
    cycle = first(WLTC, 120.0)
    r = simulate(cycle, 298.15, cycle_maps, controller=_mpc(), keep_trace=True)
    rules = simulate(cycle, 298.15, cycle_maps, keep_trace=True)
    assert r.summary["controller_decisions"] == 0 and r.summary["controller_fallbacks"] == 0
    assert not np.any(r.trace["flags"] & L.F_CONTROLLER_FALLBACK)
    np.testing.assert_array_equal(r.trace["states"], rules.trace["states"])


def test_a_control_step_must_be_a_whole_number_of_time_steps(synthetic):  # noqa: F811
    from evtms.system.controllers import check_period

    check_period(10.0, 0.5)
    for period, dt in ((2.5, 1.0), (0.5, 1.0)):
        with pytest.raises(EvtmsInputError, match="whole multiple of the time step"):
            check_period(period, dt)
    with pytest.raises(EvtmsInputError, match="whole multiple"):
        simulate(first(WLTC, 60.0), 308.15, synthetic, dt=4.0, controller=Fixed(290.0, 0.5, period=10.0))
