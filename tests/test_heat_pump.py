"""The indirect heat pump in the simulator (spec v2 section 6): the hp circuit on the heater-core and e-drive loops,
its controller, backup, suction trips and lockout, the radiator as its source, frost, and every ledger.

The refrigerant loop runs on synthetic cycle maps (:mod:`test_simulate`'s, plus an ``hp`` map built here) that
close their energy balance exactly, so these tests check the simulator; the ``hp`` map of real LUTs is the
cycle solver's (``tests/test_cycle_hp.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_climate import first
from test_simulate import params, parked, refrigerant  # noqa: F401 - the synthetic maps' fixture

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import drive_cycle
from evtms.system.inputs import Trace
from evtms.system.maps import CycleMap
from evtms.system.simulate import simulate

WLTC = drive_cycle("wltc3b")


HP = {"hvac": {"heating": "heat_pump"}}


def hp_map(capacity: float = 1.0, suction: float = 1.0) -> CycleMap:
    """A heat pump whose chiller draws more with speed and a warmer source, its suction falling with both
    speed and a colder source; the water-cooled condenser gives the chiller's heat plus 0.9 of the work."""
    nodes = [
        np.array([0.1, 0.5, 1.0]),
        np.array([0.3, 1.0]),
        np.array([293.15, 343.15]),
        np.array([0.3, 1.0]),
        np.array([248.15, 273.15, 308.15]),
    ]
    speed, _, T_H, _, T_E = np.meshgrid(*nodes, indexing="ij")
    v = np.zeros((*speed.shape, 9))
    W = 2500.0 * speed * (1.0 + (T_H - 293.15) / 100.0)
    q_ch = capacity * 4000.0 * speed * np.clip((T_E - 233.15) / 60.0, 0.0, None)
    v[..., 0] = suction * 2.9e5 * np.exp(0.037 * (T_E - 283.15)) / (0.5 + speed)
    v[..., 1] = 1.0e6 + 1.2e6 * speed
    v[..., 2] = 0.03 * speed
    v[..., 5] = q_ch
    v[..., 7], v[..., 8] = W, 0.9 * W
    v[..., 6] = q_ch + 0.9 * W
    return CycleMap("hp", ("speed", "u_H", "T_H", "u_E", "T_E"), tuple(nodes), v, 0)


def with_hp(refrigerant, **kw):  # noqa: F811
    return dataclasses.replace(refrigerant, maps={**refrigerant.maps, "hp": hp_map(**kw)})


def test_heat_pump_heats_the_cabin_for_less_than_the_coolant_ptc_and_every_ledger_closes(refrigerant):  # noqa: F811
    ref = with_hp(refrigerant)
    hp = simulate(WLTC, 268.15, ref, params(**HP), dt=1.0, keep_trace=True)
    ptcw = simulate(WLTC, 268.15, ref, params(hvac={"heating": "ptc_coolant"}), dt=1.0)
    for name, residual in hp.ledgers.items():
        assert residual <= 1e-9, (name, residual)
    out = hp.trace["out"]
    ran = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    assert ran.mean() > 0.3
    s = hp.summary
    assert s["hp_heat_kWh"] > 0.5 and s["cop_hp"] > 1.0 and s["cop_sys_mean"] > 1.0
    assert s["source_heat_kWh"] == pytest.approx(s["ambient_heat_kWh"] + s["waste_heat_kWh"], abs=1e-12)
    assert s["hvac_energy_kWh"] < ptcw.summary["hvac_energy_kWh"]
    assert abs(s["T_cabin_end_degC"] - ptcw.summary["T_cabin_end_degC"]) < 1.0  # the same comfort
    # The heat pump's heat flows go to its loops; the front condenser and the battery chiller carry none.
    assert np.all(out[ran, L.O_Q_COND] == 0.0) and np.all(out[ran, L.O_Q_CHILLER] == 0.0)
    assert np.all(out[ran, L.O_Q_WCC] > 0.0) and np.all(out[ran, L.O_Q_CH_E] >= 0.0)
    # Its chiller needs the e-drive loop's flow.
    assert np.all(out[ran, L.O_U_PUMP_E] >= 0.5)
    assert ptcw.summary["hp_heat_kWh"] is None


def test_ledgers_close_at_every_step_size_with_the_heat_pump(refrigerant):  # noqa: F811
    ref = with_hp(refrigerant)
    for dt in (0.1, 10.0):
        r = simulate(WLTC, 263.15, ref, params(**HP), dt=dt)
        assert max(r.ledgers.values()) <= 1e-9, (dt, r.ledgers)


def test_radiator_is_the_source_below_the_ambient_and_frost_is_flagged(refrigerant):  # noqa: F811
    ref = with_hp(refrigerant)
    r = simulate(WLTC, 268.15, ref, params(**HP), dt=1.0, RH_amb=0.9, keep_trace=True)
    out, st = r.trace["out"], r.trace["states"]
    T_E = st[:-1, L.S_TE]
    hp = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    rad = out[:, L.O_RAD_IN] > 0
    assert np.any(hp & rad)
    # In heat-pump mode the radiator joins below the ambient less the band and leaves above it plus the band.
    joined = np.flatnonzero(np.diff(rad.astype(int)) > 0) + 1
    assert np.all(T_E[joined[hp[joined]]] < 268.15 - 1.0)
    assert np.any(out[hp & rad, L.O_Q_RAD] < 0.0)  # the air heats the loop: the ambient source
    assert r.summary["ambient_heat_kWh"] > 0.0
    # Frost: exactly the steps with the radiator as the source, its cold end below 0 degC and the ambient's
    # frost point (the ambient's humidity ratio at 268.15 K, RH 0.9, saturating over ice).
    frost = (r.trace["flags"] & L.F_FROST_OUTSIDE) > 0
    assert frost.any() and r.summary["frost_time_s"] == pytest.approx(float(np.sum(r.trace["dts"][frost])))
    T_fp = L.frost_point(L.humidity_ratio(268.15, 0.9, 101325.0), 101325.0)
    flowing = out[:, L.O_U_PUMP_E] > 0
    expected = rad & flowing & (T_E < 273.15) & (T_E < T_fp)
    assert np.array_equal(frost, expected)


def test_backup_fills_in_only_behind_a_heat_pump_running_flat_out(refrigerant):  # noqa: F811
    weak = with_hp(refrigerant, capacity=0.05)
    r = simulate(WLTC, 263.15, weak, params(**HP), dt=1.0, keep_trace=True)
    out = r.trace["out"]
    backup = (r.trace["flags"] & L.F_HP_BACKUP) > 0
    assert backup.any() and r.summary["backup_kWh"] > 0.0
    hp = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    # Split range: the coolant PTC heats with the heat pump running only while it is backing it up.
    assert np.all(out[hp & ~backup, L.O_P_PTCW] == 0.0)
    # It starts only after the heat pump has run flat out (at the suction limiter's ceiling, or at 1) for the
    # backup delay (60 s), and it heats only while the heat pump was flat out within that delay.
    # (or with its target beyond the 70 degC the heat pump alone reaches: the map's warmest loop)
    flat = hp & ((out[:, L.O_SPEED_CMD] >= out[:, L.O_HP_CEILING]) | (out[:, L.O_T_H_TARGET] > 343.15))
    released = np.flatnonzero(~backup[1:] & backup[:-1]) + 1
    for k in np.flatnonzero(backup[1:] & ~backup[:-1]) + 1:
        if np.any((released < k) & (released >= k - 60)):
            continue  # back within a minute of its release: at once (the next test)
        assert np.all(flat[k - 59 : k + 1]), k
    for k in np.flatnonzero(backup & (out[:, L.O_P_PTCW] > 0)):
        assert np.any(flat[max(k - 60, 0) : k + 1]), k


def test_a_backup_released_a_moment_ago_returns_at_once_when_the_pump_falls_short(refrigerant):  # noqa: F811
    """A vent target that falls for 30 s and rises again: the backup, released while the pump had margin,
    returns the step the pump runs flat out 2 K short again, not a minute later while the heater core cools the
    loop; and the cabin's vent air never sags more than the target's own fall asks."""
    weak = with_hp(refrigerant, capacity=0.05)
    t = np.array([0.0, 599.0, 600.0, 630.0, 631.0, 1200.0])
    sp = Trace(t, np.array([328.15, 328.15, 303.15, 303.15, 328.15, 328.15]), "test")
    r = simulate(first(WLTC, 1200.0), 263.15, weak, params(**HP), keep_trace=True, inputs={"SP_vent": sp})
    out, flags, st = r.trace["out"], r.trace["flags"], r.trace["states"]
    backup = (flags & L.F_HP_BACKUP) > 0
    released = np.flatnonzero(~backup[1:] & backup[:-1]) + 1
    back = np.flatnonzero(backup[1:] & ~backup[:-1]) + 1
    quick = [k for k in back if np.any((released < k) & (released >= k - 60))]
    assert released.size and quick, (released, back)
    for k in quick:  # flat out as the split range means it: at its ceiling, or asked beyond its warmest loop
        short = st[k, L.S_TH] < out[k, L.O_T_H_TARGET] - 2.0
        flat = out[k, L.O_SPEED_CMD] >= out[k, L.O_HP_CEILING] or out[k, L.O_T_H_TARGET] > 343.15
        assert short and flat and k - released[released < k].max() < 60, k
    # Before, it waited the minute: the loop's lowest point after the rise is within 3 K of where it was.
    rise = 631
    assert st[rise:, L.S_TH].min() > st[rise, L.S_TH] - 3.0


def test_suction_trips_restart_after_their_delay_and_lock_out(refrigerant):  # noqa: F811
    starved = with_hp(refrigerant, suction=0.2)  # suction below the 0.10 MPa floor at any speed
    p = params(**HP, heatpump={"hp_restart_delay": 60.0})
    r = simulate(WLTC, 263.15, starved, p, dt=1.0, keep_trace=True)
    out, flags = r.trace["out"], r.trace["flags"]
    locked = (flags & L.F_HP_LOCKED) > 0
    assert locked.any()
    hp = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    assert not np.any(hp & locked)
    t = np.concatenate(([0.0], np.cumsum(r.trace["dts"])))[:-1]
    stops = np.flatnonzero(hp[:-1] & ~hp[1:]) + 1
    starts = np.flatnonzero(~hp[:-1] & hp[1:]) + 1
    assert stops.size >= 3
    for s in stops:  # each trip waits out the restart delay
        later = starts[starts > s]
        if later.size:
            assert t[later[0]] - t[s] >= 60.0 - 1.0
    assert max(r.ledgers.values()) <= 1e-9


def test_below_its_lowest_ambient_the_coolant_ptc_heats_alone(refrigerant):  # noqa: F811
    ref = with_hp(refrigerant)
    r = simulate(WLTC, 253.15, ref, params(**HP), dt=1.0, keep_trace=True)
    out = r.trace["out"]
    assert not np.any(out[:, L.O_CIRCUIT] == L.CIRCUIT_HP)
    assert np.sum(out[:, L.O_P_PTCW]) > 0.0 and r.summary["hp_heat_kWh"] is None


def test_heat_pump_needs_its_loops(refrigerant):  # noqa: F811
    with pytest.raises(EvtmsInputError, match="edrive.model"):
        simulate(parked(60.0), 268.15, with_hp(refrigerant), params(**HP, edrive={"model": "ambient"}))
    with pytest.raises(EvtmsInputError, match="hp cycle map"):
        simulate(parked(60.0), 268.15, refrigerant, params(**HP))


def test_range_test_with_both_heatings_then_the_report_gives_the_gain(refrigerant, monkeypatch, tmp_path):  # noqa: F811
    import json

    from conftest import one_error_line
    from typer.testing import CliRunner

    from evtms import cli
    from evtms.workflows import simulate as simulate_workflow

    ref = with_hp(refrigerant)
    monkeypatch.setattr(simulate_workflow, "system_refrigerant", lambda *args, **kwargs: ref)
    runner = CliRunner()

    def run(*args):
        return runner.invoke(cli.app, [str(a) for a in args])

    toml = tmp_path / "small.toml"
    toml.write_text("[battery]\nn_parallel = 8\n")
    out = tmp_path / "mct.nc"
    res = run("simulate", "--range", "mct", "--t-amb", "-10,0", "--heating", "ptc_air,heat_pump", "--params", toml,
              "--luts", tmp_path / "l", "-o", out, "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    runs = json.loads(res.stdout)["runs"]
    assert [r["heating"] for r in runs] == ["ptc_air", "ptc_air", "heat_pump", "heat_pump"]
    assert runs[2]["hp_heat_kWh"] > 0 and runs[0]["hp_heat_kWh"] is None
    res = run("report", "range", out, "-o", tmp_path / "r.png", "--heating", "ptc_air,heat_pump", "--json")
    assert res.exit_code == 0, res.output
    gain = json.loads(res.stdout)["heat_pump_gain"]
    assert [g["T_amb_degC"] for g in gain] == pytest.approx([-10.0, 0.0])
    for g, hp, base in zip(gain, runs[2:], runs[:2], strict=True):
        expected = hp["range"]["range_combined_km"] / base["range"]["range_combined_km"] - 1.0
        assert g["gain_pct"] == pytest.approx(100.0 * expected, rel=1e-9) and g["gain_pct"] > 0.0
        assert g["cop_sys_mean"] == hp["cop_sys_mean"] and g["base"] == "ptc_air"
        assert g["hvac_share"] < g["base_hvac_share"]
    text = run("report", "range", out, "-o", tmp_path / "r2.png")
    assert text.exit_code == 0 and "heat_pump" in text.stdout and "vs ptc_air" in text.stdout
    bad = run("report", "range", out, "-o", tmp_path / "r3.png", "--heating", "ptc_coolant")
    one_error_line(bad, "--heating 'ptc_coolant': the file has no run of it")
    assert not (tmp_path / "r3.png").exists()


def test_the_loops_crossflow_effectiveness_is_the_benches():
    from evtms.hx.effectiveness import crossflow_one_mixed_effectiveness

    rng = np.random.default_rng(5)
    c_air, c_liq, ua = rng.uniform(10.0, 1500.0, 300), rng.uniform(10.0, 1500.0, 300), rng.uniform(1.0, 3000.0, 300)
    loop = np.array([L.crossflow_effectiveness(a, b, u) for a, b, u in zip(c_air, c_liq, ua, strict=True)])
    c_min, c_max = np.minimum(c_air, c_liq), np.maximum(c_air, c_liq)
    bench = crossflow_one_mixed_effectiveness(ua / c_min, c_min / c_max, c_liq <= c_air)  # the liquid is mixed
    np.testing.assert_allclose(loop, bench, rtol=1e-12)


def test_a_heat_pump_cycling_at_part_load_comes_back_and_the_ptc_stays_off(refrigerant):  # noqa: F811
    strong = with_hp(refrigerant, capacity=3.0)  # more than a mild day needs even at the minimum speed
    r = simulate(WLTC, 288.15, strong, params(**HP), dt=1.0, keep_trace=True)
    out = r.trace["out"]
    hp = out[:, L.O_CIRCUIT] == L.CIRCUIT_HP
    starts = np.flatnonzero(hp[1:] & ~hp[:-1])
    assert starts.size >= 2  # off at its floor with the loop warm, and back on as it cools
    heating = out[:, L.O_Q_HC] > 0
    assert np.sum(out[:, L.O_P_PTCW]) < 0.02 * np.sum(out[heating, L.O_Q_HC])  # the heat pump holds it alone
    assert max(r.ledgers.values()) <= 1e-9


def test_only_a_heat_pump_reads_the_heat_pump_map():
    """The maps a run needs, so that a folder without the heat pump's map (as the demo leaves it)
    serves every other heating option without building one."""
    from evtms.system.params import SystemParams, system_params_from_dict
    from evtms.system.refrigerant import map_names

    assert map_names(SystemParams()) == ("ac", "chiller", "ac+chiller")
    assert map_names(system_params_from_dict(HP)) == ("ac", "chiller", "ac+chiller", "hp")
