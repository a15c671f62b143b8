"""`evtms sweep` and the simulation engine it shares with `evtms surrogate train`.

The sweep's rows are the figures of single `evtms simulate` runs of the same
scenarios; in this process and on dask workers they are the same; bad input
is one line, exit 2, nothing written; the summary table reads back as it was
written. The maps are built on the small axes (conftest's ``small_maps``); the
training comparison runs on the synthetic maps of ``test_surrogates``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from conftest import one_error_line
from typer.testing import CliRunner

from evtms.cli import app
from evtms.system.sweep_table import COLUMNS, FIGURE_COLUMNS, SweepTable, read_table, write_table

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
#: Figures that are times of this run, not results.
TIMINGS = {"loop_time_s"}


@pytest.fixture()
def luts(small_map_luts):
    return small_map_luts


@pytest.fixture(autouse=True)
def _small_maps(small_maps):
    """Every test here builds its maps on the small axes."""


@pytest.fixture(scope="module")
def cluster():
    """Two local dask worker processes, shared by the tests that compare with in-process runs."""
    distributed = pytest.importorskip("distributed")
    c = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        worker_dashboard_address="127.0.0.1:0",
    )
    yield c
    c.close()


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _trace(tmp_path, seconds: int = 240):
    trace = tmp_path / "trip.csv"
    rows = "".join(f"{t},{min(1.5 * t, 50.0) if t < seconds - 40 else max(0.0, 50.0 - 1.5 * (t - seconds + 40))}\n"
                   for t in range(seconds + 1))  # fmt: skip
    trace.write_text("time_s,speed_kmh\n" + rows)
    return trace


def _variant(tmp_path):
    p = tmp_path / "warm-cabin.toml"
    p.write_text("[cabin]\nT_set = 297.15\n[vehicle]\nmass = 2100.0\n")
    return p


def _sweep(tmp_path, luts, out, *extra):
    trace = _trace(tmp_path)
    r = run("sweep", "--t-amb", "-5,32", "--cycle", f"{trace},parked:300", "--params", _variant(tmp_path),
            "--luts", luts, "-o", out, "--json", *extra)  # fmt: skip
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout), trace


def _same_rows(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        for k in x:
            if k in TIMINGS:
                continue
            same = x[k] == y[k] or (isinstance(x[k], float) and math.isnan(x[k]) and math.isnan(y[k]))
            assert same, (x["scenario"], k, x[k], y[k])


def test_rows_are_the_figures_of_single_simulate_runs(luts, tmp_path):
    result, trace = _sweep(tmp_path, luts, tmp_path / "study.nc")
    rows = result["rows"]
    assert result["scenarios"] == 4 and result["failed"] == 0 and result["runner"] == "in-process"
    # Order: parameter sets, cycles, ambients (innermost).
    assert [(r["cycle"], r["T_amb_degC"]) for r in rows] == [
        (str(trace), -5.0), (str(trace), 32.0), ("parked:300", -5.0), ("parked:300", 32.0),
    ]  # fmt: skip
    for row in rows:
        one = tmp_path / f"one-{row['scenario']}.nc"
        r = run("simulate", "--cycle", row["cycle"], "--t-amb", row["T_amb_degC"], "--params", row["params"],
                "--luts", luts, "-o", one, "--json")  # fmt: skip
        assert r.exit_code == 0, r.output
        s = json.loads(r.stdout)
        for key in ("battery_energy_kWh", "hvac_energy_kWh", "distance_km", "soc_end", "T_cabin_end_degC",
                    "T_battery_end_degC", "ledger_worst", "compressor_starts"):  # fmt: skip
            assert row[key] == s[key], (row["scenario"], key)
        assert row["range_km"] == s["range_km"] or (s["range_km"] is None and row["range_km"] is None)
        assert row["status"] == s["termination"] == "end of cycle"
        with netCDF4.Dataset(one) as ds:
            T = ds["T_battery"][:] - 273.15
        assert row["T_battery_min_degC"] == pytest.approx(float(T.min()), abs=1e-12)
        assert row["T_battery_max_degC"] == pytest.approx(float(T.max()), abs=1e-12)
    drive, parked = rows[1], rows[3]
    assert drive["battery_Wh_per_km"] == pytest.approx(drive["battery_energy_kWh"] * 1e3 / drive["distance_km"])
    assert parked["distance_km"] == 0.0 and parked["battery_Wh_per_km"] is None  # NaN in the file, null in JSON
    assert read_table(tmp_path / "study.nc").column("battery_energy_kWh") == [r["battery_energy_kWh"] for r in rows]


def test_workers_give_the_in_process_rows_and_run_files(luts, tmp_path, cluster):
    serial, _ = _sweep(tmp_path, luts, tmp_path / "serial.csv")
    runs = tmp_path / "runs"
    parallel, _ = _sweep(tmp_path, luts, tmp_path / "dask.csv", "--scheduler", cluster.scheduler_address,
                         "--batch", "1", "--runs", runs)  # fmt: skip
    assert parallel["runner"] == "dask" and parallel["workers"] == 2
    rows = [{k: v for k, v in r.items() if k != "run_file"} for r in parallel["rows"]]
    _same_rows([{k: v for k, v in r.items() if k != "run_file"} for r in serial["rows"]], rows)
    files = sorted(p.name for p in runs.iterdir())
    assert files == [r["run_file"] for r in parallel["rows"]] == [f"run-{i:04d}.nc" for i in range(4)]
    with netCDF4.Dataset(runs / "run-0001.nc") as ds:
        summary = json.loads(ds.summary)
        assert summary["battery_energy_kWh"] == parallel["rows"][1]["battery_energy_kWh"]
        assert ds["T_battery"][:].max() - 273.15 == pytest.approx(parallel["rows"][1]["T_battery_max_degC"])


@pytest.mark.parametrize(
    "args, message",
    [
        (["--cycle", "wltc3b,nosuch"], "nosuch"),
        (["--cycle", "wltc3b,wltc3b"], "--cycle 'wltc3b' is given twice"),
        (["--t-amb", "-80"], "T_amb = -80 degC is not allowed"),
        (["--t-amb", "x"], "--t-amb 'x' is not a number"),
        (["--rh-amb", "1.5"], "RH_amb = 1.5 is not allowed"),
        (["--sun", "-3"], "--sun -3 is not allowed"),
        (["--params", "missing.toml"], "params file 'missing.toml': no such file"),
        (
            ["--t-amb", "0:40:1000", "--cycle", "wltc3b,nedc", "--max-scenarios", "1000"],
            "2,000 scenarios (2 cycles x 1000 ambients) are more than --max-scenarios 1,000",
        ),
        (["--t-amb", "0:40:20", "--params", "missing.toml", "--max-scenarios", "10"], "20 scenarios"),
        (["--max-scenarios", "0"], "--max-scenarios 0 is not allowed"),
        (["--model", "physics"], "--model 'physics' is not allowed in a sweep"),
        (["--workers", "0"], "--workers 0 is not allowed"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "give --workers or --scheduler, not both"),
        (["--scheduler", "http://x"], "scheduler address 'http://x' is not allowed"),
        (["--batch", "0"], "--batch 0 is not allowed"),
        (["--mode", "heat"], "--mode 'heat' is unknown"),
        (["--dt", "0"], "--dt 0 is not allowed"),
        (["-o", "study.txt"], "must end in .nc or .csv"),
    ],
)
def test_bad_input_is_one_line_and_nothing_written(luts, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    r = run("sweep", "-o", "study.nc", "--runs", "runs", "--luts", luts, "--t-amb", "20", *args)
    one_error_line(r, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_the_size_is_checked_before_any_file_is_read(luts, tmp_path):
    r = run("sweep", "--t-amb", "0:40:1000", "--cycle", "wltc3b,nedc,udds", "--params", tmp_path / "none.toml",
            "--luts", luts, "--max-scenarios", "100", "-o", tmp_path / "s.nc")  # fmt: skip
    one_error_line(r, "3,000 scenarios (3 cycles x 1000 ambients) are more than --max-scenarios 100")


def _table(n: int = 3) -> SweepTable:
    rows = []
    for i in range(n):
        row = {c.name: (f"text, with comma {i}" if c.kind == "str" else i if c.kind == "int" else 0.1 * i + 1e-17)
               for c in COLUMNS}  # fmt: skip
        row["range_km"] = math.nan if i == 1 else 412.345678901234567
        row["message"] = "" if i != 2 else 'failed: "quoted", ünïcode'
        rows.append(row)
    return SweepTable(rows, {"dt": 1.0, "runner": "in-process", "workers": 1})


@pytest.mark.parametrize("suffix", [".nc", ".csv"])
def test_the_summary_table_round_trips(tmp_path, suffix):
    table = _table()
    path = write_table(table, tmp_path / f"t{suffix}")
    back = read_table(path)
    _same_rows(table.rows, back.rows)
    assert [list(r) for r in back.rows][0] == [c.name for c in COLUMNS]
    assert back.attrs["title"] == "evtms simulation sweep" and back.attrs["workers"] == 1
    assert math.isnan(back.rows[1]["range_km"]) and back.rows[0]["range_km"] == 412.345678901234567


def test_concurrent_sweeps_to_one_output_leave_one_whole_table(tmp_path):
    """Two processes writing tables of 2 and 5 rows to one file, over and over: it is always one of them, whole."""
    path = tmp_path / "t.nc"
    script = (
        "import sys; sys.path[:0] = ['tests', '.']\n"
        "from test_sweep import _table; from evtms.system.sweep_table import write_table\n"
        "for _ in range(8): write_table(_table(int(sys.argv[1])), sys.argv[2])\n"
    )
    procs = [subprocess.Popen([sys.executable, "-c", script, str(n), str(path)], cwd=ROOT) for n in (2, 5)]
    sizes = set()
    while any(p.poll() is None for p in procs):
        if path.exists():
            sizes.add(len(read_table(path).rows))
    assert [p.returncode for p in procs] == [0, 0]
    sizes.add(len(read_table(path).rows))
    assert sizes <= {2, 5}
    assert [p.name for p in tmp_path.iterdir()] == ["t.nc"]  # no temporary file left


def test_a_failed_run_is_a_row_with_status_error():
    from evtms.system.sweep_table import failed_figures

    row = failed_figures(3, None, "the loop\nstopped")
    assert row["status"] == "error" and row["message"] == "the loop stopped"
    assert set(row) == {c.name for c in FIGURE_COLUMNS} and math.isnan(row["battery_energy_kWh"])


# --- the engine: batches, order, installation -----------------------------------------------------------------


class _ReversedRunner:
    """A runner that computes the batches last first, in this process (what a cluster's completion order may do)."""

    name = "reversed"
    workers = 3

    def run(self, job, chunks):
        for k in reversed(list(chunks)):
            yield k, job(k)

    def close(self):
        pass


def _context(n: int = 7):
    from evtms.system.scenarios import Scenario
    from evtms.system.sweep import Run, SweepContext
    from evtms.system.sweep_table import SweepRows
    from tests.test_surrogates import synthetic_refrigerant

    setups = [Scenario(name="", cycle=c).setup() for c in ("parked:60", "parked:120")]
    runs = [Run(i % 2, 263.15 + 5.0 * i) for i in range(n)]
    return SweepContext(setups, [synthetic_refrigerant()], runs, SweepRows(n), {"dt": 1.0})


@pytest.mark.parametrize("size", [1, 3, 64])
def test_batches_come_back_in_run_order_whatever_their_size_and_completion(size):
    from evtms.system.sweep import batches, iter_installed, run_batches

    assert [list(b) for b in batches(7, 3)] == [[0, 1, 2], [3, 4, 5], [6]]
    ctx = _context()
    serial = run_batches(ctx)
    seen = []
    shuffled = run_batches(ctx, _ReversedRunner(), size=size, progress=lambda d, n: seen.append(d))
    _same_rows(serial, shuffled)
    assert [r["T_battery_end_degC"] for r in serial] == sorted(r["T_battery_end_degC"] for r in serial)
    assert seen[-1] == 7 and len(seen) == -(-7 // size)
    assert list(iter_installed()) == []  # uninstalled after the runs


def test_a_run_that_raises_is_its_rows_error_and_the_others_run_on(monkeypatch):
    from evtms.system import scenarios
    from evtms.system.sweep import run_batches
    from evtms.system.sweep_table import failed_figures

    real = scenarios.run_scenario

    def flaky(setup, refrigerant, T_amb, **options):
        if T_amb > 280.0 and T_amb < 285.0:
            raise FloatingPointError("the loop\nleft finite numbers")
        return real(setup, refrigerant, T_amb, **options)

    monkeypatch.setattr(scenarios, "run_scenario", flaky)
    ctx = _context()
    with pytest.raises(FloatingPointError):  # no ``failed``: the error ends the sweep (the training's choice)
        run_batches(ctx)
    ctx.failed = failed_figures
    rows = run_batches(ctx, _ReversedRunner(), size=2)
    assert [r["status"] for r in rows] == ["end of cycle"] * 4 + ["error"] + ["end of cycle"] * 2  # 283.15 K
    assert rows[4]["message"] == "the loop left finite numbers" and math.isnan(rows[4]["soc_end"])


def test_a_worker_that_does_not_see_the_run_folder_sends_the_file_back(tmp_path):
    """Where the folder's token is not the sweep's (a cluster without the folder) the file's bytes come back."""
    from evtms.system.sweep import run_batches
    from evtms.system.sweep_table import RUNS_MARKER, SweepRows, write_run_bytes

    ctx = _context(2)
    (tmp_path / RUNS_MARKER).write_text("another sweep's token")
    ctx.reduce = SweepRows(2, str(tmp_path), ctx.token)
    rows = run_batches(ctx)
    assert [r["run_file"] for r in rows] == ["run-0000.nc", "run-0001.nc"] and not list(tmp_path.glob("*.nc"))
    write_run_bytes(tmp_path, rows[1]["run_file"], rows[1].pop("run_bytes"))
    with netCDF4.Dataset(tmp_path / "run-0001.nc") as ds:
        assert json.loads(ds.summary)["soc_end"] == rows[1]["soc_end"]


def _train(tmp_path, name: str, runner=None):
    from evtms.surrogates import train
    from tests.test_surrogates import synthetic_refrigerant

    train.train_surrogates(synthetic_refrigerant(), ["bc"], tmp_path / name, quick=True, seed=5, runner=runner)
    return np.load(tmp_path / name / "mode_models.npz")


def _no_times(value):
    if isinstance(value, dict):
        return {k: _no_times(v) for k, v in value.items() if k not in ("created", "time_s")}
    return value


def _same_models(a, b) -> None:
    assert sorted(a.files) == sorted(b.files)
    for name in a.files:
        if name != "attrs":  # holds the creation time and the fits' times
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert _no_times(json.loads(str(a["attrs"]))) == _no_times(json.loads(str(b["attrs"])))


def test_training_split_into_batches_gives_the_serial_models(tmp_path, monkeypatch):
    """The training runs cut into batches of one, computed last first: the models of the serial run."""
    pytest.importorskip("sklearn")
    from evtms.system import sweep

    serial = _train(tmp_path, "serial")
    monkeypatch.setattr(sweep, "batch_size", lambda n, workers: 1)
    _same_models(serial, _train(tmp_path, "reversed", runner=_ReversedRunner()))


@pytest.mark.slow  # two trainings and a cluster: about 20 s on two idle cores, a minute on a busy machine
def test_training_on_workers_gives_the_serial_models(tmp_path, cluster):
    pytest.importorskip("sklearn")
    from evtms.system.sweep import make_runner

    dask = make_runner(scheduler=cluster.scheduler_address)
    try:
        parallel = _train(tmp_path, "dask", runner=dask)
    finally:
        dask.close()
    _same_models(_train(tmp_path, "serial"), parallel)
