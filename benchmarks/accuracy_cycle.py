"""LUT cycle against the direct physics on random points over the whole envelope.

Run:  python benchmarks/accuracy_cycle.py LUT_FOLDER [--points 100] [--topology cabin,chiller,cabin+chiller,hp] [--wide]

The tests compare 24 points (fan and blower from 0.2, speed from 0.15); this
script draws points over the full envelope of docs/guide/cycle.md (speed 0.1-1, fan and
blower 0.1-1, ambient 15-45 degC, cabin 15-35 degC at RH 0.2-0.8, superheat
5-10 K; with --wide ambient -10-50 degC and cabin 10-50 degC, the system
simulator's) and prints the median, 90th percentile and worst relative error of
the suction and discharge pressures, Q_evap, COP and valve opening, the
floating superheat where the valve is saturated in both, the statuses of both
solutions and the worst energy-balance residuals, for each circuit topology
(the chiller's coolant 0.12-0.45 kg/s, the battery pump at 0.3-1 of 4e-4 m3/s, at 15-40 degC; with two branches also the
chiller's heat flow and share of the refrigerant flow). The heat pump ``hp`` has
an envelope of its own (:func:`hp_envelope`: speed 0.1-1, the heating loop at
0.05-0.36 kg/s and 20-70 degC, the e-drive loop at 0.1-0.36 kg/s and -25-35
degC, superheat 5-10 K). The direct reference, on the compiled benches, takes
a few tens of milliseconds a point (100 hp points about 5 s).
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from evtms.cycle import OperatingPoints, load_cycle_luts, run_cycle
from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS, VALVE_SATURATED_FLAGS


def envelope(n: int, seed: int = 11, wide: bool = False) -> OperatingPoints:
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.1, 1.0, n),
        fan=rng.uniform(0.1, 1.0, n),
        blower=rng.uniform(0.1, 1.0, n),
        T_amb=rng.uniform(263.15, 323.15, n) if wide else rng.uniform(288.15, 318.15, n),
        RH_amb=0.4,
        T_cabin=rng.uniform(283.15, 323.15, n) if wide else rng.uniform(288.15, 308.15, n),
        RH_cabin=rng.uniform(0.2, 0.8, n),
        mdot_coolant=rng.uniform(0.12, 0.45, n),
        T_coolant_in=rng.uniform(288.15, 313.15, n),
        superheat=rng.uniform(5.0, 10.0, n),
        # Drawn last: the other inputs stay those of the envelope before the WCC chain.
        mdot_coolant_h=rng.uniform(0.05, 0.36, n),
        T_coolant_h_in=rng.uniform(288.15, 313.15, n),
    )


def hp_envelope(n: int, seed: int = 11) -> OperatingPoints:
    """Random operating points of the heat pump: its coolant loops' ranges (system-v2 spec, section 6)."""
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.1, 1.0, n),
        mdot_coolant_h=rng.uniform(0.05, 0.36, n),
        T_coolant_h_in=rng.uniform(293.15, 343.15, n),
        mdot_coolant=rng.uniform(0.1, 0.36, n),
        T_coolant_in=rng.uniform(248.15, 308.15, n),
        superheat=rng.uniform(5.0, 10.0, n),
    )


#: Figures compared per topology: (result variable, label).
FIGURES = {
    "cabin": ("p_A", "p_B", "Q_evap", "COP", "valve_opening"),
    "chiller": ("p_A", "p_B", "Q_chiller", "COP", "valve_opening"),
    "cabin+chiller": ("p_A", "p_B", "mdot", "Q_evap", "Q_chiller", "mdot_chiller", "COP", "valve_opening"),
    "hp": ("p_A", "p_B", "Q_cond", "Q_chiller", "COP", "COP_heating", "valve_opening"),
    "cabin+wcc": ("p_A", "p_B", "Q_cond", "Q_wcc", "Q_evap", "COP", "valve_opening"),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts")
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--topology", default="cabin,chiller,cabin+chiller")
    ap.add_argument(
        "--wide", action="store_true", help="the system simulator's envelope: ambient -10-50 degC, cabin 10-50 degC"
    )
    args = ap.parse_args()
    points = envelope(args.points, wide=args.wide)
    for circuit in args.topology.split(","):
        print(f"== topology {circuit}, {args.points} random points")
        compare(hp_envelope(args.points) if circuit == "hp" else points, load_cycle_luts(args.luts, circuit), circuit)


def relative_error(lut: np.ndarray, direct: np.ndarray) -> np.ndarray:
    """``|lut / direct - 1|`` in per cent; 0 where both are 0 (a closed branch in both solutions)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(lut - direct) / np.abs(direct) * 100
    return np.where((lut == 0) & (direct == 0), 0.0, err)


def spread(err: np.ndarray) -> str:
    """Median, 90th percentile and worst of errors in per cent."""
    return f"median {np.median(err):.2f} %  90 % within {np.quantile(err, 0.9):.2f} %  worst {err.max():.2f} %"


def compare(points: OperatingPoints, luts, circuit: str) -> None:
    lut = run_cycle(points, luts, circuit=circuit)
    direct = run_cycle(points, circuit=circuit)
    for name, r in (("LUT", lut), ("direct", direct)):
        counts = Counter(CYCLE_FLAGS[c] for c in r["status"].tolist())
        print(f"statuses {name}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    print(f"status equal in {(lut['status'] == direct['status']).sum()} of {len(points)} points")
    for i in np.nonzero(lut["status"] != direct["status"])[0]:
        print(f"  point {i}: LUT {CYCLE_FLAGS[lut['status'][i]]}, direct {CYCLE_FLAGS[direct['status'][i]]}")
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    print(f"{ok.sum()} points valid in both")
    for name in FIGURES[circuit]:
        print(f"{name:14s} {spread(relative_error(lut[name][ok], direct[name][ok]))}")
    if circuit == "cabin+chiller":
        # A branch that takes a small share of the flow has a small heat flow, whose relative error
        # is large (the split is ill-conditioned there): also as a share of the total cooling.
        total = np.abs(direct["Q_evap"][ok] + direct["Q_chiller"][ok])
        print(f"{'total cooling':14s} {spread(relative_error(lut['Q_evap'][ok] + lut['Q_chiller'][ok], -total))}")
        share = {name: np.abs(lut[name][ok] - direct[name][ok]) / total * 100 for name in ("Q_evap", "Q_chiller")}
        for name, err in share.items():
            print(f"{name:14s} of the total cooling: {spread(err)}")
        worst = np.nonzero(ok)[0][np.argmax(share["Q_chiller"])]
        print(
            f"  worst Q_chiller point (of the total): chiller flow {direct['mdot_chiller'][worst] * 1e3:.2f} g/s "
            f"direct, {lut['mdot_chiller'][worst] * 1e3:.2f} g/s LUT, of {direct['mdot'][worst] * 1e3:.1f} g/s"
        )
    if circuit == "cabin+wcc":
        # The WCC's part of the condensing heat, as a share of the whole (small where it takes little).
        err = np.abs(lut["Q_wcc"][ok] - direct["Q_wcc"][ok]) / np.abs(direct["Q_cond"][ok]) * 100
        print(f"{'Q_wcc':14s} of the condensing heat: {spread(err)}")
    # The floating superheat where the valve is saturated in both (it equals the setpoint elsewhere).
    sat = ok & np.isin(lut["status"], VALVE_SATURATED_FLAGS) & np.isin(direct["status"], VALVE_SATURATED_FLAGS)
    if sat.any():
        err = np.abs(lut["superheat_actual"][sat] - direct["superheat_actual"][sat])
        print(
            f"superheat_actual at {sat.sum()} points with the valve saturated in both: median error "
            f"{np.median(err):.2f} K, worst {err.max():.2f} K (floating {direct['superheat_actual'][sat].min():.1f}"
            f"-{direct['superheat_actual'][sat].max():.1f} K)"
        )
    bal = np.abs(direct["balance_relative"][np.isin(direct["status"], VALID_CYCLE_FLAGS)])
    print(f"energy balance, direct: worst {bal.max():.1e} of W_fluid")
    bal = np.abs(lut["balance_relative"][np.isin(lut["status"], VALID_CYCLE_FLAGS)])
    print(f"energy balance, LUT: worst {bal.max():.1e} of W_fluid")


if __name__ == "__main__":
    main()
