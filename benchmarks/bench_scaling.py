"""Sweep scaling: in-process vs dask workers on the condenser bench, and a 3.2-million-point grid.

Run:  python benchmarks/bench_scaling.py [--big]

1. A 100,000-point condenser grid (10 values per axis) in-process and on a
   local dask cluster of 2 single-threaded worker processes. Both runners are
   warmed up first (CoolProp imported, property tables built), so the figures
   are sweep throughput (best of 3 each); the cluster's start-up is reported
   separately.
2. With --big, the 3.2-million-point grid (20 values per axis) with 2 workers:
   wall time and the peak resident memory of the main process and of each
   worker (chunks of 16,384 points).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from evtms.benches import BENCHES  # noqa: E402
from evtms.benches.chunked import DaskRunner, InProcessRunner, sweep_to_file  # noqa: E402
from evtms.benches.parameters import Parameters  # noqa: E402


def grid(n: int) -> dict[str, np.ndarray]:
    return {
        "mdot": np.linspace(0.004, 0.008, n),
        "fan": np.linspace(0.1, 1.0, n),
        "p_in": np.linspace(0.9e6, 1.2e6, n),
        "T_in": np.linspace(330.0, 375.0, n),
        "T_res": np.linspace(300.0, 330.0, n),
    }


def timed(runner, g, folder: Path, name: str, chunk_points: int = 16384) -> float:
    t0 = time.perf_counter()
    sweep_to_file(BENCHES["condenser"], g, Parameters(), folder / name, runner=runner, chunk_points=chunk_points)
    return time.perf_counter() - t0


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true", help="also run the 3.2-million-point grid")
    args = ap.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="evtms-scaling-"))
    g = grid(10)
    warm = grid(4)
    local = InProcessRunner()
    timed(local, warm, folder, "warm_in.nc")
    t_in = min(timed(local, g, folder, "in.nc") for _ in range(3))
    t0 = time.perf_counter()
    dask = DaskRunner(workers=2)
    t_start = time.perf_counter() - t0
    timed(dask, warm, folder, "warm_dask.nc", chunk_points=64)  # each worker builds its tables once
    t_dask = min(timed(dask, g, folder, "dask.nc") for _ in range(3))
    n = 10**5
    print(
        f"100,000 points: in-process {t_in:.2f} s = {n / t_in:,.0f} pt/s; 2 dask workers {t_dask:.2f} s = "
        f"{n / t_dask:,.0f} pt/s; speed-up {t_in / t_dask:.2f}x (cluster start-up {t_start:.1f} s, not included)"
    )
    if args.big:
        t_big = timed(dask, grid(20), folder, "big.nc")
        workers = dask.client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
        size = (folder / "big.nc").stat().st_size / 2**20
        print(
            f"3,200,000 points on 2 workers: {t_big:.1f} s = {3.2e6 / t_big:,.0f} pt/s; peak memory: main "
            f"{peak_mb():.0f} MB, workers {', '.join(f'{v:.0f}' for v in workers.values())} MB; file {size:.0f} MB"
        )
    dask.close()


if __name__ == "__main__":
    main()
