"""The performance table of the cycle and the whole jobs, measured side by side in one run, with the machine.

Run:  python benchmarks/perf_table.py LUT_FOLDER [--grids] [--demo] [--accuracy-points 100] [--json]
      [--topology cabin] [--repeat 50] [--cli-runs 3] [--peer-points 50] [--profile 50] [--write]

LUT_FOLDER holds the cycle LUTs (``evtms bench all --grid cycle -o luts/``).
The script benchmarks the ``evtms`` it imports (its path is printed; put the
checkout first with ``PYTHONPATH=.`` if another copy is installed) and runs the
``evtms`` command installed next to the running Python. It measures:

- loading the LUTs and building the interpolators (in-process, once);
- the LUT cycle on one point: the first ``CycleSolver.solve`` call after the
  load, then the median (and 90th percentile) of ``--repeat`` further
  single-point calls on the same solver and models, one point at a time over
  the envelope of ``benchmarks/accuracy_cycle.py`` (``run_cycle`` would rebuild
  the interpolators on every call, so the solver is called directly);
- the LUT cycle on 10, 100, 1,000 and 10,000 envelope points, one batch each
  (ms per point);
- a cold CLI call ``evtms cycle run --luts LUT_FOLDER``: wall time and peak
  resident memory of the child process (its own rusage, from ``os.wait4`` in
  a small launcher process), first with an empty cache folder
  (``EVTMS_CACHE_DIR``: the run builds the cache, as the first run after the
  LUTs changed does), then the median of ``--cli-runs`` runs on that cache;
- with ``--grids``, ``evtms bench all --grid cycle -o TMP`` in one process
  (about 4 min) and with ``--workers 2``; with ``--demo``, README command 1,
  ``evtms demo -o TMP`` (a fresh folder, so every LUT is computed): wall time
  and peak memory of the child (for a child with worker processes, the largest
  single process of its tree, not their sum);
- with ``--accuracy-points N``, the LUT cycle against the direct physics on N
  random points (``accuracy_cycle.compare``; the direct physics takes about
  0.25 s a point);
- when TESPy is importable (``pip install -e '.[peers]'``), the same envelope
  points solved one at a time by a TESPy R134a cycle (see :func:`tespy_peer`
  for the model and how the inputs map), its time per point and the ratio to
  evtms's;
- with ``--profile N``, cProfile of N single-point solves: the top 10 functions
  by cumulative and by own time.

Timings are wall-clock (``time.perf_counter``) on whatever else the machine is
running; the machine block at the top says which CPU, how many cores, and when.
With ``--write`` (which needs ``--grids`` and ``--demo``: the page's table has
every row) the table and the machine go to docs/performance.md, which
``performance_page.py`` writes whole.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import json
import os
import platform
import pstats
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import performance_page
from accuracy_cycle import compare, envelope

import evtms
from evtms.benches.parameters import Parameters
from evtms.cycle import CycleSolver, OperatingPoints, load_cycle_luts
from evtms.cycle.models import LutModels
from evtms.cycle.solver import VALID_CYCLE_FLAGS
from evtms.cycle.topology import topology
from evtms.fluid import Fluid, SaturationCurve

BATCHES = (10, 100, 1000, 10000)


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
        "tespy": _version("tespy"),
    }


def _version(module: str) -> str:
    try:
        return str(__import__(module).__version__).split()[0]
    except ImportError:
        return "not importable"


# -- helpers ------------------------------------------------------------------
def one_point(points: OperatingPoints, i: int) -> OperatingPoints:
    return OperatingPoints(**{k: v[i : i + 1] for k, v in points.subset(np.arange(len(points))).items()})


def valid(result: dict) -> int:
    return int(np.isin(result["status"], VALID_CYCLE_FLAGS).sum())


def evtms_command() -> list[str]:
    """The ``evtms`` console script of the running Python (not a shell shim), else the one on PATH."""
    exe = Path(sys.executable).with_name("evtms")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("evtms")
    if found is None:
        raise SystemExit("no 'evtms' command found; install the package (pip install -e .)")
    return [found]


#: Runs argv[2:] and writes its wall time and own rusage to argv[1]. A forked child's peak RSS
#: starts from its parent's high-water mark (Linux carries it across exec), so the command is
#: started from this small launcher, not from the benchmark holding the LUTs in memory.
LAUNCHER = """
import json, os, subprocess, sys, time
t0 = time.perf_counter()
proc = subprocess.Popen(sys.argv[2:])
_, status, usage = os.wait4(proc.pid, 0)
wall = time.perf_counter() - t0
with open(sys.argv[1], "w") as f:
    json.dump({"wall_s": wall, "rss_mb": usage.ru_maxrss / 1024.0, "rc": os.waitstatus_to_exitcode(status)}, f)
"""


def run_child(cmd: list[str], env: dict[str, str] | None = None) -> dict:
    """Run ``cmd`` (with ``env`` added to the environment); its wall time [s], peak RSS [MB] (its own rusage),
    exit code and last output lines."""
    with tempfile.TemporaryDirectory(prefix="evtms-perf-") as tmp, tempfile.TemporaryFile() as out:
        report = Path(tmp) / "rusage.json"
        subprocess.run(
            [sys.executable, "-c", LAUNCHER, str(report), *cmd],
            stdout=out,
            stderr=subprocess.STDOUT,
            env={**os.environ, **(env or {})},
        )
        out.seek(0)
        tail = out.read().decode(errors="replace").strip().splitlines()[-3:]
        if not report.exists():
            return {"wall_s": float("nan"), "rss_mb": float("nan"), "rc": -1, "tail": tail}
        return {**json.loads(report.read_text()), "tail": tail}


def child_row(runs: list[dict]) -> str:
    walls = [r["wall_s"] for r in runs]
    rss = [r["rss_mb"] for r in runs]
    failed = sum(r["rc"] != 0 for r in runs)
    text = f"{np.median(walls):.2f} s, {np.median(rss):.0f} MB"
    if len(runs) > 1:
        text += f" (median of {len(runs)}; {min(walls):.2f}-{max(walls):.2f} s)"
    if failed:
        text += f"; {failed} run(s) FAILED: {' | '.join(runs[-1]['tail'])}"
    return text


class Table:
    def __init__(self) -> None:
        self.rows: list[dict] = []

    def add(self, figure: str, value: str, target: str = "", **data) -> None:
        self.rows.append({"figure": figure, "value": value, "target": target, **data})
        print(f"  {figure}: {value}", flush=True)

    def markdown(self) -> str:
        return performance_page.cycle_table({"rows": self.rows})


# -- in-process LUT cycle -----------------------------------------------------
def lut_cycle(args, table: Table) -> CycleSolver:
    t0 = time.perf_counter()
    luts = load_cycle_luts(args.luts, args.topology)
    circuit = topology(args.topology)
    solver = CycleSolver(LutModels(luts, circuit.components), SaturationCurve(Fluid()), circuit)
    load = time.perf_counter() - t0
    table.add("load LUTs + build interpolators (in-process)", f"{load:.2f} s", seconds=load)

    singles = envelope(args.repeat + 1, seed=12)
    t0 = time.perf_counter()
    first = solver.solve(one_point(singles, 0))
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    solver.solve(one_point(singles, 0))
    t_again = time.perf_counter() - t0
    table.add(
        "LUT cycle, one point, first call after load",
        f"{t_first * 1e3:.1f} ms (the same point again: {t_again * 1e3:.1f} ms)",
        ms=t_first * 1e3,
        again_ms=t_again * 1e3,
    )
    times, ok = [], valid(first)
    for i in range(1, args.repeat + 1):
        t0 = time.perf_counter()
        r = solver.solve(one_point(singles, i))
        times.append(time.perf_counter() - t0)
        ok += valid(r)
    ms = np.array(times) * 1e3
    table.add(
        f"LUT cycle, one point (warm, in-process, median of {args.repeat})",
        f"{np.median(ms):.1f} ms (90 % within {np.quantile(ms, 0.9):.1f} ms, "
        f"slowest {ms.max():.0f} ms; {ok - valid(first)}/{args.repeat} valid)",
        "1 ms",
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
        table.add(
            f"LUT cycle, {n:,} points in one batch",
            f"{dt_ / n * 1e3:.3f} ms a point ({dt_:.2f} s; {valid(r)}/{n} valid)",
            "30 us" if n == 10000 else "",
            ms_per_point=dt_ / n * 1e3,
            seconds=dt_,
            n=n,
        )
    return solver


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
    cmd = [*evtms_command(), "cycle", "run", "--luts", str(args.luts)]
    if args.topology != "cabin":
        cmd += ["--topology", args.topology]
    print(f"  (running {' '.join(cmd)}, once on an empty cache folder, then x {args.cli_runs})", flush=True)
    with tempfile.TemporaryDirectory(prefix="evtms-perf-cache-") as cache:
        env = {"EVTMS_CACHE_DIR": cache}
        first = run_child(cmd, env)
        runs = [run_child(cmd, env) for _ in range(args.cli_runs)]
    table.add(
        f"cold `evtms cycle run --luts luts/` (cache warm; median of {args.cli_runs})",
        child_row(runs),
        "1.5 s, 300 MB",
        wall_s=[r["wall_s"] for r in runs],
        rss_mb=[r["rss_mb"] for r in runs],
    )
    table.add(
        "the same, first run after the LUTs changed (builds the cache)",
        child_row([first]),
        wall_s=first["wall_s"],
        rss_mb=first["rss_mb"],
    )


def long_commands(args, table: Table) -> None:
    bench_all = ["bench", "all", "--grid", "cycle", "-q"]
    jobs = (
        (
            args.grids,
            "`evtms bench all --grid cycle` (five benches, one process)",
            [*bench_all, "-o"],
            "40 s",
            "--grids",
        ),
        (args.grids, "the same with `--workers 2`", [*bench_all, "--workers", "2", "-o"], "", "--grids"),
        (args.demo, "README command 1 (`evtms demo`)", ["demo", "-o"], "60 s", "--demo"),
    )
    for wanted, figure, argv, target, flag in jobs:
        if not wanted:
            table.add(figure, f"not run (add {flag})", target)
            continue
        with tempfile.TemporaryDirectory(prefix="evtms-perf-") as tmp:
            cmd = [*evtms_command(), *argv, tmp]
            print(f"  (running {' '.join(cmd)})", flush=True)
            run = run_child(cmd)
        table.add(figure, child_row([run]), target, wall_s=run["wall_s"], rss_mb=run["rss_mb"], rc=run["rc"])


# -- accuracy -----------------------------------------------------------------
def accuracy(args, table: Table) -> None:
    figure = f"LUT cycle vs direct physics, {args.accuracy_points} random points"
    if args.accuracy_points <= 0:
        table.add("LUT cycle vs direct physics", "not run (add --accuracy-points 100)")
        return
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        compare(envelope(args.accuracy_points), load_cycle_luts(args.luts, args.topology), args.topology)
    detail = buf.getvalue()
    print("\n".join("    " + line for line in detail.splitlines()))
    # compare() prints one "<figure> median ... worst X %" line per figure.
    worst = {m[1]: float(m[2]) for m in re.finditer(r"^(\S+)\s+median .*worst ([0-9.]+) %$", detail, re.M)}
    if not worst:
        table.add(figure, "see the detail above")
        return
    name = max(worst, key=worst.get)
    value = f"worst {worst[name]:.2f} % ({name})"
    if "COP" in worst and name != "COP":
        value += f", COP worst {worst['COP']:.2f} %"
    table.add(figure, value, worst_percent=worst)


# -- TESPy --------------------------------------------------------------------
def tespy_peer(args, solver: CycleSolver, table: Table) -> None:
    """The envelope points solved one at a time by TESPy's off-design simulation of a simple R134a cycle.

    Model: compressor (constant isentropic efficiency, evtms's nominal 0.65),
    ``Condenser`` (refrigerant out as saturated liquid, subcooling 0 as in the
    cycle's default), ``Valve``, evaporator ``HeatExchanger`` (air hot side,
    refrigerant cold side), closed by a ``CycleCloser``; no pressure drops;
    both air streams are dry air (TESPy's ``air``: evtms's latent heat has no
    counterpart). Design: evtms's own LUT solution at speed 0.6, fan and blower
    1, ambient 30 degC, cabin 27 degC at RH 0.2 (no condensate there), superheat
    10 K sets the suction and discharge pressures and the refrigerant flow, from
    which TESPy sizes the UA of both coils. Off design (``UA_char`` on both
    coils, TESPy's default characteristic lines) an operating point maps as:
    speed -> suction volume flow ``v = v_design * speed / 0.6`` (constant
    volumetric efficiency); fan, blower -> air volume flow at inlet
    ``fan * fan_flow_max`` of the condenser and evaporator parameters; T_amb,
    T_cabin -> air inlet temperatures at 1 atm; superheat -> ``td_dew`` at the
    evaporator outlet; RH_amb and RH_cabin are not used. Each point starts
    from the previous solution (TESPy's default); a point that does not
    converge is retried once from the design state, and that retry is timed too.
    """
    try:
        import logging

        from tespy.components import Compressor, Condenser, CycleCloser, HeatExchanger, Sink, Source, Valve
        from tespy.connections import Connection
        from tespy.networks import Network
        from tespy.tools.logger import TESPY_LOGGER_ID
    except ImportError:
        table.add("TESPy peer", "TESPy is not importable: skipped (pip install -e '.[peers]')")
        return
    import tespy

    logging.getLogger(TESPY_LOGGER_ID).setLevel(logging.CRITICAL + 1)
    if args.topology != "cabin":
        table.add("TESPy peer", f"modelled for the cabin circuit only, not {args.topology}: skipped")
        return
    params = Parameters()
    design = OperatingPoints(speed=0.6, fan=1.0, blower=1.0, T_amb=303.15, T_cabin=300.15, RH_cabin=0.2, superheat=10.0)
    ref = solver.solve(design)
    if valid(ref) != 1:
        table.add("TESPy peer", f"evtms's design point did not solve ({ref['reason'][0]}): skipped")
        return
    nw = Network(iterinfo=False)
    cc, comp, cond = CycleCloser("cycle closer"), Compressor("compressor"), Condenser("condenser")
    valve, evap = Valve("expansion valve"), HeatExchanger("evaporator")
    amb, amb_out, cab, cab_out = Source("ambient"), Sink("ambient out"), Source("cabin"), Sink("cabin out")
    c0 = Connection(cc, "out1", evap, "in2")
    c1 = Connection(evap, "out2", comp, "in1")
    c2 = Connection(comp, "out1", cond, "in1")
    c3 = Connection(cond, "out1", valve, "in1")
    c4 = Connection(valve, "out1", cc, "in1")
    a1, a2 = Connection(amb, "out1", cond, "in2"), Connection(cond, "out2", amb_out, "in1")
    e1, e2 = Connection(cab, "out1", evap, "in1"), Connection(evap, "out1", cab_out, "in1")
    nw.add_conns(c0, c1, c2, c3, c4, a1, a2, e1, e2)
    comp.set_attr(eta_s=params.compressor.eta_isentropic)
    cond.set_attr(pr1=1, pr2=1, offdesign=["UA_char"])
    evap.set_attr(pr1=1, pr2=1, offdesign=["UA_char"])
    c1.set_attr(fluid={"R134a": 1}, td_dew=10.0, p=float(ref["p_A"][0]), m=float(ref["mdot"][0]), design=["p", "m"])
    c2.set_attr(p=float(ref["p_B"][0]), design=["p"])
    a1.set_attr(fluid={"air": 1}, T=303.15, p=101325.0, v=params.condenser.fan_flow_max)
    e1.set_attr(fluid={"air": 1}, T=300.15, p=101325.0, v=params.evaporator.fan_flow_max)
    t0 = time.perf_counter()
    try:
        nw.solve("design", print_results=False)
    except Exception as exc:  # any TESPy failure skips the peer; it does not end the run
        table.add("TESPy peer", f"TESPy {tespy.__version__.split()[0]} design failed ({exc}): skipped")
        return
    t_design = time.perf_counter() - t0
    if not nw.converged:
        table.add("TESPy peer", f"TESPy {tespy.__version__.split()[0]} design did not converge: skipped")
        return
    state = nw.save(as_dict=True)
    v_design = c1.v.val

    def solve(init_path=None) -> bool:
        try:
            nw.solve(
                "offdesign",
                design_path=state,
                init_path=init_path,
                init_previous=init_path is None,
                print_results=False,
            )
        except Exception:  # a crashed solve is a failed point
            return False
        return bool(nw.converged)

    points = envelope(args.peer_points, seed=14)
    times, converged, retried, cop = [], 0, 0, []
    for i in range(len(points)):
        c1.set_attr(v=v_design * points.speed[i] / 0.6, td_dew=float(points.superheat[i]))
        a1.set_attr(T=float(points.T_amb[i]), v=float(points.fan[i]) * params.condenser.fan_flow_max)
        e1.set_attr(T=float(points.T_cabin[i]), v=float(points.blower[i]) * params.evaporator.fan_flow_max)
        t0 = time.perf_counter()
        ok = solve()
        if not ok:
            retried += 1
            ok = solve(init_path=state)
        times.append(time.perf_counter() - t0)
        converged += ok
        if ok:
            cop.append(-evap.Q.val / comp.P.val)
    ms = np.array(times) * 1e3
    # evtms on the very same points: one at a time, and as one batch.
    single = []
    for i in range(len(points)):
        t0 = time.perf_counter()
        solver.solve(one_point(points, i))
        single.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    r = solver.solve(points)
    batch_ms = (time.perf_counter() - t0) / len(points) * 1e3
    evtms_single = float(np.median(single) * 1e3)
    table.add("TESPy peer: design solve", f"{t_design * 1e3:.0f} ms (TESPy {tespy.__version__.split()[0]})")
    table.add(
        f"TESPy peer: off-design, one point at a time ({len(points)} points)",
        f"{np.median(ms):.1f} ms median, {ms.mean():.1f} ms mean per point; {converged}/{len(points)} converged "
        f"({retried} retried from the design state); median COP {np.median(cop) if cop else float('nan'):.2f}",
        median_ms=float(np.median(ms)),
        mean_ms=float(ms.mean()),
        converged=converged,
        n=len(points),
    )
    table.add(
        "TESPy / evtms LUT time per point, same points",
        f"one at a time: {np.median(ms) / evtms_single:.2f} x (evtms {evtms_single:.1f} ms median); "
        f"evtms as one batch: {ms.mean() / batch_ms:.0f} x (evtms {batch_ms:.2f} ms/pt; "
        f"{valid(r)}/{len(points)} valid, median COP {np.nanmedian(r['COP']):.2f})",
        ratio_single=float(np.median(ms) / evtms_single),
        ratio_batch=float(ms.mean() / batch_ms),
    )


# -- main ---------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts", metavar="LUT_FOLDER", help="folder with the cycle LUTs (evtms bench all --grid cycle)")
    ap.add_argument("--grids", action="store_true", help="also time 'evtms bench all --grid cycle' (about 6 min)")
    ap.add_argument("--demo", action="store_true", help="also time README command 1, 'evtms demo' (minutes)")
    ap.add_argument("--json", action="store_true", help="also print the table and machine as one JSON object")
    ap.add_argument("--topology", default="cabin", help="circuit: cabin, chiller or cabin+chiller")
    ap.add_argument("--accuracy-points", type=int, default=0, help="LUT vs direct on N points (0 = skip)")
    ap.add_argument("--repeat", type=int, default=50, help="single-point solves for the warm median")
    ap.add_argument("--cli-runs", type=int, default=3, help="cold 'cycle run' calls (median)")
    ap.add_argument("--peer-points", type=int, default=50, help="points solved by TESPy when it is installed")
    ap.add_argument("--profile", type=int, default=0, help="cProfile N single-point solves (0 = skip)")
    ap.add_argument("--write", action="store_true", help="rewrite docs/performance.md with this run's table")
    args = ap.parse_args()
    if args.write and not (args.grids and args.demo):
        ap.error("--write needs --grids and --demo: the page's table has every row")

    info = machine()
    print("== machine")
    for k, v in info.items():
        print(f"  {k}: {v}")
    print(f"== measuring ({args.topology} circuit, LUTs in {args.luts})")
    table = Table()
    solver = lut_cycle(args, table)
    cli_calls(args, table)
    long_commands(args, table)
    accuracy(args, table)
    tespy_peer(args, solver, table)
    print(f"\n== table ({info['date']}, {info['cpu']}, {info['cores']} cores, commit {info['commit']})\n")
    print(table.markdown())
    if args.write:
        page = performance_page.write("cycle", {"machine": info, "rows": table.rows})
        print(f"\nwrote {page}")
    if args.profile > 0:
        profile(solver, args.profile)
    if args.json:
        print("\n" + json.dumps({"machine": info, "table": table.rows}, indent=1))


if __name__ == "__main__":
    main()
