"""The project's performance table in one run: every target figure measured now, the peers side by side.

Run:  python benchmarks/perf_table.py LUT_FOLDER [--all | --grids --demo --maps --physics] [--reduced]
      [--json] [--write] [--suite-seconds S] [--physics-timeout 60] [--direct-points 5] [--repeat 50]
      [--cli-runs 3] [--peer-points 50] [--accuracy-points 100] [--topology cabin] [--profile 50]
      python benchmarks/perf_table.py --dry-run --json     (the rows, none measured)

LUT_FOLDER holds the cycle LUTs (``evtms bench all --grid cycle -o luts/``)
with the simulator's cycle maps cached in its ``maps/`` (a first
``evtms simulate --luts LUT_FOLDER`` builds them). The script benchmarks the
``evtms`` it imports (its path is printed; put the checkout first with
``PYTHONPATH=.`` if another copy is installed) and runs the ``evtms`` command
installed next to the running Python, in the same environment.

The table (``perf_common.TARGETS``): each target row has the measured value,
the target, whether it is met and, where a peer is installed, the peer's
figure and evtms's time / the peer's. Every run prints every row; a row not
run says which option runs it. A quick run (no options) takes a minute or two:

- the direct-physics cycle point: ``--direct-points`` envelope points
  (``benchmarks/accuracy_cycle.py``) solved one at a time in-process with the
  bench physics, after one not counted (CoolProp's set-up), median;
- the LUT cycle on one point, warm (median of ``--repeat`` single-point calls
  on the same solver: ``run_cycle`` would rebuild the interpolators on every
  call), and on 10, 100, 1,000 and 10,000 points in one batch each;
- a first ``evtms cycle run --luts LUT_FOLDER`` on an empty cache folder
  (``EVTMS_CACHE_DIR``: the run builds the cache, as the first run after new
  LUTs does) and the median of ``--cli-runs`` runs on that cache: wall time
  and peak memory of the child process (its own rusage, from ``os.wait4`` in a
  small launcher process);
- the whole ``evtms simulate`` command, maps cached, and the in-process
  ``simulate()`` call (``perf_system.py``);
- the peers (``perf_peers.py``, the ``peers`` extra: ``pip install -e
  '.[peers]'``): TESPy on ``--peer-points`` envelope points one at a time
  (beside the cycle rows), FASTSim-3 over the same WLTC as a library call and
  as a whole process (beside the simulate rows).

Heavy rows, behind options (``--all``: every one):

- ``--grids``: ``evtms bench all --grid cycle -o TMP`` in one process and
  with ``--workers 2`` (for a child with worker processes, peak memory is the
  largest single process of its tree, not their sum);
- ``--maps``: the cycle maps built into a copy of the LUT folder;
- ``--demo``: ``evtms demo -o TMP`` (a fresh folder: every LUT is computed);
- ``--physics``: ``simulate --model physics`` over WLTC at 30 degC and at
  40 degC soaked, each stopped at ``--physics-timeout`` seconds and then
  reported as "more than" that (with the share done and an extrapolation).

``--reduced`` runs the heavy rows at a reduced size where they have one
(``--grid thesis`` for the benches, two-node axes for the maps), to check that
they run: their values are marked as checks and meet no target. The test
suite's time is CI's: ``--suite-seconds S`` puts it in its row.
``--accuracy-points N`` adds the LUT cycle against the direct physics on N
random points (detail rows); ``--profile N`` prints cProfile of N single-point
LUT solves.

Timings are wall-clock (``time.perf_counter``) on whatever else the machine is
running; the machine block says which CPU, how many cores, the load average
and when. ``--json`` prints the machine and the rows as one JSON object on
stdout (the progress goes to stderr). ``--write`` (needs ``--all``, not
``--reduced``) puts the table and the machine into docs/performance.md, which
``performance_page.py`` writes whole.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import importlib.metadata
import io
import json
import platform
import pstats
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import perf_peers
import perf_system
import performance_page
from accuracy_cycle import compare, envelope
from perf_common import TARGETS, Table, child_fields, child_row, compile_bytecode, evtms_command, run_child

import evtms
from evtms.cycle import CycleSolver, OperatingPoints, load_cycle_luts
from evtms.cycle.solver import VALID_CYCLE_FLAGS
from evtms.cycle.topology import topology
from evtms.fluid import Fluid, SaturationCurve

BATCHES = (10, 100, 1000, 10000)
#: The options of the heavy rows, which --all turns on.
HEAVY = ("grids", "demo", "maps", "physics")


# -- machine ------------------------------------------------------------------
def machine() -> dict[str, str]:
    """CPU model, cores, date, load, git commit (the page's fields) and versions, for citing the figures."""
    return {
        **performance_page.machine(Path(evtms.__file__).parent),
        "os": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "evtms": f"{evtms.__version__} ({Path(evtms.__file__).parent})",
        "CoolProp": _version("CoolProp"),
        "numba": _version("numba"),
        "tespy": _version("tespy"),
        "fastsim": _version("fastsim"),
    }


def _version(package: str) -> str:
    """The installed version of ``package`` (its metadata: nothing is imported)."""
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


# -- helpers ------------------------------------------------------------------
def one_point(points: OperatingPoints, i: int) -> OperatingPoints:
    return OperatingPoints(**{k: v[i : i + 1] for k, v in points.subset(np.arange(len(points))).items()})


def valid(result: dict) -> int:
    return int(np.isin(result["status"], VALID_CYCLE_FLAGS).sum())


def per_point(seconds: float) -> str:
    """A time per point in us below a millisecond, else in ms."""
    return f"{seconds * 1e6:.1f} us" if seconds < 1e-3 else f"{seconds * 1e3:.2f} ms"


def single_points(solver: CycleSolver, points: OperatingPoints) -> tuple[np.ndarray, int]:
    """Each point solved alone: the times [ms] and how many solved."""
    times, ok = [], 0
    for i in range(len(points)):
        t0 = time.perf_counter()
        r = solver.solve(one_point(points, i))
        times.append(time.perf_counter() - t0)
        ok += valid(r)
    return np.array(times) * 1e3, ok


# -- in-process cycle ---------------------------------------------------------
def lut_cycle(args, table: Table) -> CycleSolver:
    """Rows lut_point and lut_10000, and the load, first-call and smaller-batch details."""
    from evtms.cycle.models import LutModels

    t0 = time.perf_counter()
    luts = load_cycle_luts(args.luts, args.topology)
    circuit = topology(args.topology)
    solver = CycleSolver(LutModels(luts, circuit.components), SaturationCurve(Fluid()), circuit)
    load = time.perf_counter() - t0
    table.detail("lut_load", "load LUTs + build interpolators (in-process)", f"{load:.2f} s", seconds=load)

    singles = envelope(args.repeat + 1, seed=12)
    t0 = time.perf_counter()
    solver.solve(one_point(singles, 0))
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    solver.solve(one_point(singles, 0))
    t_again = time.perf_counter() - t0
    table.detail(
        "lut_first_call",
        "LUT cycle, one point, first call after load",
        f"{t_first * 1e3:.1f} ms (the same point again: {t_again * 1e3:.1f} ms)",
        ms=t_first * 1e3,
        again_ms=t_again * 1e3,
    )
    paged = page_in(solver)
    table.detail("lut_paged_in", "cycle tables read into the page cache first", f"{paged / 1e6:.0f} MB")
    ms, ok = single_points(solver, OperatingPoints(**singles.subset(np.arange(1, args.repeat + 1))))
    table.add(
        "lut_point",
        f"{np.median(ms):.1f} ms (median of {args.repeat}; 90 % within {np.quantile(ms, 0.9):.1f} ms, "
        f"slowest {ms.max():.0f} ms; {ok}/{args.repeat} valid)",
        median_ms=float(np.median(ms)),
        p90_ms=float(np.quantile(ms, 0.9)),
        max_ms=float(ms.max()),
        n=args.repeat,
    )
    for n in BATCHES:
        points = envelope(n)
        t0 = time.perf_counter()
        r = solver.solve(points)
        dt_ = time.perf_counter() - t0
        value = f"{per_point(dt_ / n)} a point ({dt_:.2f} s; {valid(r)}/{n} valid)"
        fields = {"us_per_point": dt_ / n * 1e6, "seconds": dt_, "n": n}
        if n == 10000:
            table.add("lut_10000", value, **fields)
        else:
            table.detail(f"lut_{n}", f"LUT cycle, {n:,} points in one batch", value, **fields)
    return solver


def page_in(solver: CycleSolver) -> int:
    """Read the files the solver's tables are memory-mapped from once, so that the single-point row
    starts from them in the page cache whatever ran before it (a heavy row of an earlier run evicts
    them, and the first pass then reads from disk: 2-5 ms a point instead of 1-1.5); returns the
    bytes read. The first touch of each page in this process is still timed."""
    files: set[str] = set()
    for lut in solver.models.luts.values():
        lut.no_heat_indicator()  # the tables a NaN cell reads, built on first use
        _mapped_files(lut, files, set())
    total = 0
    for name in sorted(files):
        with open(name, "rb") as f:
            while chunk := f.read(1 << 24):
                total += len(chunk)
    return total


def _mapped_files(obj, files: set[str], seen: set[int], depth: int = 0) -> None:
    """The files of the memory-mapped arrays ``obj`` holds (evtms objects, containers), into ``files``."""
    if id(obj) in seen or depth > 5:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        base = obj
        while base is not None and not isinstance(base, np.memmap):
            base = base.base if isinstance(base, np.ndarray) else None
        if base is not None and base.filename:
            files.add(base.filename)
        return
    if isinstance(obj, dict):
        items = obj.values()
    elif isinstance(obj, (list, tuple)):
        items = obj
    elif type(obj).__module__.startswith("evtms") and hasattr(obj, "__dict__"):
        items = vars(obj).values()
    else:
        return
    for item in items:
        _mapped_files(item, files, seen, depth + 1)


def direct_point(args, table: Table) -> None:
    """Row direct_point: envelope points solved one at a time by the bench physics, after one not counted."""
    from evtms.benches.parameters import Parameters
    from evtms.cycle.models import DirectModels

    fluid = Fluid()
    circuit = topology(args.topology)
    solver = CycleSolver(DirectModels(Parameters(), fluid), SaturationCurve(fluid), circuit)
    points = envelope(args.direct_points + 1, seed=15)
    t0 = time.perf_counter()
    solver.solve(one_point(points, 0))
    first = time.perf_counter() - t0
    ms, ok = single_points(solver, OperatingPoints(**points.subset(np.arange(1, args.direct_points + 1))))
    table.add(
        "direct_point",
        f"{np.median(ms):.0f} ms (median of {args.direct_points}; {ms.min():.0f}-{ms.max():.0f} ms; "
        f"{ok}/{args.direct_points} valid; first call, not counted, {first:.2f} s)",
        median_ms=float(np.median(ms)),
        n=args.direct_points,
    )


def profile(solver: CycleSolver, n: int) -> None:
    points = envelope(n, seed=13)
    singles = [one_point(points, i) for i in range(n)]
    prof = cProfile.Profile()
    prof.enable()
    for p in singles:
        solver.solve(p)
    prof.disable()
    for key, label in (("cumulative", "cumulative"), ("tottime", "own")):
        buf = io.StringIO()
        pstats.Stats(prof, stream=buf).strip_dirs().sort_stats(key).print_stats(10)
        body = buf.getvalue()
        start = body.find("   ncalls")
        print(f"\n== cProfile of {n} single-point solves: top 10 by {label} time")
        print(body[start:].rstrip() if start >= 0 else body.rstrip())


# -- child processes ----------------------------------------------------------
def cli_calls(args, table: Table) -> None:
    """Row first_cycle_run (empty cache folder) and the detail of the runs on that cache."""
    cmd = [*evtms_command(), "cycle", "run", "--luts", str(args.luts)]
    if args.topology != "cabin":
        cmd += ["--topology", args.topology]
    print(f"  (running {' '.join(cmd)}, once on an empty cache folder, then x {args.cli_runs})", flush=True)
    with tempfile.TemporaryDirectory(prefix="evtms-perf-cache-") as cache:
        env = {"EVTMS_CACHE_DIR": cache}
        first = run_child(cmd, env)
        runs = [run_child(cmd, env) for _ in range(args.cli_runs)]
    table.add("first_cycle_run", child_row([first]), **child_fields([first]))
    table.detail(
        "cycle_run_cached",
        f"`evtms cycle run --luts luts/`, cache built (median of {args.cli_runs}; earlier target 1.5 s, 300 MB)",
        child_row(runs),
        **child_fields(runs),
    )


def long_commands(args, table: Table) -> None:
    """Rows bench_all, bench_all_workers (--grids) and demo (--demo)."""
    grid = "thesis" if args.reduced else "cycle"
    bench_all = ["bench", "all", "--grid", grid, "-q"]
    jobs = (
        (args.grids, "bench_all", [*bench_all, "-o"], True),
        (args.grids, "bench_all_workers", [*bench_all, "--workers", "2", "-o"], True),
        (args.demo, "demo", ["demo", "-o"], False),
    )
    for wanted, key, argv, reducible in jobs:
        if not wanted:
            continue
        with tempfile.TemporaryDirectory(prefix="evtms-perf-") as tmp:
            cmd = [*evtms_command(), *argv, tmp]
            print(f"  (running {' '.join(cmd)})", flush=True)
            run = run_child(cmd)
        if args.reduced and reducible:
            table.add(key, f"--grid {grid}, a check only: {child_row([run])}", reduced=True, rc=run["rc"])
        else:
            table.add(key, child_row([run]), rc=run["rc"], **child_fields([run]))


def test_suite(args, table: Table) -> None:
    if args.suite_seconds is not None:
        table.add("test_suite", f"{args.suite_seconds:.0f} s (CI's time, given)", seconds=args.suite_seconds)


# -- accuracy -----------------------------------------------------------------
def accuracy(args, table: Table) -> None:
    figure = f"LUT cycle vs direct physics, {args.accuracy_points} random points"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        compare(envelope(args.accuracy_points), load_cycle_luts(args.luts, args.topology), args.topology)
    detail = buf.getvalue()
    print("\n".join("    " + line for line in detail.splitlines()))
    # compare() prints one "<figure> median ... worst X %" line per figure.
    worst = {m[1]: float(m[2]) for m in re.finditer(r"^(\S+)\s+median .*worst ([0-9.]+) %$", detail, re.M)}
    if not worst:
        table.detail("accuracy", figure, "see the detail above")
        return
    name = max(worst, key=worst.get)
    value = f"worst {worst[name]:.2f} % ({name})"
    if "COP" in worst and name != "COP":
        value += f", COP worst {worst['COP']:.2f} %"
    table.detail("accuracy", figure, value, worst_percent=worst)


# -- peers beside the rows ----------------------------------------------------
def tespy_ratios(table: Table, tespy_ms: float, version: str) -> None:
    """TESPy's median off-design point beside the cycle rows (evtms's time per point / TESPy's)."""
    text = f"TESPy {version} {tespy_ms:.0f} ms a point"
    for key, field, scale in (("direct_point", "median_ms", 1.0), ("lut_point", "median_ms", 1.0)):
        row = table.targets.get(key)
        if row and field in row:
            table.peer(key, text, row[field] * scale / tespy_ms)
    row = table.targets.get("lut_10000")
    if row and "us_per_point" in row:
        table.peer("lut_10000", text, row["us_per_point"] * 1e-3 / tespy_ms)


def fastsim_ratios(table: Table, times: perf_peers.FastsimTimes, call_s: float | None) -> None:
    """FASTSim-3's WLTC beside the simulate rows: its whole process, and its library call."""
    if times.process_s is not None:
        row = table.targets.get("simulate_process")
        ratio = row["wall_s"] / times.process_s if row and "wall_s" in row else None
        table.peer("simulate_process", f"FASTSim-3 whole process {times.process_s:.2f} s", ratio)
    if times.call_s is None:
        return
    text = f"FASTSim-3 library call {times.call_s * 1e3:.0f} ms"
    row = table.targets.get("physics_30")
    if row and "seconds" in row and not row.get("lower_bound"):
        table.peer("physics_30", text, row["seconds"] / times.call_s)
    for row in table.details:
        if row["key"] == "simulate_call" and call_s is not None:
            row["peer"] = f"{text}: evtms / peer {call_s / times.call_s:.3g}"
            row["peer_ratio"] = call_s / times.call_s


# -- main ---------------------------------------------------------------------
def parse(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts", metavar="LUT_FOLDER", nargs="?", help="folder with the cycle LUTs and cached maps")
    ap.add_argument("--all", action="store_true", help="every heavy row: --grids --demo --maps --physics")
    ap.add_argument("--grids", action="store_true", help="time 'evtms bench all --grid cycle', 1 and 2 workers")
    ap.add_argument("--demo", action="store_true", help="time README command 1, 'evtms demo' (minutes)")
    ap.add_argument("--maps", action="store_true", help="time building the simulator's cycle maps")
    ap.add_argument("--physics", action="store_true", help="time 'simulate --model physics' (bounded)")
    ap.add_argument("--reduced", action="store_true", help="heavy rows at a reduced size: a check that they run")
    ap.add_argument("--physics-timeout", type=float, default=60.0, help="seconds before a physics run is stopped")
    ap.add_argument("--suite-seconds", type=float, help="the test suite's time on a clean clone (CI's) [s]")
    ap.add_argument("--dry-run", action="store_true", help="print the rows without measuring any")
    ap.add_argument("--json", action="store_true", help="print the table and machine as one JSON object only")
    ap.add_argument("--topology", default="cabin", help="circuit: cabin, chiller or cabin+chiller")
    ap.add_argument("--direct-points", type=int, default=5, help="points for the direct-physics median")
    ap.add_argument("--accuracy-points", type=int, default=0, help="LUT vs direct on N points (0 = skip)")
    ap.add_argument("--repeat", type=int, default=50, help="single-point LUT solves for the warm median")
    ap.add_argument("--cli-runs", type=int, default=3, help="runs of each whole command (median)")
    ap.add_argument("--peer-points", type=int, default=50, help="points solved by TESPy when it is installed")
    ap.add_argument("--profile", type=int, default=0, help="cProfile N single-point solves (0 = skip)")
    ap.add_argument("--write", action="store_true", help="rewrite docs/performance.md with this run's table")
    args = ap.parse_args(argv)
    if args.all:
        for flag in HEAVY:
            setattr(args, flag, True)
    if args.write and (args.dry_run or args.reduced or not all(getattr(args, f) for f in HEAVY)):
        ap.error("--write needs every row measured at full size: --all, without --reduced or --dry-run")
    if args.luts is None and not args.dry_run:
        ap.error("LUT_FOLDER is required (the folder of 'evtms bench all --grid cycle -o LUT_FOLDER')")
    for name in ("direct_points", "repeat", "cli_runs", "peer_points"):
        if getattr(args, name) < 1:
            ap.error(f"--{name.replace('_', '-')} must be at least 1")
    return args


def measure(args, table: Table) -> CycleSolver:
    """Every row the options ask for, quick ones first; the peers beside them."""
    compile_bytecode()
    solver = lut_cycle(args, table)
    direct_point(args, table)
    cli_calls(args, table)
    perf_system.simulate_process(args, table)
    call_s = perf_system.simulate_call(args, table)
    perf_system.simulate_mpc(args, table)
    long_commands(args, table)
    if args.maps:
        perf_system.maps_build(args, table)
    if args.physics:
        perf_system.physics(args, table)
    test_suite(args, table)
    if args.accuracy_points > 0:
        accuracy(args, table)
    tespy_ms = perf_peers.tespy_peer(args, solver, table)
    if tespy_ms is not None:
        tespy_ratios(table, tespy_ms, _version("tespy"))
    fastsim = perf_peers.fastsim_peer(args, table)
    if fastsim is not None:
        fastsim_ratios(table, fastsim, call_s)
    return solver


def main(argv: list[str] | None = None) -> None:
    args = parse(argv)
    info = machine()
    table = Table()
    # With --json, stdout carries the one JSON object: everything else goes to stderr.
    with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext():
        print("== machine")
        for k, v in info.items():
            print(f"  {k}: {v}")
        solver = None
        if not args.dry_run:
            print(f"== measuring ({args.topology} circuit, LUTs in {args.luts})")
            solver = measure(args, table)
        table.finish("dry run" if args.dry_run else "")
        print(
            f"\n== table ({info['date']}, {info['cpu']}, {info['cores']} cores, load {info['load']}, "
            f"commit {info['commit']})\n"
        )
        print(performance_page.cycle_table({"rows": table.rows}))
        if args.write:
            page = performance_page.write("cycle", {"machine": info, "rows": table.rows})
            print(f"\nwrote {page}")
        if args.profile > 0 and solver is not None:
            profile(solver, args.profile)
    if args.json:
        print(json.dumps({"machine": info, "targets": list(TARGETS), "table": table.rows}, indent=1, default=str))


if __name__ == "__main__":
    main()
