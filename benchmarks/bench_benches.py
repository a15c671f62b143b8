"""Speed of the benches: thesis grids and 10,000-point grids, one core.

Run:  python benchmarks/bench_benches.py [--repeat 3]

Prints, per bench, the compute time of its thesis grid (CoolProp already
imported and the fluid built, as in a long-running process) and the
throughput in points per second on a 10,000-point grid. Timing is the best of
``--repeat`` runs.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the figures claim
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from evtms.benches import BENCHES  # noqa: E402
from evtms.benches.grid import build_grid  # noqa: E402
from evtms.benches.parameters import Parameters  # noqa: E402
from evtms.benches.sweep import evaluate_grid  # noqa: E402
from evtms.fluid import Fluid  # noqa: E402


def dense_grid(bench, n_target: int = 10_000) -> dict[str, np.ndarray]:
    """A grid of about ``n_target`` points spanning each thesis axis' range."""
    thesis = build_grid(bench, "thesis", {})
    k = len(thesis)
    per_axis = max(2, round(n_target ** (1.0 / k)))
    grid = {name: np.linspace(v.min(), v.max(), per_axis) for name, v in thesis.items()}
    # Trim the last axis so that the total is close to n_target.
    total = per_axis ** (k - 1)
    last = list(grid)[-1]
    grid[last] = np.linspace(thesis[last].min(), thesis[last].max(), max(2, round(n_target / total)))
    return grid


def best_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    params, fluid = Parameters(), Fluid()
    print(f"cores visible: {os.cpu_count()}, one process, CoolProp HEOS")
    total_thesis = 0.0
    points_thesis = 0
    for name, bench in BENCHES.items():
        grid = build_grid(bench, "thesis", {})
        n = int(np.prod([len(v) for v in grid.values()]))
        t = best_time(lambda b=bench, g=grid: evaluate_grid(b, g, params, fluid), args.repeat)
        dense = dense_grid(bench)
        nd = int(np.prod([len(v) for v in dense.values()]))
        td = best_time(lambda b=bench, g=dense: evaluate_grid(b, g, params, fluid), args.repeat)
        total_thesis += t
        points_thesis += n
        print(f"{name:16s} thesis {n:5d} pts {t * 1e3:8.1f} ms | dense {nd:6d} pts {td:6.2f} s = {nd / td:8.0f} pt/s")
    print(f"{'all thesis':16s}        {points_thesis:5d} pts {total_thesis * 1e3:8.1f} ms")


if __name__ == "__main__":
    main()
