"""Can the evaporator's cycle grid shrink? Axes coarsened, against the direct physics.

Run:  python benchmarks/grid_study.py LUT_FOLDER [--points 100] [--wide 0] [--low-speed 0]
      [--workers 2] [--variants mdot,blower,...,curvature:0.7,...]

For each variant the evaporator LUT is written again on the ``cycle`` preset
with one axis thinned (every other interior node dropped, the ends kept), or
(``curvature:TAU[:TAU_FLOW]``) with the nodes of every axis that the
interpolant needs least dropped while dropping one misses the outlet by less
than ``TAU`` kelvin, and the flow that meets the setpoint by less than
``TAU_FLOW`` per cent, where the cycle's roots lie (``grid_curvature.py``;
the nodes dropped are printed with their misses), into a scratch folder
beside hard links to the folder's other LUTs. The LUT cycle then solves the
accuracy benchmark's random points (``accuracy_cycle.envelope``; ``--wide``
more of its wide envelope; ``--low-speed`` parallel points where the cabin
branch runs at a few g/s, :func:`low_speed`) in the ``cabin`` and
``cabin+chiller`` circuits, compared with the direct physics at the same
points (solved once). The tables give each variant's size and bench time,
and per sample the 90th percentile and the worst of each error; ``cycle`` is
the preset itself. A variant that keeps every one of them within ``--slack``
(relative, default 10 %, or 0.05 percentage points) of the preset's, being
smaller, would win.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from accuracy_cycle import envelope, relative_error
from grid_curvature import curvature_nodes

from evtms.benches import BENCHES
from evtms.cycle import load_cycle_luts, run_cycle
from evtms.cycle.solver import VALID_CYCLE_FLAGS, OperatingPoints

#: Figures whose errors (per cent) the study compares, per circuit.
FIGURES = {
    "cabin": ("p_A", "p_B", "Q_evap", "COP", "valve_opening"),
    "cabin+chiller": ("p_A", "Q_evap", "COP", "split"),
}
AXES = ("mdot", "blower", "p_in", "h_in", "T_air_in", "RH_air_in")


def thinned(values: np.ndarray) -> np.ndarray:
    """Every other interior node dropped, both ends kept."""
    keep = np.zeros(values.size, bool)
    keep[::2] = True
    keep[-1] = True
    return values[keep]


def variant_axes(variant: str | None, source: Path, dropped: list | None = None) -> dict[str, np.ndarray]:
    """The axes a variant changes: ``None`` the preset (none), an axis name that axis thinned,
    ``curvature:TAU[:TAU_FLOW]`` the nodes :func:`grid_curvature.curvature_nodes` keeps (the nodes
    it drops, with their misses, into ``dropped``)."""
    if variant is None:
        return {}
    if variant.startswith("curvature:"):
        return curvature_nodes(source, *(float(t) for t in variant.split(":")[1:]), dropped=dropped)
    return {variant: thinned(np.asarray(BENCHES["evaporator"].presets["cycle"][variant], float))}


def build(folder: Path, source: Path, axes: dict[str, np.ndarray], workers: int) -> tuple[float, float, int]:
    """The evaporator LUT into ``folder`` (the preset with ``axes`` in place of its own), the other
    LUTs linked from ``source``; returns (seconds, MB, points)."""
    for f in source.glob("*.nc"):
        if f.name != "evaporator.nc":
            os.link(f, folder / f.name)
    preset = BENCHES["evaporator"].presets["cycle"]
    cmd = [sys.executable, "-m", "evtms", "bench", "evaporator", "--grid", "cycle", "-q", "-o"]
    cmd += [str(folder / "evaporator.nc"), "--workers", str(workers)]
    for axis, values in axes.items():
        cmd += ["--axis", f"{axis}=" + ",".join(f"{v:.17g}" for v in values)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    seconds = time.perf_counter() - t0
    sizes = [len(axes.get(a, preset[a])) for a in preset]
    return seconds, (folder / "evaporator.nc").stat().st_size / 1e6, int(np.prod(sizes))


def low_speed(n: int, seed: int = 21) -> OperatingPoints:
    """``cabin+chiller`` points at low compressor speed with a mild cabin and warm coolant, where
    the chiller takes most of the flow and the cabin branch runs at a few g/s (about half of them
    below 9 g/s): the branch flows the evaporator's low flow nodes are for."""
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.1, 0.35, n),
        fan=rng.uniform(0.2, 1.0, n),
        blower=rng.uniform(0.1, 0.5, n),
        T_amb=rng.uniform(288.15, 313.15, n),
        RH_amb=0.4,
        T_cabin=rng.uniform(288.15, 303.15, n),
        RH_cabin=rng.uniform(0.2, 0.8, n),
        mdot_coolant=rng.uniform(0.12, 0.45, n),
        T_coolant_in=rng.uniform(293.15, 318.15, n),
        superheat=rng.uniform(5.0, 10.0, n),
    )


def errors(luts, points, direct: dict, circuit: str, figures: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """The LUT cycle's relative errors [%] against ``direct``, (90th percentile, worst) per figure,
    at the points valid in both; ``split`` the chiller's heat off as a share of the total cooling,
    and ``equal`` the statuses that agree (a count, twice)."""
    lut = run_cycle(points, luts, circuit=circuit)
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    rel = {k: relative_error(lut[k][ok], direct[k][ok]) for k in figures if k != "split"}
    if "split" in figures:
        total = np.abs(direct["Q_evap"][ok] + direct["Q_chiller"][ok])
        rel["split"] = np.abs(lut["Q_chiller"][ok] - direct["Q_chiller"][ok]) / total * 100
    out = {k: (float(np.quantile(e, 0.9)), float(e.max())) for k, e in rel.items()}
    equal = float((lut["status"] == direct["status"]).sum())
    return {**out, "equal": (equal, equal)}


def samples(args) -> dict[str, tuple[OperatingPoints, dict[str, tuple[str, ...]]]]:
    """The study's samples: the accuracy benchmark's random points, its wide envelope, and the
    low-speed parallel points (:func:`low_speed`), each with its circuits' figures."""
    out = {"random": (envelope(args.points), FIGURES)}
    if args.wide:
        out["wide"] = (envelope(args.wide, seed=12, wide=True), FIGURES)
    if args.low_speed:
        out["low speed"] = (low_speed(args.low_speed), {"cabin+chiller": ("Q_evap", "COP", "split")})
    return out


def holds(errs: dict, base: dict, slack: float) -> bool:
    """Every 90th percentile and worst error within ``slack`` (or 0.05 percentage points) of the preset's."""
    return all(
        errs[s][c][k][j] <= base[s][c][k][j] * (1 + slack) + 0.05
        for s in base
        for c in base[s]
        for k in base[s][c]
        if k != "equal"
        for j in (0, 1)
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts", type=Path)
    ap.add_argument("--points", type=int, default=100, help="random points of the accuracy benchmark")
    ap.add_argument("--wide", type=int, default=0, help="random points of its wide envelope (default none)")
    ap.add_argument("--low-speed", type=int, default=0, help="low-speed cabin+chiller points (default none)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--variants",
        default=",".join(AXES),
        help="comma-separated: an axis (thinned to every other node) or curvature:TAU[:TAU_FLOW]",
    )
    ap.add_argument("--slack", type=float, default=0.10, help="allowed rise of an error [1]")
    args = ap.parse_args(argv)
    sets = samples(args)
    direct = {s: {c: run_cycle(pts, circuit=c) for c in figs} for s, (pts, figs) in sets.items()}
    rows = []
    for variant in (None, *args.variants.split(",")):
        dropped = []
        axes = variant_axes(variant, args.luts, dropped)
        with tempfile.TemporaryDirectory(prefix="evtms-grid-") as tmp:
            seconds, mb, n = build(Path(tmp), args.luts, axes, args.workers)
            errs = {
                s: {c: errors(load_cycle_luts(tmp, c), pts, direct[s][c], c, f) for c, f in figs.items()}
                for s, (pts, figs) in sets.items()
            }
            shutil.rmtree(tmp, ignore_errors=True)
        rows.append((variant or "cycle", n, mb, seconds, errs))
        print(f"  {rows[-1][0]}: {n:,} points, {mb:.0f} MB, {seconds:.0f} s", file=sys.stderr, flush=True)
        for d in dropped:
            print(f"    dropped {d.axis} {d.value:.4g}: outlet {d.outlet:.3f} K, flow {d.flow:.2f} %", file=sys.stderr)
    base = rows[0][4]
    print("| grid | points | MB | bench s | holds |")
    print("|---|---|---|---|---|")
    for name, n, mb, seconds, errs in rows:
        print(f"| {name} | {n:,} | {mb:.0f} | {seconds:.0f} | {'yes' if holds(errs, base, args.slack) else 'no'} |")
    for s, (pts, figs) in sets.items():
        head = [f"{c} {k}" for c in figs for k in base[s][c] if k != "equal"]
        print(f"\n{s}, {len(pts)} points: error 90th percentile / worst [%], statuses equal")
        print("| grid | " + " | ".join(head) + " | equal |")
        print("|---" * (len(head) + 2) + "|")
        for name, _, _, _, errs in rows:
            cells = [
                f"{errs[s][c][k][0]:.2f} / {errs[s][c][k][1]:.2f}" for c in figs for k in base[s][c] if k != "equal"
            ]
            equal = " / ".join(f"{errs[s][c]['equal'][0]:.0f}" for c in figs)
            print(f"| {name} | " + " | ".join(cells) + f" | {equal} |")


if __name__ == "__main__":
    main()
