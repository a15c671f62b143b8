"""Comparison of the modelling approaches (evtms.workflows.compare, evtms.reports.compare): errors, measured
files, step study, output.

The simulations run the LUT model on the small synthetic cycle maps of
``test_simulate.py`` over a two-minute trace; where a test needs another
approach (physics, surrogate) a stand-in simulator runs the LUT model under
that name, so these tests check the comparison, not the models.
"""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest
from test_simulate import refrigerant  # noqa: F401 - the synthetic maps' fixture

from evtms.errors import EvtmsInputError
from evtms.reports import compare as R  # noqa: N812
from evtms.reports.html import referenced_files
from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import DriveCycle
from evtms.system.simulate import simulate
from evtms.workflows import compare as C  # noqa: N812


def short_cycle(seconds: float = 120.0) -> DriveCycle:
    t = np.arange(0.0, seconds + 1.0)
    v = 12.0 * np.sin(np.pi * t / seconds) ** 2
    return DriveCycle("short", t, v, np.zeros_like(t), "test")


def lut_as(cycle, T_amb, maps, params, *, dt, model, mode_models=None, **options):
    """Stand-in for every approach: the LUT model whatever ``model`` says."""
    return simulate(cycle, T_amb, maps, params, dt=dt, **options)


def records(time, **values) -> dict[str, np.ndarray]:
    return {"time": np.asarray(time, float), **{k: np.asarray(v, float) for k, v in values.items()}}


def fake_run(dt: float, **summary_changes) -> R.Run:
    t = np.arange(0.0, 61.0)
    rec = records(t, T_cabin=300.0 - 0.01 * t, T_battery=298.0 + 0 * t, SOC=0.9 - 1e-4 * t, P_hvac=1000.0 + 0 * t)
    rec["P_hvac"][0] = np.nan
    summary = {
        "battery_energy_kWh": 1.0,
        "hvac_energy_kWh": 0.5,
        "soc_end": 0.894,
        "T_cabin_end_degC": 26.25,
        "T_battery_end_degC": 24.85,
        "wall_time_s": 0.01,
        **summary_changes,
    }
    return R.Run("lut", "short", 303.15, dt, rec, summary)


# ---------------------------------------------------------------------------------------------- errors


def test_errors_of_a_constant_offset_on_aligned_times():
    """Reference every 2 s, candidate every 1 s and 0.5 K higher: RMSE = max = 0.5 K on the 2 s records."""
    ref = records(np.arange(0.0, 11.0, 2.0), T_cabin=290.0 + np.arange(6.0))
    t = np.arange(0.0, 11.0)
    cand = records(t, T_cabin=290.0 + t / 2.0 + 0.5)
    e = C.trajectory_errors(ref, cand)["T_cabin"]
    assert e.n == 6
    assert e.rmse == pytest.approx(0.5, abs=1e-12) and e.max_abs == pytest.approx(0.5, abs=1e-12)


def test_errors_interpolate_between_records_and_stay_within_the_span():
    """Candidate records between the reference's (a linear trend, so interpolation is exact); a shorter
    candidate is compared over its span only; the RMSE of two offsets is their quadratic mean."""
    ref = records(np.arange(0.0, 21.0), SOC=0.9 - 0.001 * np.arange(21.0))
    t = np.arange(0.5, 10.0, 1.0)
    offset = np.where(np.arange(t.size) % 2 == 0, 0.001, -0.002)
    cand = records(t, SOC=0.9 - 0.001 * t + offset)
    _, r, c = C.align(ref["time"], ref["SOC"], cand["time"], cand["SOC"])
    assert r.size == 9  # t = 1..9 lie within 0.5..9.5
    e = C.trajectory_errors(ref, cand)["SOC"]
    assert e.n == 9
    # every reference time lies midway between a +0.001 and a -0.002 record: -0.0005 everywhere
    assert e.max_abs == pytest.approx(0.0005, abs=1e-12) and e.rmse == pytest.approx(0.0005, abs=1e-12)


def test_errors_skip_the_first_interval_mean_and_flag_a_blow_up():
    t = np.arange(0.0, 6.0)
    ref = records(t, P_hvac=[np.nan, 1000, 1000, 1000, 1000, 1000])
    good = records(t, P_hvac=[np.nan, 1010, 990, 1010, 990, 1010])
    e = C.trajectory_errors(ref, good)["P_hvac"]
    assert e.n == 5 and e.rmse == pytest.approx(10.0) and e.max_abs == pytest.approx(10.0)
    blown = records(t, P_hvac=[np.nan, 1000, 1000, np.nan, np.inf, np.nan])
    e = C.trajectory_errors(ref, blown)["P_hvac"]
    assert e.n == 5 and np.isnan(e.rmse) and np.isnan(e.max_abs)


# ---------------------------------------------------------------------------------------------- runs


@pytest.fixture(scope="module")
def compared(refrigerant):  # noqa: F811
    """physics (stand-in) and lut on the short cycle at two ambients, steps 0.1, 1 and 10 s."""
    messages = []
    result = C.run_compare(
        [short_cycle()],
        [268.15, 313.15],
        refrigerant,
        approaches=("physics", "lut"),
        dts=(0.1, 1.0, 10.0),
        physics_dts=(1.0, 10.0),
        repeat=2,
        simulator=lut_as,
        progress=lambda done, total, message: messages.append((done, total, message)),
    )
    return result, messages


def test_physics_row_has_speed_up_one_and_no_error(compared):
    result, messages = compared
    assert [(r.approach, r.T_amb_degC) for r in result.rows] == [
        ("physics", -5.0),
        ("lut", -5.0),
        ("physics", 40.0),
        ("lut", 40.0),
    ]
    for row in result.rows:
        assert row.reference == "physics" and row.dt_s == 1.0
        assert row.compared_records == 121
        if row.approach == "physics":
            assert row.speedup == 1.0
            assert row.d_battery_energy_pct == 0.0 and row.d_hvac_energy_pct == 0.0
        else:
            assert row.speedup > 0 and np.isfinite(row.speedup)
        for name in ("T_cabin_K", "T_battery_K", "SOC", "P_hvac_W"):
            assert getattr(row, f"rmse_{name}") == 0.0 and getattr(row, f"max_{name}") == 0.0
        assert row.battery_energy_kWh > 0 and row.wall_time_s > 0 and row.termination == "end of cycle"
    # progress: one message per simulation, counting up to the total (2 scenarios x (physics 1 + lut 2) at
    # dt 1, then physics at 10 s and lut at 0.1 and 10 s)
    assert messages[-1] == (12, 12, "done")
    assert [m[0] for m in messages[:-1]] == list(range(12))


def test_step_study_rows_and_largest_stable_step(compared):
    result, _ = compared
    assert {(s.approach, s.dt_s) for s in result.steps} == {
        ("physics", 1.0),
        ("physics", 10.0),
        ("lut", 0.1),
        ("lut", 1.0),
        ("lut", 10.0),
    }
    for s in result.steps:
        assert s.finite and s.bounded
        assert s.reference_dt_s == (1.0 if s.approach == "physics" else 0.1)
        if s.dt_s == s.reference_dt_s:
            assert s.stable and s.d_battery_energy_pct == 0.0 and s.d_T_cabin_end_K == 0.0
        assert s.stable == s.within_tolerance
    for a in ("physics", "lut"):
        per = result.stable_dt[a]
        assert set(per) == {"short at -5 degC", "short at 40 degC", "all"}
        assert per["all"] == min(per["short at -5 degC"], per["short at 40 degC"])


def test_a_run_with_nan_is_unstable():
    runs = {0.1: fake_run(0.1), 1.0: fake_run(1.0), 10.0: fake_run(10.0)}
    runs[10.0].records["T_battery"][30:] = np.nan
    rows = C.assess_steps(runs)
    assert [r.stable for r in rows] == [True, True, False]
    bad = rows[-1]
    assert not bad.finite and not bad.bounded and "T_battery not finite from t = 30 s" in bad.reason
    assert C.largest_stable(rows) == 1.0
    # a NaN only in the summary, a run out of bounds, a run that moved too far
    runs[10.0] = fake_run(10.0, hvac_energy_kWh=float("nan"))
    assert C.assess_steps(runs)[-1].finite is False
    runs[10.0] = fake_run(10.0)
    runs[10.0].records["T_cabin"][5] = 500.0
    row = C.assess_steps(runs)[-1]
    assert row.finite and not row.bounded and not row.stable and "T_cabin 500.0 K" in row.reason
    runs[10.0] = fake_run(10.0, T_cabin_end_degC=26.25 + 3.0)
    row = C.assess_steps(runs)[-1]
    assert row.finite and row.bounded and not row.within_tolerance and row.d_T_cabin_end_K == pytest.approx(3.0)
    assert "cabin end temperature" in row.reason
    # the finest step blew up: the next sound one is the reference, and no step is stable from the finest
    runs = {0.1: fake_run(0.1), 1.0: fake_run(1.0, battery_energy_kWh=1.01)}
    runs[0.1].records["SOC"][:] = np.nan
    rows = C.assess_steps(runs)
    assert rows[1].reference_dt_s == 1.0 and rows[1].stable and not rows[0].stable
    assert C.largest_stable(rows) is None


def test_run_compare_marks_a_nan_run_unstable(refrigerant):  # noqa: F811
    def blows_up_at_10(cycle, T_amb, maps, params, *, dt, model, mode_models=None):
        r = simulate(cycle, T_amb, maps, params, dt=dt)
        if dt == 10.0:
            r.records["T_cabin"] = r.records["T_cabin"].copy()
            r.records["T_cabin"][3:] = np.nan
        return r

    result = C.run_compare(
        [short_cycle()], [303.15], refrigerant, approaches=("lut",), dts=(1.0, 10.0), simulator=blows_up_at_10
    )
    (coarse,) = [s for s in result.steps if s.dt_s == 10.0]
    assert not coarse.finite and not coarse.stable
    assert result.stable_dt["lut"] == {"short at 30 degC": 1.0, "all": 1.0}


def test_surrogate_out_of_range_fraction_and_mode_models_passed(refrigerant):  # noqa: F811
    models = object()
    seen = []

    def flagged(cycle, T_amb, maps, params, *, dt, model, mode_models=None):
        seen.append((model, mode_models))
        r = simulate(cycle, T_amb, maps, params, dt=dt)
        if model == "surrogate":
            r.flags[1::2] |= L.F_SURROGATE_OOR  # every other record after the first
        return r

    result = C.run_compare(
        [short_cycle()],
        [303.15],
        refrigerant,
        approaches=("lut", "surrogate"),
        mode_models=models,
        step_study=False,
        repeat=1,
        simulator=flagged,
    )
    assert {m for m, _ in seen} == {"lut", "surrogate"} and all(mm is models for _, mm in seen)
    lut, sur = result.rows
    assert lut.out_of_range_fraction == 0.0
    assert sur.out_of_range_fraction == pytest.approx(0.5)
    assert lut.speedup is None and lut.reference == "none" and lut.rmse_T_cabin_K is None  # no physics run
    assert result.steps == [] and result.stable_dt == {"lut": {}, "surrogate": {}}


def test_default_simulator_runs_the_lut_model(refrigerant):  # noqa: F811
    result = C.run_compare([short_cycle(60.0)], [298.15], refrigerant, approaches=("lut",), dts=(1.0,), repeat=1)
    (row,) = result.rows
    assert row.approach == "lut" and row.battery_energy_kWh > 0 and row.compared_records == 0


def test_a_failing_approach_is_an_error_naming_it(refrigerant):  # noqa: F811
    def unavailable(cycle, T_amb, maps, params, *, dt, model, mode_models=None):
        if model == "physics":
            raise NotImplementedError("no physics here")
        return simulate(cycle, T_amb, maps, params, dt=dt)

    with pytest.raises(EvtmsInputError, match=r"approach 'physics' is not available \(physics on short at 30 degC"):
        C.run_compare([short_cycle()], [303.15], refrigerant, simulator=unavailable, approaches=("lut", "physics"))

    def bad_input(cycle, T_amb, maps, params, *, dt, model, mode_models=None):
        raise EvtmsInputError("mode models do not cover mode CC")

    with pytest.raises(EvtmsInputError, match=r"^lut on short at 30 degC at dt 1 s: mode models do not cover"):
        C.run_compare([short_cycle()], [303.15], refrigerant, simulator=bad_input, approaches=("lut",))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"approaches": ("lut", "exact")}, "approach 'exact' is unknown; allowed: physics, lut, surrogate"),
        ({"approaches": ()}, "no approach"),
        ({"approaches": ("lut", "lut")}, "name one twice"),
        ({"approaches": ("surrogate",)}, "the surrogate approach needs mode models"),
        ({"dts": (0.1, 100.0)}, "step 100.0 s is not allowed"),
        ({"dt": 0.0}, "step 0.0 s is not allowed"),
        ({"repeat": 0}, "repeat 0"),
        ({"t_ambs_K": []}, "nothing to compare"),
        ({"t_ambs_K": [300.0, 310.0], "measured": {"time": np.zeros(1), "SOC": np.ones(1)}}, "one drive cycle and one"),
        ({"measured": {"time": np.array([0.0, 500.0]), "SOC": np.ones(2)}}, "measured times reach 500 s, beyond"),
    ],
)
def test_bad_requests_are_refused_before_any_run(refrigerant, kwargs, message):  # noqa: F811
    def never(*args, **kw):
        raise AssertionError("no simulation expected")

    args = {"approaches": ("lut",), "t_ambs_K": [300.0], **kwargs}
    t_ambs = args.pop("t_ambs_K")
    with pytest.raises(EvtmsInputError, match=message.replace("(", r"\(")):
        C.run_compare([short_cycle()], t_ambs, refrigerant, simulator=never, **args)


# ---------------------------------------------------------------------------------------------- measured


def test_measured_file_is_read(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("# logger export\ntime,T_cabin,SOC\n0,300.0,0.9\n\n2.5,299.5,0.899\n5,299,0.898\n")
    m = C.read_measured(path)
    assert list(m) == ["time", "T_cabin", "SOC"]
    np.testing.assert_array_equal(m["time"], [0.0, 2.5, 5.0])
    np.testing.assert_array_equal(m["T_cabin"], [300.0, 299.5, 299.0])


@pytest.mark.parametrize(
    ("text", "line", "rule"),
    [
        ("time,T_cabin,speed\n0,300,1\n", 1, "column 'speed' is not allowed; allowed: time, T_cabin"),
        ("T_cabin,SOC\n300,0.9\n", 1, "no 'time' column"),
        ("time,SOC,SOC\n0,0.9,0.9\n", 1, "column 'SOC' appears twice"),
        ("time\n0\n", 1, "only 'time'"),
        ("time,SOC\n1,0.9\n", 2, "the first time is 1 s; measured times start at 0"),
        ("time,SOC\n0,0.9\n1,0.9\n1,0.9\n", 4, "time 1 s does not increase"),
        ("time,SOC\n0,0.9\n1,nan\n", 3, "SOC nan is not finite"),
        ("time,T_battery\n0,25.0\n", 2, "T_battery 25 K is not allowed; allowed: 150 to 450 K"),
        ("time,SOC\n0,90\n", 2, "SOC 90 is not allowed; allowed: 0 to 1"),
        ("time,SOC\n0,0.9,1\n", 2, "3 values in '0,0.9,1'; expected 2"),
        ("time,SOC\n0,high\n", 2, "is not 2 numbers"),
        ("# nothing\n", None, "empty"),
        ("time,SOC\n", None, "a header and no rows"),
    ],
)
def test_measured_file_errors_name_file_line_and_rule(tmp_path, text, line, rule):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(EvtmsInputError) as info:
        C.read_measured(path)
    message = str(info.value)
    assert "\n" not in message
    where = f"{path}:{line}: " if line is not None else f"{path}: "
    assert message.startswith(where), message
    assert rule in message


def test_measured_file_that_is_not_a_file(tmp_path):
    with pytest.raises(EvtmsInputError, match="cannot read the measured file"):
        C.read_measured(tmp_path / "missing.csv")
    with pytest.raises(EvtmsInputError, match="not a regular file"):
        C.read_measured(tmp_path)
    (tmp_path / "latin.csv").write_bytes(b"time,SOC\n0,0.9 \xe9\n")
    with pytest.raises(EvtmsInputError, match="not UTF-8"):
        C.read_measured(tmp_path / "latin.csv")


def test_measured_reference_replaces_physics_where_given(refrigerant, tmp_path):  # noqa: F811
    cycle = short_cycle()
    base = simulate(cycle, 303.15, refrigerant, dt=1.0)
    t = base.records["time"][::5]  # measured every 5 s, 1 K above the simulated cabin
    path = tmp_path / "m.csv"
    rows = "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, base.records["T_cabin"][::5] + 1.0, strict=True))
    path.write_text("time,T_cabin\n" + rows + "\n")
    measured = C.read_measured(path)
    result = C.run_compare(
        [cycle],
        [303.15],
        refrigerant,
        approaches=("physics", "lut"),
        measured=measured,
        measured_source=str(path),
        step_study=False,
        repeat=1,
        simulator=lut_as,
    )
    for row in result.rows:
        assert row.reference == "measured (T_cabin), physics (others)"
        assert row.rmse_T_cabin_K == pytest.approx(1.0, abs=1e-9) and row.max_T_cabin_K == pytest.approx(1.0)
        assert row.rmse_T_battery_K == 0.0 and row.rmse_SOC == 0.0  # still against physics
        assert row.compared_records == 121
    summary = R.compare_summary(result)
    assert summary["reference"] == "measured" and summary["measured"] == str(path)
    d = R.trajectory_data(result, "short", 303.15)
    assert set(d["measured"]) == {"time_min", "T_cabin"}
    np.testing.assert_allclose(d["measured"]["T_cabin"], base.records["T_cabin"][::5] + 1.0 - 273.15)


# ---------------------------------------------------------------------------------------------- output


def test_written_files_parse_back(compared, tmp_path):
    result, _ = compared
    out = tmp_path / "compare"
    files = R.write_compare(result, out)
    names = sorted(p.name for p in files)
    assert names == sorted(
        [
            "compare.csv",
            "compare.html",
            "steps.csv",
            "steps.html",
            "summary.json",
            "index.html",
            "trajectories_short_-5degC.png",
            "trajectories_short_40degC.png",
        ]
    )
    assert all(p.is_file() and p.stat().st_size > 0 for p in files)
    assert sorted(p.name for p in out.iterdir()) == names  # nothing else (no staging leftovers)
    assert not [p for p in tmp_path.iterdir() if p.name != "compare"]
    with open(out / "compare.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == [f.name for f in dataclasses.fields(R.CompareRow)]
    assert len(table) == 4 and table[0]["approach"] == "physics" and float(table[0]["speedup"]) == 1.0
    assert float(table[1]["rmse_T_cabin_K"]) == 0.0 and float(table[1]["battery_energy_kWh"]) > 0
    with open(out / "steps.csv", newline="") as fh:
        steps = list(csv.DictReader(fh))
    assert list(steps[0]) == [f.name for f in dataclasses.fields(R.StepRow)]
    assert len(steps) == len(result.steps) and {s["stable"] for s in steps} <= {"true", "false"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary == json.loads(json.dumps(R.compare_summary(result)))
    assert summary["reference"] == "physics" and len(summary["table"]) == 4
    assert set(summary["largest_stable_dt_s"]) == {"physics", "lut"}
    links = {p.name for p in referenced_files(out / "index.html")}
    assert links == set(names) - {"index.html"}
    assert all(p.is_file() for p in referenced_files(out / "index.html"))


def test_a_failed_write_leaves_the_folder_as_it_was(compared, tmp_path, monkeypatch):
    result, _ = compared
    out = tmp_path / "compare"

    def broken(*args, **kwargs):
        raise RuntimeError("disk gone")

    monkeypatch.setattr(R, "trajectory_figure", broken)
    with pytest.raises(RuntimeError, match="disk gone"):
        R.write_compare(result, out)
    assert not out.exists() and list(tmp_path.iterdir()) == []
    out.mkdir()
    (out / "compare.csv").write_text("old")
    with pytest.raises(RuntimeError):
        R.write_compare(result, out)
    assert (out / "compare.csv").read_text() == "old" and [p.name for p in out.iterdir()] == ["compare.csv"]
