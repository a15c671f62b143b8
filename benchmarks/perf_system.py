"""The performance table's system-simulation rows: map build, physics model, the whole `evtms simulate`.

Each row runs in a child process (its own imports, its own peak memory, a
timeout that ends it):

- **maps_build**: ``load_refrigerant`` on a copy of the LUT folder that has no
  ``maps/`` (hard links to the LUT files where the file system allows, so the
  LUTs keep their identity and the cycle's cache stays warm; else copies),
  which builds, writes and loads the three cycle maps with the simulator's
  default settings; the build call's time, and the child's wall time and peak
  memory. ``--reduced`` builds maps of two nodes on speed and on each
  temperature axis instead (a check that the row runs, not the figure).
- **physics_30**, **physics_40_soaked**: ``simulate(model="physics")`` over
  WLTC class 3b at dt 1 s, maps loaded, on a fresh ``Refrigerant`` (the
  physics model reuses the solves of earlier runs on one object). The child
  reports every stop of the loop (a physics solve or a reuse) with the step it
  reached; a ``simulate()`` call still running after ``--physics-timeout``
  seconds (set-up not counted) is stopped and reported as "more than" that,
  with the share of the cycle done and (from a tenth of the cycle done) the
  linear extrapolation of the time to the whole cycle (the solves are not spread evenly over the cycle: the
  extrapolation is a rough figure, the bound is the measurement).
- **simulate_process**: the whole command ``evtms simulate --cycle wltc3b
  --t-amb 30 --luts LUT_FOLDER -o TMP --json`` with the maps cached: one run
  first (not counted; it must find the maps cached, which is checked before),
  then the median of ``--cli-runs``.
- the detail row **simulate_call**: the in-process ``simulate()`` call of the
  LUT model on the same WLTC at 30 degC (maps loaded, compiled; median of
  ``--cli-runs``), beside FASTSim-3's library call;
- the detail row **simulate_mpc**: the same call with the predictive
  controller on a WLTC at 40 degC with sun (best of 3), and its time per
  decision, mean and worst (skipped without the extra ``mpc``).
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

from perf_common import Table, child_fields, child_row, evtms_command, last_json, run_child

#: (T_amb [K], T_init [K] or None, sun [W/m2]) of the physics rows.
PHYSICS_CASES = {
    "physics_30": (303.15, None, 0.0),
    "physics_40_soaked": (313.15, 313.15, 600.0),
}

#: The share of the cycle a stopped physics run must have done for its time to be extrapolated.
MIN_SHARE = 0.1

#: Axis overrides of ``--reduced``: two nodes on speed and on each temperature axis [1, K].
REDUCED_AXES = {
    "speed": (0.3, 1.0),
    "T_amb": (293.15, 313.15),
    "T_air_in": (295.15, 305.15),
    "T_coolant_in": (293.15, 303.15),
}

#: Builds the maps of the LUT folder argv[1] (argv[2]: "reduced" for REDUCED_AXES) and prints the build time.
MAPS_CHILD = """
import json, sys, time
t0 = time.perf_counter()
import dataclasses
from evtms.system.params import SystemParams
from evtms.system.refrigerant import load_refrigerant, map_settings
settings = map_settings(SystemParams())
if sys.argv[2] == "reduced":
    settings = dataclasses.replace(settings, axes=json.loads(sys.argv[3]))
t1 = time.perf_counter()
ref = load_refrigerant(sys.argv[1], settings=settings)
t2 = time.perf_counter()
nodes = {name: int(m.values[..., 0].size) for name, m in ref.maps.items()}
print(json.dumps({"import_s": t1 - t0, "build_s": t2 - t1, "nodes": nodes}), flush=True)
"""

#: Runs the physics model over WLTC 3b (argv: LUT folder, T_amb [K], T_init [K] or "none", sun [W/m2], the time
#: limit of the simulate() call [s]); prints one JSON line per stop of the loop, then the summary, or a "timeout"
#: line when the limit ends the run (SIGALRM: the loop returns to Python at every stop, the solves are Python).
PHYSICS_CHILD = """
import json, os, signal, sys, time
t_start = time.perf_counter()
from evtms.system import loop as L
from evtms.system.drive_cycles import drive_cycle
from evtms.system.refrigerant import load_refrigerant
from evtms.system.simulate import simulate, step_count
refrigerant = load_refrigerant(sys.argv[1])
cycle = drive_cycle("wltc3b")
dt = 1.0
steps = step_count(cycle.duration, dt)
run_loop = L.run_loop
state = {"step": 0, "stops": 0}
def line(**extra):
    print(json.dumps({**state, "steps": steps, "s": time.perf_counter() - t0, **extra}), flush=True)
def traced(*args):
    # simulate() calls L.run_loop until it returns the steps done; a negative return is a stop for a solve.
    done = run_loop(*args)
    state["stops"] += done < 0
    state["step"] = done if done >= 0 else -done - 1
    line()
    return done
def stop(signum, frame):
    line(timeout=float(sys.argv[5]))
    os._exit(3)
L.run_loop = traced
T_init = None if sys.argv[3] == "none" else float(sys.argv[3])
print(json.dumps({"setup_s": time.perf_counter() - t_start}), flush=True)
signal.signal(signal.SIGALRM, stop)
t0 = time.perf_counter()
signal.setitimer(signal.ITIMER_REAL, float(sys.argv[5]))
r = simulate(cycle, float(sys.argv[2]), refrigerant, dt=dt, T_init=T_init, sun=float(sys.argv[4]), model="physics")
signal.setitimer(signal.ITIMER_REAL, 0)
keys = ("wall_time_s", "loop_time_s", "physics_solves", "steps", "hvac_energy_kWh", "T_cabin_end_degC")
print(json.dumps({"summary": {k: r.summary[k] for k in keys}}), flush=True)
"""


def _python() -> list[str]:
    return [sys.executable, "-c"]


# -- maps ---------------------------------------------------------------------
def lut_copy(luts: Path, dest: Path) -> str:
    """The LUT files of ``luts`` (not its maps) in ``dest``: hard links where possible, else copies; which."""
    how = "hard links"
    for f in sorted(luts.glob("*.nc")):
        try:
            os.link(f, dest / f.name)
        except OSError:
            shutil.copy2(f, dest / f.name)
            how = "copies"
    return how


def maps_build(args, table: Table) -> None:
    """Row maps_build: the three cycle maps built into a copy of the LUT folder (child process)."""
    from evtms.cycle.api import cycle_luts_folder

    folder = cycle_luts_folder(args.luts)  # LUT_FOLDER may be evtms demo's output or luts/ folder
    if folder is None:
        table.add("maps_build", f"not run: no cycle LUTs in {args.luts}")
        return
    with tempfile.TemporaryDirectory(prefix="evtms-perf-maps-") as tmp:
        how = lut_copy(folder, Path(tmp))
        argv = [*_python(), MAPS_CHILD, tmp, "reduced" if args.reduced else "full", json.dumps(REDUCED_AXES)]
        print(f"  (building the cycle maps into {tmp}, LUTs as {how})", flush=True)
        run = run_child(argv)
    res = last_json(run["out"])
    if run["rc"] != 0 or res is None:
        table.add("maps_build", f"FAILED: {' | '.join(run['tail'])}")
        return
    nodes = sum(res["nodes"].values())
    value = (
        f"{res['build_s']:.1f} s ({nodes:,} nodes; whole process {run['wall_s']:.1f} s, {run['rss_mb']:.0f} MB; "
        f"LUTs as {how})"
    )
    if args.reduced:
        table.add("maps_build", "reduced axes, a check only: " + value, nodes=nodes, reduced=True)
        return
    table.add("maps_build", value, seconds=res["build_s"], nodes=nodes, wall_s=run["wall_s"], rss_mb=run["rss_mb"])


def missing_maps(luts: Path) -> list[str]:
    """The cycle maps of ``luts`` a simulation with the default parameters reads that are not cached
    (so a run would build them)."""
    from evtms.cycle.api import cycle_luts_folder
    from evtms.luts.store import KEY_ATTR, LutStore
    from evtms.luts.validate import read_map_lut
    from evtms.system.maps import _plan  # the cache key load_maps looks for
    from evtms.system.params import SystemParams
    from evtms.system.refrigerant import map_names, map_settings

    folder = cycle_luts_folder(luts)
    params = SystemParams()
    names = map_names(params)
    if folder is None:
        return list(names)
    settings = map_settings(params)
    store = LutStore(folder)
    missing = []
    for name in names:
        key = _plan(name, folder, settings).key
        found = False
        for path in store.map_places(name):
            try:
                read_map_lut(path, {KEY_ATTR: key})
                found = True
                break
            except Exception:  # missing, stale or damaged: look at the next place
                continue
        if not found:
            missing.append(name)
    return missing


# -- physics model -------------------------------------------------------------
def physics(args, table: Table) -> None:
    """Rows physics_30 and physics_40_soaked: the physics model over WLTC, bounded by the timeout."""
    limit = args.physics_timeout
    for key, (T_amb, T_init, sun) in PHYSICS_CASES.items():
        argv = [*_python(), PHYSICS_CHILD, str(args.luts), str(T_amb), "none" if T_init is None else str(T_init)]
        print(f"  (physics model, WLTC at {T_amb - 273.15:.0f} degC, stopped after {limit:g} s)", flush=True)
        # The child stops itself at the limit; this timeout only guards against a child that hangs in set-up.
        run = run_child([*argv, str(sun), str(limit)], timeout=limit + 600.0)
        physics_row(key, run, table)


def physics_row(key: str, run: dict, table: Table) -> None:
    """The row of one physics run: the simulate() time, or a bound when the time limit stopped the run."""
    lines = []
    for text in run["out"].splitlines():
        try:
            lines.append(json.loads(text))
        except json.JSONDecodeError:  # other output
            continue
    lines = [p for p in lines if isinstance(p, dict)]
    setup = next((p["setup_s"] for p in lines if "setup_s" in p), float("nan"))
    done = next((p["summary"] for p in lines if "summary" in p), None)
    stopped = next((p for p in lines if "timeout" in p), None)
    if done is not None:
        table.add(
            key,
            f"{done['wall_time_s']:.1f} s ({done['physics_solves']} physics solves, {done['steps']} steps; "
            f"whole process {run['wall_s']:.1f} s, of it set-up {setup:.1f} s)",
            seconds=done["wall_time_s"],
            solves=done["physics_solves"],
            wall_s=run["wall_s"],
        )
        return
    if stopped is None:
        table.add(key, f"FAILED: {' | '.join(run['tail'])}")
        return
    share = stopped["step"] / stopped["steps"]
    value = (
        f"more than {stopped['timeout']:g} s (stopped then: {share:.0%} of the cycle done, "
        f"{stopped['stops']} solver stops"
    )
    if share >= MIN_SHARE:  # from a smaller share the extrapolation says nothing
        value += f"; about {stopped['s'] / share:.0f} s for the cycle, extrapolated linearly"
    table.add(key, value + ")", seconds=stopped["timeout"], lower_bound=True, share_done=share)


# -- the whole command ----------------------------------------------------------
def simulate_process(args, table: Table) -> None:
    """Row simulate_process: the whole `evtms simulate` command with the maps cached, median of --cli-runs."""
    missing = missing_maps(Path(args.luts))
    if missing:
        table.add(
            "simulate_process",
            f"not run: maps {', '.join(missing)} not cached in {args.luts} (a run would build them; "
            f"run `evtms simulate --cycle wltc3b --luts {args.luts} -o run.nc` once)",
        )
        return
    with tempfile.TemporaryDirectory(prefix="evtms-perf-sim-") as tmp:
        cmd = [*evtms_command(), "simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", str(args.luts), "--json"]
        print(f"  (running {' '.join(cmd)} -o TMP, once, then x {args.cli_runs})", flush=True)
        run_child([*cmd, "-o", f"{tmp}/warm.nc"])
        runs = [run_child([*cmd, "-o", f"{tmp}/run{i}.nc"]) for i in range(args.cli_runs)]
    table.add("simulate_process", child_row(runs), **child_fields(runs))


def simulate_mpc(args, table: Table) -> None:
    """Detail row: ``simulate()`` with the predictive controller (WLTC at 40 degC, sun 600 W/m2): the whole call
    and the time per decision (mean and worst; the rules' call is the simulate_call row); skipped without the
    extra ``mpc``."""
    import importlib.util

    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.refrigerant import load_refrigerant
    from evtms.system.simulate import simulate

    label = "simulate(), MPC above the rules' local loops, WLTC 40 degC, sun 600 W/m2, in-process"
    if importlib.util.find_spec("casadi") is None or missing_maps(Path(args.luts)):
        table.detail("simulate_mpc", label, "not run: the extra 'mpc' (CasADi) or the maps missing")
        return
    from evtms.system.mpc import CabinMpc

    refrigerant = load_refrigerant(args.luts)
    cycle = drive_cycle("wltc3b")
    runs = [simulate(cycle, 313.15, refrigerant, sun=600.0, controller=CabinMpc()).summary for _ in range(3)]
    best = min(runs, key=lambda r: r["wall_time_s"])
    table.detail(
        "simulate_mpc",
        label + " (best of 3)",
        f"{best['wall_time_s']:.2f} s, {best['controller_solve_mean_s'] * 1e3:.1f} ms a decision (worst "
        f"{best['controller_solve_max_s'] * 1e3:.0f} ms, {best['controller_decisions']} decisions, "
        f"{best['controller_fallbacks']} fallbacks)",
        seconds=best["wall_time_s"],
        solve_mean_s=best["controller_solve_mean_s"],
        solve_max_s=best["controller_solve_max_s"],
    )


def simulate_call(args, table: Table) -> float | None:
    """Detail row: the in-process simulate() call of the LUT model, WLTC at 30 degC; its median [s]."""
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.refrigerant import load_refrigerant
    from evtms.system.simulate import simulate

    if missing_maps(Path(args.luts)):
        table.detail("simulate_call", "simulate(), LUT model, WLTC 30 degC", "not run: maps not cached")
        return None
    refrigerant = load_refrigerant(args.luts)
    cycle = drive_cycle("wltc3b")
    simulate(cycle, 303.15, refrigerant)  # compile / load the cached machine code
    runs = [simulate(cycle, 303.15, refrigerant).summary for _ in range(max(args.cli_runs, 3))]
    wall = statistics.median(r["wall_time_s"] for r in runs)
    loop = statistics.median(r["loop_time_s"] for r in runs)
    table.detail(
        "simulate_call",
        f"simulate(), LUT model, WLTC 30 degC, dt 1 s, in-process (maps loaded, compiled; median of {len(runs)})",
        f"{wall * 1e3:.1f} ms (time loop {loop * 1e3:.2f} ms)",
        seconds=wall,
        loop_s=loop,
    )
    return wall
