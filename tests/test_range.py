"""Range tests (spec v2 section 7): the J1634 and GTR 15 sequences, their arithmetic, runs to break-off, the CLI.

The runs use the synthetic cycle maps of ``test_simulate.py`` (the CLI's map
loading is replaced by them), so every test here takes seconds.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import xarray as xr
from conftest import one_error_line
from test_simulate import params, refrigerant  # noqa: F401 - the synthetic maps' fixture
from typer.testing import CliRunner

from evtms import cli
from evtms.errors import EvtmsInputError
from evtms.reports.system_plots import depletion_data, depletion_report, range_figure
from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import DriveCycle, drive_cycle
from evtms.system.output import to_dataset
from evtms.system.range_test import (
    RangeSettings,
    break_off_time,
    ccp_sequence,
    csc_phases,
    mct_sequence,
    measure,
    run_range_test,
)
from evtms.system.simulate import SimulationResult, simulate, usable_energy
from evtms.workflows import simulate as simulate_workflow

UDDS, HWFET, WLTC = drive_cycle("udds"), drive_cycle("hwfet"), drive_cycle("wltc3b")
runner = CliRunner()


def _key_off_spans(cycle: DriveCycle) -> list[tuple[float, float]]:
    i = np.flatnonzero(cycle.key_off)
    return [(float(cycle.time[k]), float(cycle.time[k + 1] - cycle.time[k])) for k in i]


def test_mct_sequence_has_the_cfr_order_soaks_and_csc_speed():
    s = RangeSettings()
    seq = mct_sequence(4000.0, 2, s)
    names = [p.name for p in seq.phases]
    assert names == [
        "UDDS1", "key-on pause", "HWFET1", "key-off soak", "UDDS2", "CSC_M1", "CSC soak", "CSC_M2",
        "UDDS3", "key-on pause", "HWFET2", "key-off soak", "UDDS4", "CSC_E1", "CSC soak", "CSC_E2",
    ]  # fmt: skip
    lengths = {p.name: p.end - p.start for p in seq.phases}
    assert lengths["UDDS1"] == 1369.0 and lengths["HWFET1"] == 765.0
    assert [p.end - p.start for p in seq.phases if p.kind == "key_on"] == [15.0, 15.0]
    assert [p.end - p.start for p in seq.phases if p.name.startswith("CSC_M")] == [2000.0, 2000.0]
    assert [p.end - p.start for p in seq.phases if p.name.startswith("CSC_E")] == [3600.0, 3600.0]
    # Phases tile the trace; key-off exactly on the soaks: 10 min after each HWFET, 5 min between CSC phases.
    assert all(a.end == b.start for a, b in zip(seq.phases, seq.phases[1:], strict=False))
    assert seq.phases[-1].end == seq.cycle.duration == 4 * 1369 + 2 * 765 + 2 * 15 + 2 * 600 + 4000 + 300 + 7200 + 300
    soaks = [(p.start, p.end - p.start) for p in seq.phases if p.kind == "key_off"]
    assert _key_off_spans(seq.cycle) == soaks and [d for _, d in soaks] == [600.0, 300.0, 600.0, 300.0]
    # 65 mph (29.06 m/s) in every CSC phase, reached and left at 1 m/s2 on whole seconds; standing elsewhere.
    c = seq.cycle
    assert s.csc_speed == pytest.approx(29.06, abs=5e-3) and s.csc_speed == 65 * 0.44704
    for p in seq.phases:
        inside = (c.time >= p.start) & (c.time <= p.end)
        v = c.speed[inside]
        if p.kind == "csc":
            assert v.max() == s.csc_speed and v[0] == v[-1] == 0.0
            assert np.max(np.abs(np.diff(v) / np.diff(c.time[inside]))) <= 1.0 + 1e-12
            assert np.all(c.time[inside] == np.round(c.time[inside]))
        elif p.kind in ("key_on", "key_off"):
            assert np.all(v == 0.0)
    udds = [p for p in seq.phases if p.kind == "udds"]
    for p in udds:
        inside = (c.time >= p.start) & (c.time <= p.end)
        np.testing.assert_array_equal(c.speed[inside], UDDS.speed)


def test_csc_phases_and_ccp():
    s = RangeSettings()
    assert csc_phases(7300.0, s) == [2433.0, 2433.0, 2434.0]
    assert csc_phases(3600.0, s) == [3600.0] and csc_phases(60.0, s) == [] and csc_phases(61.0, s) == [61.0]
    assert [p.name for p in mct_sequence(0.0, 1).phases][4:7] == ["UDDS2", "UDDS3", "key-on pause"]  # no CSC_M
    seq = ccp_sequence(3)
    assert [(p.name, p.start, p.end) for p in seq.phases] == [
        ("WLTC1", 0.0, 1800.0), ("WLTC2", 1800.0, 3600.0), ("WLTC3", 3600.0, 5400.0)
    ]  # fmt: skip
    assert not seq.cycle.key_off.any() and seq.cycle.distance == pytest.approx(3 * WLTC.distance, rel=1e-12)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: mct_sequence(-1.0, 1), "CSC_M length"),
        (lambda: mct_sequence(0.0, 0), "CSC_E phases"),
        (lambda: ccp_sequence(0), "WLTC count"),
        (lambda: ccp_sequence(400), "at most 604,800 s"),
        (lambda: mct_sequence(1e9, 1), "at most 604,800 s"),
        (lambda: RangeSettings(csc_e_share=1.5), "csc_e_share"),
        (lambda: RangeSettings(ramp_acceleration=0.0), "ramp_acceleration"),
    ],
)
def test_bad_sequence_input_is_one_line(make, message):
    with pytest.raises(EvtmsInputError, match=message) as info:
        make()
    assert "\n" not in str(info.value)


def test_key_off_steps_draw_nothing_while_the_network_runs_on(refrigerant):  # noqa: F811
    t = np.array([0.0, 10.0, 300.0, 310.0, 910.0, 920.0, 1200.0, 1210.0])
    v = np.array([0.0, 15.0, 15.0, 0.0, 0.0, 15.0, 15.0, 0.0])
    off = np.array([False, False, False, True, False, False, False, False])
    cycle = DriveCycle("drive-soak-drive", t, v, np.zeros_like(t), "test", off)
    r = simulate(cycle, 313.15, refrigerant, dt=1.0, sun=600.0, T_init=313.15)
    rec = r.records
    soak = (rec["time"] > 310.0) & (rec["time"] <= 910.0)
    # Only the refrigerant filter's tail (10 s time constant) outlives the key: its compressor work decays with
    # the heat flows it balances; every other load is off at once.
    assert np.all(rec["P_hvac"][soak] == rec["P_compressor"][soak])
    late = soak & (rec["time"] > 500.0)
    assert np.all(np.abs(rec["P_battery"][late]) < 0.1) and np.all(rec["P_hvac"][late] < 0.1)
    assert np.all(r.mode[soak] == L.OFF) and np.all(rec["blower"][soak] == 0.0)
    before = rec["time"] <= 310.0
    assert np.nanmax(rec["P_hvac"][before]) > 500.0  # the cabin was being cooled before the soak
    T_cab = rec["T_cabin"][soak]
    assert T_cab[-1] > T_cab[0] + 1.0  # the hot car warms up with the HVAC off
    assert max(r.ledgers.values()) <= 1e-9, r.ledgers
    aux = params().vehicle.aux_power
    assert r.summary["aux_energy_kWh"] == pytest.approx(aux * (1210.0 - 600.0) / 3.6e6, rel=1e-12)


def _synthetic_run(seq, power: dict[str, float], dT_cab: dict[str, float], t_end: float, flags=None):
    """Records at 1 s: power [W] constant per phase (by name, pauses and soaks by kind), cabin temperature
    linear within each phase by its change [K], battery temperature constant."""
    t = np.arange(0.0, t_end + 1.0)
    P = np.full(t.size, np.nan)
    T_nodes, T = [seq.phases[0].start], [300.0]
    for p in seq.phases:
        inside = (t > p.start) & (t <= p.end)
        P[inside] = power.get(p.name, power.get(p.kind, 0.0))
        T_nodes.append(p.end)
        T.append(T[-1] + dT_cab.get(p.name, 0.0))
    c = seq.cycle
    seg = 0.5 * (c.speed[1:] + c.speed[:-1]) * np.diff(c.time)
    distance = np.interp(t, c.time, np.concatenate(([0.0], np.cumsum(seg))))  # exact at whole seconds
    records = {
        "time": t,
        "P_battery": P,
        "P_hvac": 0.1 * P,
        "Q_battery_gen": np.zeros_like(t),
        "v_rc": np.zeros_like(t),
        "distance": distance,
        "T_cabin": np.interp(t, T_nodes, T),
        "T_battery": np.full_like(t, 295.0),
    }
    return records, np.zeros(t.size, np.uint16) if flags is None else flags


def test_the_figures_are_the_hand_computed_ones():
    seq = mct_sequence(0.0, 2)
    start = {p.name: p.start for p in seq.phases}
    t_end = start["CSC_E1"] + 1000.0  # break-off 1000 s into CSC_E1
    power = {"UDDS1": 6000.0, "UDDS2": 5500.0, "UDDS3": 5000.0, "UDDS4": 5200.0, "HWFET1": 12000.0,
             "HWFET2": 11500.0, "key_on": 800.0, "CSC_E1": 15000.0}  # fmt: skip
    dT = {"UDDS1": 5.0, "UDDS2": 0.5, "UDDS3": 0.1, "UDDS4": 0.3, "HWFET1": 1.0, "HWFET2": 0.3}
    records, flags = _synthetic_run(seq, power, dT, t_end)
    p = params()
    f = measure(seq, records, flags, "soc_min", params=p)
    d_u, d_h = UDDS.distance, HWFET.distance  # [m]
    E = {k: power[k] * (1369.0 if k.startswith("UDDS") else 765.0) for k in power if k[0] in "UH"}  # [J]
    E_csc = 15000.0 * 1000.0
    ube = sum(E.values()) + 2 * 15 * 800.0 + E_csc
    assert f.break_off == "soc_min" and f.break_off_s == t_end
    assert f.ube_kWh == pytest.approx(ube / 3.6e6, rel=1e-12)
    assert f.hvac_share == pytest.approx(0.1, rel=1e-12)
    assert [c.name for c in f.cycles] == ["UDDS1", "HWFET1", "UDDS2", "UDDS3", "HWFET2", "UDDS4", "CSC_E1"]
    assert [c.complete for c in f.cycles] == [True] * 6 + [False]
    wh_km = 1 / 3.6  # J/m -> Wh/km
    ec_u = sum(E[k] for k in ("UDDS1", "UDDS2", "UDDS3", "UDDS4")) / (4 * d_u) * wh_km
    ec_h = (E["HWFET1"] + E["HWFET2"]) / (2 * d_h) * wh_km
    assert f.EC_Wh_per_km["udds"] == pytest.approx(ec_u, rel=1e-12)
    assert f.EC_Wh_per_km["hwfet"] == pytest.approx(ec_h, rel=1e-12)
    ube_wh = ube / 3600.0
    assert f.range_city_km == pytest.approx(ube_wh / ec_u, rel=1e-12)
    assert f.range_hwy_km == pytest.approx(ube_wh / ec_h, rel=1e-12)
    assert f.range_combined_km == pytest.approx(ube_wh / (0.55 * ec_u + 0.45 * ec_h), rel=1e-12)
    assert f.label_range_km == pytest.approx(0.7 * f.range_combined_km, rel=1e-12)
    # Steady: UDDS3 is the last UDDS with |dT| < 0.2 K; no HWFET is, so its last one counts (flagged).
    ss_u, ss_h = E["UDDS3"] / d_u * wh_km, E["HWFET2"] / d_h * wh_km
    assert f.EC_ss_Wh_per_km == pytest.approx({"udds": ss_u, "hwfet": ss_h}, rel=1e-12)
    assert f.not_steady == ("hwfet",)
    assert f.EC_ss_combined_Wh_per_km == pytest.approx(0.55 * ss_u + 0.45 * ss_h, rel=1e-12)
    assert f.range_ss_km == pytest.approx(ube_wh / (0.55 * ss_u + 0.45 * ss_h), rel=1e-12)
    warm = sum(E[k] - ss_u / wh_km * d_u for k in E if k.startswith("UDDS"))
    warm += sum(E[k] - ss_h / wh_km * d_h for k in E if k.startswith("HWFET"))
    assert f.warmup_kWh == pytest.approx(warm / 3.6e6, rel=1e-9)
    assert f.csc_e_share == pytest.approx(E_csc / ube, rel=1e-12)
    # CSC_E1 by hand: 1 m/s2 for 29 s, 0.0576 m/s in the 30th second, then 65 mph until the break-off at 1000 s.
    csc = next(k for k in f.cycles if k.name == "CSC_E1")
    d_csc = sum(k + 0.5 for k in range(29)) + 0.5 * (29.0 + 29.0576) + 970.0 * 29.0576
    assert csc.distance_km * 1e3 == pytest.approx(d_csc, rel=1e-12)
    assert f.range_depletion_km * 1e3 == pytest.approx(4 * d_u + 2 * d_h + d_csc, rel=1e-12)
    # The v1 single trip: usable energy over UDDS1's chemical energy (no battery heat here), times its distance.
    assert f.single_trip_range_km == pytest.approx(usable_energy(p) / E["UDDS1"] * d_u / 1e3, rel=1e-12)


def test_traction_cut_break_off_needs_four_seconds():
    t = np.arange(0.0, 300.0)
    flags = np.zeros(t.size, np.uint16)
    flags[100:103] = L.F_TRACTION_CUT  # 3 s: no break-off
    assert break_off_time(t, flags, 4.0) is None
    flags[200:204] = L.F_TRACTION_CUT | L.F_POWER_LIMITED  # (199, 203]: 4 s
    assert break_off_time(t, flags, 4.0) == 203.0
    seq = ccp_sequence(1)
    records, _ = _synthetic_run(seq, {"WLTC1": 5000.0}, {}, 299.0)
    f = measure(seq, records, flags, "end of cycle", params=params())
    assert f.break_off == "traction_cut" and f.break_off_s == 203.0
    assert f.ube_kWh == pytest.approx(5000.0 * 203.0 / 3.6e6, rel=1e-12)
    assert not f.cycles[0].complete and f.EC_ss_Wh_per_km == {"wltc3b": None} and f.range_ss_km is None


SMALL = {"battery": {"n_parallel": 8}}  # a 12 kWh pack: a whole MCT in about 2.7 h


def test_mct_runs_to_break_off_and_its_steady_range_matches_at_22_degC(refrigerant):  # noqa: F811
    r, f = run_range_test("mct", 295.15, refrigerant, params(**SMALL))
    assert f.break_off == "soc_min" and r.summary["termination"] == "soc_min"
    names = [c.name for c in f.cycles]
    assert names[:6] == ["UDDS1", "HWFET1", "UDDS2", "CSC_M1", "UDDS3", "HWFET2"] and names[6] == "UDDS4"
    assert names[-1].startswith("CSC_E") and not f.cycles[-1].complete
    assert all(c.complete for c in f.cycles if c.kind in ("udds", "hwfet"))
    assert 0.10 <= f.csc_e_share <= 0.22  # the predictor aims at 15 % of UBE
    assert f.soc_start == 0.98 and r.records["SOC"][0] == 0.98  # fully charged
    assert max(r.ledgers.values()) <= 1e-9
    assert f.range_ss_km == pytest.approx(f.range_combined_km, rel=0.03)
    assert f.range_city_km > 0 and f.range_hwy_km > 0 and f.single_trip_range_km > 0
    assert f.ube_kWh == pytest.approx(r.summary["battery_energy_kWh"], rel=1e-9)
    assert r.attrs["range_test"] == "mct" and json.loads(r.attrs["range"])["test"] == "mct"
    off = (r.records["time"] > 2149.0) & (r.records["time"] <= 2749.0)  # the first 10 min key-off soak
    assert np.all(r.records["P_battery"][off] == 0.0)


def test_ccp_runs_to_break_off(refrigerant):  # noqa: F811
    r, f = run_range_test("ccp", 295.15, refrigerant, params(**SMALL))
    assert f.break_off == "soc_min"
    assert f.range_depletion_km == pytest.approx(r.records["distance"][-1] / 1e3, rel=1e-12)
    assert f.range_combined_km is None and f.label_range_km is None
    assert all(c.kind == "wltc3b" for c in f.cycles) and not f.cycles[-1].complete
    assert len(f.cycles) >= 3
    assert f.range_ss_km == pytest.approx(f.range_depletion_km, rel=0.05)


def test_soc_start_sets_where_the_test_begins(refrigerant):  # noqa: F811
    low = RangeSettings(soc_start=0.3)
    r, f = run_range_test("ccp", 295.15, refrigerant, params(**SMALL), settings=low)
    full = run_range_test("ccp", 295.15, refrigerant, params(**SMALL))[1]
    assert r.records["SOC"][0] == 0.3 and f.ube_kWh < 0.4 * full.ube_kWh
    with pytest.raises(EvtmsInputError, match="start SOC"):
        run_range_test("ccp", 295.15, refrigerant, params(**SMALL), settings=RangeSettings(soc_start=0.01))
    with pytest.raises(EvtmsInputError, match="`range_test` 'single'"):
        run_range_test("single", 295.15, refrigerant)


# The report ---------------------------------------------------------------------------------------------


def _fake(T_amb: float, range_km: float, heating: str | None = None) -> SimulationResult:
    time = np.arange(3.0)
    records = {name: np.zeros(3) for name in ("speed", "T_cabin")}
    records["time"] = time
    from evtms.system.simulate import RECORD_VARIABLES

    for name in RECORD_VARIABLES:
        records.setdefault(name, np.zeros(3))
    figures = {
        "test": "mct", "range_combined_km": range_km, "range_ss_km": 1.01 * range_km,
        "single_trip_range_km": 0.9 * range_km, "EC_ss_combined_Wh_per_km": 1e5 / range_km, "hvac_share": 0.1,
        "hvac_kWh": 1.0, "warmup_kWh": 0.2, "not_steady": [],
    }  # fmt: skip
    summary = {"T_amb_degC": T_amb - 273.15, "range": figures}
    if heating:
        summary["heating"] = heating
    attrs = {"T_amb": T_amb, "termination": "soc_min", "ledgers": "{}", "range_test": "mct"}
    attrs["range"] = json.dumps(figures)
    return SimulationResult(records, np.zeros(3, np.int8), np.zeros(3, np.uint16), {}, summary, attrs)


def test_report_checks_the_geotab_shape_and_the_baseline(tmp_path):
    good = [(283.15, 850.0), (293.15, 970.0), (297.05, 1000.0), (303.15, 900.0)]
    ds = to_dataset([_fake(T, x) for T, x in good])
    d = depletion_data(ds)
    c = d["curves"][""]
    np.testing.assert_allclose(c["T_amb"], [10.0, 20.0, 23.9, 30.0])
    assert c["baseline_km"] == 1000.0
    np.testing.assert_allclose(c["pct_vs_baseline"], [-15.0, -3.0, 0.0, -10.0])
    assert all(k["ok"] for k in c["checks"]) and "breakdown" not in c
    bad = [(283.15, 990.0), (293.15, 900.0), (297.05, 1000.0), (303.15, 700.0)]
    report = depletion_report(to_dataset([_fake(T, x) for T, x in bad]))
    checks = {k["check"]: k["ok"] for k in report["curves"][0]["checks"]}
    assert checks == {
        "peak between 18 and 26 degC": True,
        "20 degC at most 5 % below the peak": False,
        "10 degC 5-20 % below the peak": False,
        "30 degC 5-20 % below the peak": False,
    }
    assert [b["hvac_share"] for b in report["curves"][0]["breakdown"]] == [0.1] * 4
    aaa = report["curves"][0]["aaa_2019"]
    assert aaa["-6.7"]["model_pct"] is None and aaa["35"]["aaa_pct"] == -17.0
    # One curve per heating option the runs name.
    two = to_dataset([_fake(T, x, h) for (T, x), h in zip(good, ["ptc_air", "heat_pump"] * 2, strict=True)])
    assert list(depletion_data(two)["curves"]) == ["ptc_air", "heat_pump"]
    assert range_figure(two, tmp_path / "r.png").stat().st_size > 1000


# The command line ---------------------------------------------------------------------------------------


@pytest.fixture
def cli_maps(monkeypatch, refrigerant):  # noqa: F811
    monkeypatch.setattr(simulate_workflow, "system_refrigerant", lambda *args, **kwargs: refrigerant)


def _run(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


def test_simulate_range_mct_then_report(cli_maps, tmp_path):
    toml = tmp_path / "small.toml"
    toml.write_text("[battery]\nn_parallel = 8\n")
    out = tmp_path / "mct.nc"
    res = _run("simulate", "--range", "mct", "--t-amb", "10,22", "--params", toml, "--luts", tmp_path / "l", "-o",
               out, "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    runs = json.loads(res.stdout)["runs"]
    assert [r["range"]["break_off"] for r in runs] == ["soc_min", "soc_min"]
    assert runs[1]["range"]["range_combined_km"] > runs[0]["range"]["range_combined_km"]
    with xr.open_dataset(out) as ds:
        assert ds.attrs["range_test"] == "mct"
        stored = json.loads(ds.attrs["range"])
        assert [s["ube_kWh"] for s in stored] == [r["range"]["ube_kWh"] for r in runs]
    fig = tmp_path / "range.png"
    res = _run("report", "range", out, "-o", fig, "--json")
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    assert report["path"] == str(fig) and report["test"] == "mct" and fig.stat().st_size > 1000
    assert [p["T_amb_degC"] for p in report["curves"][0]["points"]] == pytest.approx([10.0, 22.0])
    res = _run("simulate", "--range", "ccp", "--cycle", "wltc3b", "--t-amb", "22", "--params", toml, "--luts",
               tmp_path / "l", "-o", tmp_path / "ccp.nc")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "ccp: UBE" in res.stdout and "depletion" in res.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["--range", "epa", "--t-amb", "22"], "--range 'epa' is unknown; allowed: single, mct, ccp"),
        (["--range", "mct", "--cycle", "udds", "--t-amb", "22"], "--range mct drives its own cycles"),
        (["--range", "ccp", "--cycle", "nedc", "--t-amb", "22"], "leave out --cycle nedc"),
        (["--range", "single", "--t-amb", "22"], "give --cycle"),
        (["--range", "mct"], "give --t-amb"),
        (["--range", "mct", "--t-amb", "22", "--dt", "0"], "--dt 0 is not allowed"),
    ],
)
def test_bad_range_options_are_one_line_exit_2(cli_maps, tmp_path, args, message):
    out = tmp_path / "bad.nc"
    res = _run("simulate", *args, "--luts", tmp_path / "l", "-o", out)
    one_error_line(res, message)
    assert not out.exists()


def test_scenario_gives_its_conditions_to_a_range_test(cli_maps, tmp_path):
    toml = tmp_path / "small.toml"
    toml.write_text("[battery]\nn_parallel = 8\n")
    res = _run("simulate", "--range", "ccp", "--scenario", "cold", "--params", toml, "--luts", tmp_path / "l",
               "-o", tmp_path / "c.nc", "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "note: --range ccp keeps the scenario's conditions, not its cycle hwfet" in res.stderr
    s = json.loads(res.stdout)
    assert s["T_amb_degC"] == pytest.approx(-5.0) and s["range"]["test"] == "ccp"


def test_settings_are_recorded():
    f = dataclasses.asdict(RangeSettings())
    assert f["key_on_pause"] == 15.0 and f["key_off_soak"] == 600.0 and f["csc_soak"] == 300.0
    assert f["csc_phase_max"] == 3600.0 and f["csc_e_share"] == 0.15 and f["city_weight"] == 0.55
