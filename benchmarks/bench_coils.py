"""Speed of the coils: the compiled march on tabulated properties against the NumPy march on CoolProp.

Run:  python benchmarks/bench_coils.py [--points 16384] [--json]

For the condenser and the evaporator: the CPU time of one call on one point
through the cycle's direct models (``DirectModels.condenser`` /
``.evaporator``, median of 200), and the CPU time per point of a random sample
of the bench's cycle grid (``--points`` of them, one call, the air-property
caches warm), each with the march compiled (``solve_coil(compiled=True)``) and
as NumPy (``compiled=False``). CPU time, not wall time: the figures hold on a
shared machine. The one-time costs (building the property tables, loading the
compiled code, the moist-air lines) are paid before timing.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import evtms.benches.condenser as condenser_module
from evtms.benches import BENCHES
from evtms.benches.coil import solve_coil
from evtms.benches.parameters import Parameters
from evtms.cycle.models import DirectModels
from evtms.fluid import Fluid


def sample(bench, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` random nodes of the bench's cycle grid."""
    grid = bench.presets["cycle"]
    axes = [np.asarray(v, float) for v in grid.values()]
    rng = np.random.default_rng(seed)
    return {name: a[rng.integers(0, a.size, n)] for name, a in zip(grid, axes, strict=True)}


def one_point(models: DirectModels, component: str, i: int) -> None:
    if component == "condenser":
        models.condenser(*(np.array([v]) for v in (0.03, 0.6, 13e5, 440e3 + i, 303.15, 0.4)))
    else:
        models.evaporator(*(np.array([v]) for v in (0.03, 0.5, 3.5e5, 250e3 + i, 300.15, 0.5)))


def cpu(fn) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=16384)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    params, fluid = Parameters(), Fluid()
    models = DirectModels(params, fluid)
    figures = {}
    for component in ("condenser", "evaporator"):
        bench = BENCHES[component]
        inputs = sample(bench, args.points)
        for compiled in (True, False):
            # The benches call solve_coil through the condenser module: switch the march there.
            condenser_module.solve_coil = lambda *a, c=compiled, **k: solve_coil(*a, **{**k, "compiled": c})
            key = f"{component}_{'compiled' if compiled else 'numpy'}"
            bench.evaluate(inputs, params, fluid)  # warm: tables, compiled code, air lines
            per_point = cpu(lambda b=bench, x=inputs: b.evaluate(x, params, fluid)) / args.points
            for i in range(20):
                one_point(models, component, i)
            calls = [cpu(lambda i=i, c=component: one_point(models, c, i)) for i in range(200)]
            figures[key] = {"one_point_call_ms": float(np.median(calls) * 1e3), "grid_us_per_point": per_point * 1e6}
        condenser_module.solve_coil = solve_coil
    if args.json:
        print(json.dumps(figures))
        return
    for key, f in figures.items():
        print(f"{key:22s} one-point call {f['one_point_call_ms']:.3f} ms, grid {f['grid_us_per_point']:.1f} us/point")


if __name__ == "__main__":
    main()
