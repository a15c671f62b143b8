"""LUT cycle against the direct physics on random points over the whole envelope.

Run:  python benchmarks/accuracy_cycle.py LUT_FOLDER [--points 100]

The tests compare 24 points (fan and blower from 0.2, speed from 0.15); this
script draws points over the full envelope of the README (speed 0.1-1, fan and
blower 0.1-1, ambient 15-45 degC, cabin 15-35 degC at RH 0.2-0.8, superheat
5-10 K) and prints the median, 90th percentile and worst relative error of
the suction and discharge pressures, Q_evap, COP and valve opening, with the
statuses of both solutions. The direct reference takes about 0.25 s a point.
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
from evtms.cycle.solver import VALID_CYCLE_FLAGS


def envelope(n: int, seed: int = 11) -> OperatingPoints:
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.1, 1.0, n),
        fan=rng.uniform(0.1, 1.0, n),
        blower=rng.uniform(0.1, 1.0, n),
        T_amb=rng.uniform(288.15, 318.15, n),
        RH_amb=0.4,
        T_cabin=rng.uniform(288.15, 308.15, n),
        RH_cabin=rng.uniform(0.2, 0.8, n),
        superheat=rng.uniform(5.0, 10.0, n),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts")
    ap.add_argument("--points", type=int, default=100)
    args = ap.parse_args()
    points = envelope(args.points)
    lut = run_cycle(points, load_cycle_luts(args.luts))
    direct = run_cycle(points)
    print(f"statuses: LUT {dict(Counter(lut['status'].tolist()))}, direct {dict(Counter(direct['status'].tolist()))}")
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    print(f"{ok.sum()} points valid in both")
    for name in ("p_A", "p_B", "Q_evap", "COP", "valve_opening"):
        err = np.abs(lut[name][ok] / direct[name][ok] - 1) * 100
        print(
            f"{name:14s} median {np.median(err):.2f} %  90 % within {np.quantile(err, 0.9):.2f} %  "
            f"worst {err.max():.2f} %"
        )


if __name__ == "__main__":
    main()
