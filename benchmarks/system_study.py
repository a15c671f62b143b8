"""Step-size study and performance of the system simulator (cf. the thesis' Tables 5-6).

Run:  python benchmarks/system_study.py LUT_FOLDER [--json] [--repeat 20] [--sweep 64] [--write]
      python benchmarks/system_study.py LUT_FOLDER --markdown RESULT.json [--write]

LUT_FOLDER holds the cycle LUTs (``evtms bench all --grid cycle -o luts/``);
the cycle maps are built there on first use. It prints:

- **step size**: WLTC class 3b at 40 degC (hot soak: cabin, battery and
  coolant start at 40 degC, or 39 degC, sun 600 W/m2) and at -5 degC, auto mode, with
  dt = 0.01, 0.1, 1 and 10 s: every ``--json`` figure and its relative
  deviation from dt = 0.01 s, and the worst ledger residual per dt;
- **performance**: the time loop alone (maps loaded, compiled) for WLTC at
  dt = 0.1 s and 1 s, median of ``--repeat`` runs; the whole command
  ``evtms simulate --cycle wltc3b --t-amb 30 -o TMP --json`` with the maps
  cached (median of 3, wall time of the child); and a ``--sweep N``-scenario
  sweep (N ambients from -20 to 45 degC in one call) per run.

The project's target table (the physics model, the whole command against its
0.5 s target, FASTSim-3 beside it) is ``perf_table.py``'s; this script's
figures are the step-size study and the loop's own speed.

``--write`` puts the performance figures and the machine into
docs/performance.md, which ``performance_page.py`` writes whole; the step-size
table is docs/guide/system.md's (``--markdown`` prints both tables). With
``--markdown`` a stored ``--json`` result is printed (and written) instead of
measuring again.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import performance_page

FIELDS = (
    "traction_energy_kWh",
    "battery_energy_kWh",
    "battery_chemical_kWh",
    "hvac_energy_kWh",
    "soc_end",
    "T_cabin_end_degC",
    "T_battery_end_degC",
    "distance_km",
)
# The 40 degC soak starts the battery exactly at the critical-cooling relay's threshold (40 degC): whether
# the relay trips in the first second depends on the step, so the 39 degC soak shows the smooth case.
CASES = {
    "40 degC, soaked at 40 degC": dict(T_amb=313.15, T_init=313.15, sun=600.0),
    "40 degC, soaked at 39 degC": dict(T_amb=313.15, T_init=312.15, sun=600.0),
    "-5 degC": dict(T_amb=268.15),
}


def machine() -> dict:
    """The page's fields (date, CPU, cores, load, git commit) and the versions that set the loop's speed."""
    import numba

    import evtms

    return {
        **performance_page.machine(Path(evtms.__file__).parent),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }


def step_study(cycle, refrigerant) -> dict:
    from evtms.system.simulate import simulate

    out = {}
    for case, kw in CASES.items():
        T_amb = kw.pop("T_amb")
        runs = {dt: simulate(cycle, T_amb, refrigerant, dt=dt, **kw) for dt in (0.01, 0.1, 1.0, 10.0)}
        kw["T_amb"] = T_amb
        ref = runs[0.01].summary
        rows = {}
        for dt, r in runs.items():
            s = r.summary
            dev = {}
            for f in FIELDS:
                if f.endswith("degC"):
                    dev[f] = s[f] - ref[f]  # kelvin
                else:
                    dev[f] = (s[f] - ref[f]) / abs(ref[f]) if ref[f] else 0.0
            rows[dt] = {"values": {f: s[f] for f in FIELDS}, "deviation": dev, "ledger_worst": s["ledger_worst"]}
        out[case] = rows
    return out


def performance(cycle, refrigerant, luts: Path, repeat: int, sweep: int) -> dict:
    from evtms.system.simulate import simulate

    res = {}
    for dt in (0.1, 1.0):
        simulate(cycle, 303.15, refrigerant, dt=dt)  # compile / load the cached machine code
        loops, walls = [], []
        for _ in range(repeat):
            r = simulate(cycle, 303.15, refrigerant, dt=dt)
            loops.append(r.summary["loop_time_s"])
            walls.append(r.summary["wall_time_s"])
        res[f"loop_dt{dt:g}_s"] = statistics.median(loops)
        res[f"simulate_call_dt{dt:g}_s"] = statistics.median(walls)
    exe = Path(sys.executable).with_name("evtms")
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [str(exe), "simulate", "--cycle", "wltc3b", "--t-amb", "30", "--luts", str(luts), "--json"]
        times = []
        for i in range(3):
            t0 = time.perf_counter()
            p = subprocess.run([*cmd, "-o", f"{tmp}/run{i}.nc"], capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if p.returncode:
                raise SystemExit(p.stderr)
        res["cli_wall_s"] = statistics.median(times)
        res["cli_json"] = json.loads(p.stdout)
        t0 = time.perf_counter()
        p = subprocess.run(
            [*cmd[:5], f"-20:45:{sweep}", *cmd[6:], "-o", f"{tmp}/sweep.nc"], capture_output=True, text=True
        )
        if p.returncode:
            raise SystemExit(p.stderr)
        wall = time.perf_counter() - t0
        runs = json.loads(p.stdout)["runs"]
        res["sweep_runs"] = len(runs)
        res["sweep_wall_s"] = wall
        res["sweep_per_run_s"] = wall / len(runs)
        res["sweep_loop_per_run_s"] = statistics.median(r["loop_time_s"] for r in runs)
    return res


def page_entry(result: dict, repeat: int) -> dict:
    """The performance page's entry of a result: its machine and performance figures (no step sizes)."""
    m = result["machine"]
    load = m.get("load", "")
    fields = {k: str(m.get(k, "")) for k in ("date", "cpu", "cores", "commit")}
    fields["load"] = f"{load:.1f}" if isinstance(load, float) else str(load)
    perf = {k: v for k, v in result["performance"].items() if k != "cli_json"}
    return {"machine": fields, "repeat": repeat, "performance": perf}


def markdown(result: dict, repeat: int = 20) -> str:
    """The step-size table (docs/guide/system.md) and the performance table (docs/performance.md) of a result."""
    short = {
        "battery_energy_kWh": "battery energy",
        "battery_chemical_kWh": "chemical",
        "hvac_energy_kWh": "HVAC energy",
        "soc_end": "SOC end",
        "T_cabin_end_degC": "cabin end [K]",
        "T_battery_end_degC": "battery end [K]",
    }
    lines = ["| case | dt [s] | " + " | ".join(short.values()) + " | worst ledger |", "|---" * (len(short) + 3) + "|"]
    for case, rows in result["step_size"].items():
        for dt, row in rows.items():
            if float(dt) == 0.01:
                continue
            cells = []
            for f in short:
                v = row["deviation"][f]
                cells.append(f"{v:+.3f}" if f.endswith("degC") else f"{100 * v:+.3f} %")
            lines.append(f"| {case} | {float(dt):g} | " + " | ".join(cells) + f" | {row['ledger_worst']:.0e} |")
    entry = page_entry(result, repeat)
    perf = performance_page.measured_line(entry["machine"]) + "\n\n" + performance_page.system_table(entry)
    return "\n".join(lines) + "\n\n" + perf


def model_speed(cycle, refrigerant, mode_models, repeat: int) -> dict:
    """Loop time of the LUT and surrogate models, WLTC at 30 degC, dt 0.1 and 1 s (median of ``repeat``)."""
    from evtms.system.simulate import simulate

    res = {}
    for model in ("lut", "surrogate"):
        for dt in (0.1, 1.0):
            kw = {"dt": dt, "model": model, "mode_models": mode_models}
            simulate(cycle, 303.15, refrigerant, **kw)  # compile / load the cached machine code
            runs = [simulate(cycle, 303.15, refrigerant, **kw).summary for _ in range(repeat)]
            res[f"{model}_loop_dt{dt:g}_s"] = statistics.median(r["loop_time_s"] for r in runs)
            res[f"{model}_call_dt{dt:g}_s"] = statistics.median(r["wall_time_s"] for r in runs)
    widths = {h: [w.shape[1] for w in getattr(mode_models, h)[3].weights] for h in ("power", "dynamics")}
    res["cc_network_widths"] = widths
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("luts", type=Path)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--sweep", type=int, default=64)
    ap.add_argument("--markdown", type=Path, help="Read a --json result from this file and print its tables.")
    ap.add_argument("--write", action="store_true", help="Rewrite docs/performance.md with the performance figures.")
    ap.add_argument("--surrogates", type=Path, help="Mode-model file: also time the surrogate against the LUT loop.")
    args = ap.parse_args()
    if args.markdown:
        result = json.loads(args.markdown.read_text())
        print(markdown(result, args.repeat))
        if args.write:
            print(f"\nwrote {performance_page.write('system', page_entry(result, args.repeat))}")
        return
    if args.write and args.surrogates:
        ap.error("--write takes the step-size and performance run, not --surrogates")
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.refrigerant import load_refrigerant

    refrigerant = load_refrigerant(args.luts)
    cycle = drive_cycle("wltc3b")
    result = {"machine": machine()}
    if args.surrogates:
        from evtms.surrogates.io import load_mode_models

        result["models"] = model_speed(cycle, refrigerant, load_mode_models(args.surrogates), args.repeat)
        print(json.dumps(result, indent=1, default=str))
        return
    result["step_size"] = step_study(cycle, refrigerant)
    result["performance"] = performance(cycle, refrigerant, args.luts, args.repeat, args.sweep)
    if args.write:
        print(f"wrote {performance_page.write('system', page_entry(result, args.repeat))}")
    if args.json:
        print(json.dumps(result, indent=1, default=str))
        return
    m = result["machine"]
    print(f"{m['date']}  {m['cpu']}  {m['cores']} cores  load {m['load']}  commit {m['commit']}  numba {m['numba']}")
    for case, rows in result["step_size"].items():
        print(f"\nWLTC, {case}: deviation from dt = 0.01 s (relative; degC fields in K)")
        print(f"{'dt [s]':>7} " + " ".join(f"{f.replace('_kWh', '').replace('_degC', ''):>16}" for f in FIELDS))
        for dt, row in rows.items():
            cells = " ".join(f"{row['deviation'][f]:16.2e}" for f in FIELDS)
            print(f"{dt:7g} {cells}   ledger {row['ledger_worst']:.1e}")
    p = result["performance"]
    print(f"\ntime loop, WLTC dt 0.1 s: {p['loop_dt0.1_s'] * 1e3:.1f} ms; dt 1 s: {p['loop_dt1_s'] * 1e3:.2f} ms")
    print(f"simulate() call, dt 0.1 s: {p['simulate_call_dt0.1_s'] * 1e3:.1f} ms")
    print(f"evtms simulate (maps cached), whole command: {p['cli_wall_s']:.2f} s")
    print(
        f"sweep of {p['sweep_runs']} ambients in one call: {p['sweep_wall_s']:.2f} s, "
        f"{p['sweep_per_run_s'] * 1e3:.1f} ms per run (loop {p['sweep_loop_per_run_s'] * 1e3:.2f} ms)"
    )


if __name__ == "__main__":
    main()
