"""Interpolation speed: evtms' Interpolator vs scipy's RegularGridInterpolator.

Run:  python benchmarks/bench_interp.py

One million random queries on a 5-D LUT (the thesis condenser grid's shape,
4 x 4 x 4 x 4 x 3, with uniform and with non-uniform axes), both
interpolators side by side in one run, best of 3; then the single-point path
in microseconds per call.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.interpolate import RegularGridInterpolator  # noqa: E402

from evtms.luts import Interpolator  # noqa: E402


def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(1)
    shape = (4, 4, 4, 4, 3)
    n = 1_000_000
    table = rng.normal(size=shape)
    for label, make in (
        ("uniform axes", lambda k: np.linspace(0.0, 1.0, k)),
        ("non-uniform axes", lambda k: np.sort(np.r_[0.0, rng.uniform(0, 1, k - 2), 1.0])),
    ):
        axes = [make(k) for k in shape]
        pts = np.column_stack([rng.uniform(0, 1, n) for _ in shape])
        ours = Interpolator([(f"x{i}", a) for i, a in enumerate(axes)], {"v": table})
        ref = RegularGridInterpolator(axes, table)
        t_ours = best(lambda o=ours, p=pts: o(p))
        t_ref = best(lambda r=ref, p=pts: r(p))
        err = np.max(np.abs(ours(pts)["v"] - ref(pts)))
        print(
            f"{label:17s} 1e6 queries: evtms {t_ours * 1e3:6.0f} ms, scipy RGI {t_ref * 1e3:6.0f} ms, "
            f"speed-up {t_ref / t_ours:4.1f}x, max |diff| {err:.1e}"
        )
        rows = pts[:20000].tolist()
        t0 = time.perf_counter()
        for row in rows:
            ours.point(*row)
        t_point = (time.perf_counter() - t0) / len(rows)
        one = pts[:1]
        t_batch1 = best(lambda o=ours, q=one: [o(q) for _ in range(2000)]) / 2000
        print(
            f"{'':17s} single point: point() {t_point * 1e6:5.1f} us/call, "
            f"batched call of 1 point {t_batch1 * 1e6:5.1f} us"
        )


if __name__ == "__main__":
    main()
