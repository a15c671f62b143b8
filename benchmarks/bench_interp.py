"""Interpolation speed: evtms' Interpolator (compiled and NumPy paths) vs scipy's RegularGridInterpolator.

Run:  python benchmarks/bench_interp.py

On a 5-D LUT (the thesis condenser grid's shape, 4 x 4 x 4 x 4 x 3, with
uniform and with non-uniform axes), all in one run, best of 3:

- one million random queries: the compiled path (numba), the NumPy path
  (``EVTMS_NO_NUMBA=1`` uses it everywhere), scipy's RGI, and the compiled
  path with the curvature correction on;
- the time per call at small batches (1, 10, 100, 1,000 points; a mapping
  query as the cycle solver makes them), compiled and NumPy, and the pure-Python
  single-point path ``point()``;
- how long the first compiled call of a fresh process takes (the kernel's
  machine code loaded from numba's cache, or compiled when there is none),
  measured in a child process.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.interpolate import RegularGridInterpolator  # noqa: E402

from evtms.luts import Interpolator  # noqa: E402

FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np
from evtms.luts import Interpolator
t1 = time.perf_counter()
itp = Interpolator([("a", np.linspace(0, 1, 5)), ("b", np.linspace(0, 1, 4))], {"v": np.ones((5, 4))})
t2 = time.perf_counter()
itp({"a": [0.5], "b": [0.5]})
t3 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {t3 - t2:.3f} {itp.compiled}")
"""


def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def per_call(fn, seconds=0.2):
    """Best-of-3 time per call of ``fn``, each round about ``seconds`` long."""
    t0, calls = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds / 4:
        fn()
        calls += 1
    return best(lambda: [fn() for _ in range(4 * calls)]) / (4 * calls)


def first_call() -> None:
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True).stdout
    t_import, t_build, t_first, compiled = out.split()
    print(
        f"fresh process: import evtms.luts {float(t_import):.2f} s, first Interpolator (imports numba) "
        f"{float(t_build):.2f} s, first call {float(t_first):.2f} s (compiled={compiled}; a compile if "
        "numba's cache was empty, else a cache load)"
    )


def main() -> None:
    rng = np.random.default_rng(1)
    shape = (4, 4, 4, 4, 3)
    n = 1_000_000
    table = rng.normal(size=shape)
    first_call()
    for label, make in (
        ("uniform axes", lambda k: np.linspace(0.0, 1.0, k)),
        ("non-uniform axes", lambda k: np.sort(np.r_[0.0, rng.uniform(0, 1, k - 2), 1.0])),
    ):
        axes = [make(k) for k in shape]
        named = [(f"x{i}", a) for i, a in enumerate(axes)]
        pts = np.column_stack([rng.uniform(0, 1, n) for _ in shape])
        ours = Interpolator(named, {"v": table})
        curved = Interpolator(named, {"v": table}, curvature=True)
        ref = RegularGridInterpolator(axes, table)
        numpy_path = lambda o=ours, p=pts: o._call_numpy(p, "error")  # noqa: E731
        t_ours = best(lambda o=ours, p=pts: o(p))
        t_numpy = best(numpy_path)
        t_curved = best(lambda o=curved, p=pts: o(p))
        t_ref = best(lambda r=ref, p=pts: r(p))
        err = np.max(np.abs(ours(pts)["v"] - ref(pts)))
        same = np.array_equal(ours(pts)["v"], numpy_path()["v"])
        print(
            f"{label:17s} 1e6 queries: compiled {t_ours * 1e3:5.0f} ms, NumPy path {t_numpy * 1e3:5.0f} ms, "
            f"scipy RGI {t_ref * 1e3:5.0f} ms (compiled vs RGI {t_ref / t_ours:4.1f}x, max |diff| {err:.1e}; "
            f"compiled == NumPy path bit for bit: {same}); with curvature {t_curved * 1e3:4.0f} ms"
        )
        for m in (1, 10, 100, 1000):
            query = {name: pts[:m, j].copy() for j, (name, _) in enumerate(named)}
            t_c = per_call(lambda o=ours, q=query: o(q))
            t_n = per_call(lambda o=ours, q=query: o._call_numpy(q, "error"))
            print(
                f"{'':17s} {m:5d} point(s) a call: compiled {t_c * 1e6:7.1f} us, NumPy path {t_n * 1e6:7.1f} us "
                f"({t_n / t_c:5.1f}x)"
            )
        rows = pts[:20000].tolist()
        t0 = time.perf_counter()
        for row in rows:
            ours.point(*row)
        t_point = (time.perf_counter() - t0) / len(rows)
        print(f"{'':17s} point(): {t_point * 1e6:5.1f} us/call (pure Python)")


if __name__ == "__main__":
    main()
