"""benchmarks/perf_table.py: its table has a row for every figure of the project's target table, judges each
against its target (a timed-out run is a bound, not a figure), and refuses to write the page from a partial run.

Nothing here is timed: the benchmark's figures are the benchmark's. The rows are read with ``--dry-run``,
which measures nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"

#: The project's target table: row key -> (words its figure must name, target as printed).
FIGURES = {
    "direct_point": (("direct", "cycle run --direct", "median"), "10 ms"),
    "lut_point": (("LUT cycle", "one point", "warm", "in-process"), "1 ms"),
    "lut_10000": (("LUT cycle", "10,000 points", "per point"), "30 us"),
    "bench_all": (("evtms bench all --grid cycle", "M points", "one process"), ""),
    "bench_all_workers": (("evtms bench all --grid cycle", "--workers 2"), "30 s on 2 cores"),
    "maps_build": (("cycle maps", "build time"), "10 s"),
    "demo": (("evtms demo -o out/", "time and peak memory"), "60 s, 600 MB"),
    "first_cycle_run": (("first `evtms cycle run`", "builds the cache", "memory"), "3 s, 500 MB"),
    "physics_30": (("simulate --model physics", "WLTC 30 degC"), "10 s"),
    "physics_40_soaked": (("simulate --model physics", "WLTC 40 degC", "soaked"), "20 s"),
    "simulate_process": (("whole `evtms simulate --cycle wltc3b", "--json` process", "maps cached"), "0.5 s"),
    "test_suite": (("test suite", "clean clone"), ""),
}


@pytest.fixture
def bench(monkeypatch):
    """The benchmark scripts, importable as they import each other (from their own folder)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import perf_common
    import perf_system
    import perf_table

    return perf_common, perf_system, perf_table


def test_dry_run_json_has_every_figure_of_the_target_table(bench, capsys):
    bench[2].main(["--dry-run", "--json"])
    captured = capsys.readouterr()
    out = json.loads(captured.out)  # stdout is the one JSON object; the progress went to stderr
    assert "== table" in captured.err
    rows = {r["key"]: r for r in out["table"]}
    assert list(rows) == list(FIGURES) == out["targets"]
    for key, (words, target) in FIGURES.items():
        row = rows[key]
        assert all(w in row["figure"] for w in words), (key, row["figure"])
        assert row["target"] == target, key
        assert row["met"] is None and row["value"] == "not run (dry run)" and row["peer"] == ""
    assert {"date", "cpu", "cores", "load", "commit", "tespy", "fastsim"} <= set(out["machine"])


def test_dry_run_prints_the_table_with_met_and_peer_columns(bench, capsys):
    bench[2].main(["--dry-run"])
    out = capsys.readouterr().out
    assert "| figure | measured | target | met | peer |" in out
    assert "| `evtms demo -o out/` (fresh folder), time and peak memory | not run (dry run) | 60 s, 600 MB | | |" in out


@pytest.mark.parametrize(
    "args",
    [["luts", "--write"], ["luts", "--grids", "--demo", "--write"], ["luts", "--all", "--reduced", "--write"]],
)
def test_write_needs_every_row_at_full_size(bench, capsys, args):
    with pytest.raises(SystemExit) as exit_:
        bench[2].parse(args)
    assert exit_.value.code == 2 and "--write needs every row measured at full size" in capsys.readouterr().err


def test_the_lut_folder_is_required_unless_dry_run(bench, capsys):
    with pytest.raises(SystemExit):
        bench[2].parse([])
    assert "LUT_FOLDER is required" in capsys.readouterr().err
    assert bench[2].parse(["--all"] + ["--dry-run"]).physics  # --all turns every heavy row on


def test_rows_are_judged_against_their_targets(bench):
    common = bench[0]
    first = common.TARGETS["first_cycle_run"]  # 3 s and 500 MB: both must hold
    assert common.met({"wall_s": 2.0, "rss_mb": 400.0}, first) is True
    assert common.met({"wall_s": 2.0, "rss_mb": 501.0}, first) is False
    assert common.met({"wall_s": 3.5, "rss_mb": 400.0}, first) is False
    assert common.met({"wall_s": 2.0}, first) is None  # memory not measured: no verdict
    assert common.met({"wall_s": float("nan"), "rss_mb": 1.0}, first) is None  # a failed run
    physics = common.TARGETS["physics_40_soaked"]  # 20 s
    assert common.met({"seconds": 60.0, "lower_bound": True}, physics) is False  # more than 60 s: not met
    assert common.met({"seconds": 15.0, "lower_bound": True}, physics) is None  # more than 15 s: unknown
    assert common.met({"seconds": 1.0}, common.TARGETS["test_suite"]) is None  # no target


def test_table_fills_the_rows_not_run_with_their_option(bench):
    common = bench[0]
    table = common.Table(quiet=True)
    table.add("lut_point", "0.5 ms", median_ms=0.5)
    table.detail("lut_load", "load LUTs", "0.4 s")
    table.peer("lut_point", "TESPy 0.11.3 70 ms a point", 0.5 / 70.0)
    table.peer("demo", "not measured, so no peer")
    table.finish()
    rows = {r["key"]: r for r in table.rows}
    assert [r["key"] for r in table.rows] == [*common.TARGETS, "lut_load"]  # targets in order, then details
    assert rows["lut_point"]["met"] is True and rows["lut_point"]["peer_ratio"] == pytest.approx(0.5 / 70.0)
    assert rows["demo"]["value"] == "not run (add --demo)" and rows["demo"]["peer"] == ""
    assert rows["lut_10000"]["value"] == "not run (not measured)"


def test_a_physics_run_stopped_at_its_limit_is_a_bound(bench):
    common, system = bench[:2]
    lines = [{"setup_s": 3.0}, {"step": 0, "steps": 1800, "s": 0.1, "stops": 1}]
    lines += [{"step": 450, "steps": 1800, "s": 59.0, "stops": 40}, {"step": 450, "steps": 1800, "s": 60.0}]
    lines[-1].update(stops=40, timeout=60.0)
    run = {"out": "\n".join(json.dumps(p) for p in lines), "tail": [], "wall_s": 64.0}
    table = common.Table(quiet=True)
    system.physics_row("physics_30", run, table)
    row = table.targets["physics_30"]
    assert row["value"].startswith("more than 60 s (stopped then: 25% of the cycle done, 40 solver stops")
    assert "about 240 s for the cycle, extrapolated linearly" in row["value"]
    assert row["lower_bound"] and row["seconds"] == 60.0 and row["met"] is False
    lines[-1].update(step=90)  # 5 % of the cycle: too little to extrapolate from
    system.physics_row("physics_30", {**run, "out": "\n".join(json.dumps(p) for p in lines)}, table)
    short = "more than 60 s (stopped then: 5% of the cycle done, 40 solver stops)"
    assert table.targets["physics_30"]["value"] == short
    done = {"summary": {"wall_time_s": 8.0, "physics_solves": 12, "steps": 1800}}
    system.physics_row("physics_40_soaked", {**run, "out": json.dumps(done)}, table)
    row = table.targets["physics_40_soaked"]
    assert row["seconds"] == 8.0 and row["met"] is True and "lower_bound" not in row
