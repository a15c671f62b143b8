"""Cycle speed: 1,000 operating points on LUTs in one batch, and the direct-physics median per point.

Run:  python benchmarks/bench_cycle.py LUT_FOLDER [--direct 20]

LUT_FOLDER holds the cabin loop's LUTs written by ``evtms bench all --grid cycle``.
Reports the batched LUT solve (best of 3, after the LUTs are loaded and the
interpolators built) and the median time per point of the direct-physics
reference solved one point at a time.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from evtms.benches.parameters import Parameters  # noqa: E402
from evtms.cycle import OperatingPoints, load_cycle_luts  # noqa: E402
from evtms.cycle.models import DirectModels, LutModels  # noqa: E402
from evtms.cycle.solver import VALID_CYCLE_FLAGS, CycleSolver  # noqa: E402
from evtms.fluid import Fluid, SaturationCurve  # noqa: E402


def points(n: int, seed: int = 5) -> OperatingPoints:
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.2, 1.0, n),
        fan=rng.uniform(0.3, 1.0, n),
        blower=rng.uniform(0.3, 1.0, n),
        T_amb=rng.uniform(293.15, 313.15, n),
        T_cabin=rng.uniform(295.15, 303.15, n),
        RH_cabin=0.5,
        superheat=8.0,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts")
    ap.add_argument("--direct", type=int, default=20, help="points for the direct-physics median")
    args = ap.parse_args()
    fluid = Fluid()
    t0 = time.perf_counter()
    solver = CycleSolver(LutModels(load_cycle_luts(args.luts)), SaturationCurve(fluid))
    print(f"load LUTs and build interpolators: {time.perf_counter() - t0:.2f} s")
    ops = points(1000)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        r = solver.solve(ops)
        best = min(best, time.perf_counter() - t0)
    solved = int(np.isin(r["status"], VALID_CYCLE_FLAGS).sum())
    print(f"LUT cycle: 1000 points in {best:.3f} s ({best:.3f} ms per point), {solved} solved")
    direct = CycleSolver(DirectModels(Parameters(), fluid), SaturationCurve(fluid))
    few = points(args.direct, seed=6)
    times = []
    for i in range(args.direct):
        one = OperatingPoints(**{k: v[i : i + 1] for k, v in few.subset(np.arange(args.direct)).items()})
        t0 = time.perf_counter()
        direct.solve(one)
        times.append(time.perf_counter() - t0)
    print(f"direct-physics cycle: median {np.median(times):.3f} s per point (of {args.direct}, one at a time)")


if __name__ == "__main__":
    main()
