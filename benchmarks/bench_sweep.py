"""Time per run of ``evtms sweep`` in this process and on 1 and 2 local dask workers, at 20, 100 and 1,000 scenarios.

Run:  python benchmarks/bench_sweep.py LUT_FOLDER [--sizes 20,100,1000] [--runners in,1,2] [--json]

LUT_FOLDER holds the cycle LUTs with their maps cached (``evtms bench all
--grid cycle -o luts/`` and one ``evtms simulate`` on them); nothing is
written there as long as the parameter variants keep the coolant's flow
(they change the cabin setpoint and the vehicle's mass, which the maps do not
depend on). The scenarios are ambients x the four built-in cycles x parameter
variants: 20 = 5 x 4 x 1, 100 = 5 x 4 x 5, 1,000 = 10 x 4 x 25. Per size and
runner it prints the wall time of the whole request (maps, workers' start,
table), the time of the runs (from the first batch sent to the last row back:
the context's installation on the workers included) and that time per
scenario, the CPU time of the request (this process and its workers) per
scenario, then the marginal wall and CPU cost of a run between the two largest
sizes. The CPU time does not depend on what else the machine runs; the
load average before each measurement is printed: on a shared machine, compare
the runners of one size, measured back to back.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import tempfile
from pathlib import Path

SHAPES = {20: (5, 1), 100: (5, 5), 1000: (10, 25)}  # scenarios -> (ambients, parameter variants); 4 cycles
CYCLES = "wltc3b,nedc,udds,hwfet"


def variants(folder: Path, n: int) -> list[Path]:
    """``n`` system TOML files: cabin setpoints 20-24 degC x vehicle masses 1700-2100 kg."""
    out = []
    for i in range(n):
        p = folder / f"variant-{i:02d}.toml"
        p.write_text(f"[cabin]\nT_set = {293.15 + i % 5:.2f}\n[vehicle]\nmass = {1700.0 + 100.0 * (i // 5):.1f}\n")
        out.append(p)
    return out


def cpu_seconds() -> float:
    """CPU time [s] of this process and of its finished children (the local workers, once their cluster closed)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def measure(luts: Path, size: int, runner: str, tmp: Path) -> dict:
    from evtms.workflows.sweep import SweepRequest, run_sweep

    ambients, n_params = SHAPES[size]
    folder = tmp / f"p{n_params}"
    folder.mkdir(exist_ok=True)
    params = variants(folder, n_params) if n_params > 1 else []
    workers = None if runner == "in" else int(runner)
    load = os.getloadavg()[0]
    cpu0 = cpu_seconds()
    r = run_sweep(
        SweepRequest(
            output=tmp / f"sweep-{size}-{runner}.nc", cycle=CYCLES, t_amb=f"-20:45:{ambients}", params=params,
            luts=luts, workers=workers,
        )
    )  # fmt: skip
    cpu = cpu_seconds() - cpu0
    assert r.scenarios == size and r.failed == 0, (r.scenarios, r.failed)
    return {
        "scenarios": size,
        "runner": "in-process" if workers is None else f"{workers} worker(s)",
        "wall_s": r.wall_time_s,
        "runs_s": r.run_time_s,
        "per_run_ms": 1e3 * r.per_run_s,
        "cpu_s": cpu,
        "cpu_per_run_ms": 1e3 * cpu / size,
        "load": load,
    }


def cpu_model() -> str:
    """The processor's name (Linux: /proc/cpuinfo), else the platform's."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts", type=Path)
    ap.add_argument("--sizes", default="20,100,1000")
    ap.add_argument("--runners", default="in,1,2")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="evtms-bench-sweep-") as tmp:
        for size in (int(s) for s in a.sizes.split(",")):
            for runner in a.runners.split(","):
                rows.append(measure(a.luts, size, runner, Path(tmp)))
                if not a.json:
                    r = rows[-1]
                    print(f"{r['scenarios']:5d} {r['runner']:<12} wall {r['wall_s']:7.2f} s  runs {r['runs_s']:7.2f} s"
                          f"  {r['per_run_ms']:6.1f} ms/run  CPU {r['cpu_s']:6.2f} s, {r['cpu_per_run_ms']:5.1f} ms/run"
                          f"  (load {r['load']:.2f})", flush=True)  # fmt: skip
    sizes = sorted({r["scenarios"] for r in rows})
    marginal = {}
    if len(sizes) >= 2:
        big, small = sizes[-1], sizes[-2]
        for name in dict.fromkeys(r["runner"] for r in rows):
            t = {r["scenarios"]: (r["runs_s"], r["cpu_s"]) for r in rows if r["runner"] == name}
            marginal[name] = tuple(1e3 * (t[big][i] - t[small][i]) / (big - small) for i in (0, 1))
    machine = f"{cpu_model()}, {os.cpu_count()} cores"
    if a.json:
        print(json.dumps({"rows": rows, "marginal_ms_per_run": marginal, "machine": machine}))
        return
    for name, (wall, cpu) in marginal.items():
        print(f"marginal {name}: {wall:.1f} ms wall, {cpu:.1f} ms CPU per run ({sizes[-2]} -> {sizes[-1]} scenarios)")
    print(f"machine: {machine}; python {sys.version.split()[0]}")


if __name__ == "__main__":
    main()
