"""Can the evaporator's cycle grid shrink? Axes coarsened, against the direct physics.

Run:  python benchmarks/grid_study.py LUT_FOLDER [--points 100] [--workers 2]
      [--variants mdot,blower,...,curvature:0.7,...]

For each variant the evaporator LUT is written again on the ``cycle`` preset
with one axis thinned (every other interior node dropped, the ends kept), or
(``curvature:TAU[:TAU_FLOW]``) with the nodes of every axis that the
interpolant needs least dropped while dropping one misses the outlet by
less than ``TAU`` kelvin, and the flow that meets the setpoint by less than
``TAU_FLOW`` per cent, where the cycle's roots lie (``grid_curvature.py``), into a scratch
folder beside hard links to the folder's other LUTs; the
LUT cycle then solves the accuracy benchmark's random points
(``accuracy_cycle.envelope``) in the ``cabin`` and ``cabin+chiller``
circuits and is compared with the direct physics at the same points
(solved once). The table gives each variant's size, its bench time and the
worst errors the accuracy benchmark reports; ``cycle`` is the preset itself.
A variant that keeps every worst error within ``--slack`` (relative, default
10 %, or 0.05 percentage points) of the preset's, being smaller, would win.
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
from evtms.cycle.solver import VALID_CYCLE_FLAGS

#: Figures whose worst error (per cent) the study compares, per circuit.
FIGURES = {"cabin": ("p_A", "p_B", "Q_evap", "COP", "valve_opening"), "cabin+chiller": ("p_A", "Q_evap", "COP")}
AXES = ("mdot", "blower", "p_in", "h_in", "T_air_in", "RH_air_in")


def thinned(values: np.ndarray) -> np.ndarray:
    """Every other interior node dropped, both ends kept."""
    keep = np.zeros(values.size, bool)
    keep[::2] = True
    keep[-1] = True
    return values[keep]


def variant_axes(variant: str | None, source: Path) -> dict[str, np.ndarray]:
    """The axes a variant changes: ``None`` the preset (none), an axis name that axis thinned,
    ``curvature:TAU`` the nodes :func:`grid_curvature.curvature_nodes` keeps."""
    if variant is None:
        return {}
    if variant.startswith("curvature:"):
        return curvature_nodes(source, *(float(t) for t in variant.split(":")[1:]))
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


def worst(luts, points, direct: dict, circuit: str) -> dict[str, float]:
    """Worst relative errors [%] of the LUT cycle against ``direct``, and the statuses that agree."""
    lut = run_cycle(points, luts, circuit=circuit)
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    out = {k: float(relative_error(lut[k][ok], direct[k][ok]).max()) for k in FIGURES[circuit]}
    if circuit == "cabin+chiller":
        total = np.abs(direct["Q_evap"][ok] + direct["Q_chiller"][ok])
        out["split"] = float((np.abs(lut["Q_chiller"][ok] - direct["Q_chiller"][ok]) / total * 100).max())
    out["equal"] = float((lut["status"] == direct["status"]).sum())
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts", type=Path)
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--variants", default=",".join(AXES), help="axes to thin, comma-separated")
    ap.add_argument("--slack", type=float, default=0.10, help="allowed rise of a worst error [1]")
    args = ap.parse_args(argv)
    points = envelope(args.points)
    direct = {c: run_cycle(points, circuit=c) for c in FIGURES}
    rows = []
    for variant in (None, *args.variants.split(",")):
        axes = variant_axes(variant, args.luts)
        with tempfile.TemporaryDirectory(prefix="evtms-grid-") as tmp:
            seconds, mb, n = build(Path(tmp), args.luts, axes, args.workers)
            errors = {c: worst(load_cycle_luts(tmp, c), points, direct[c], c) for c in FIGURES}
            shutil.rmtree(tmp, ignore_errors=True)
        rows.append((variant or "cycle", n, mb, seconds, errors))
        for axis, values in axes.items():
            print(f"    {axis}: {len(values)} nodes, {', '.join(f'{v:.4g}' for v in values)}", file=sys.stderr)
        print(f"  {rows[-1][0]}: {n:,} points, {mb:.0f} MB, {seconds:.0f} s, {errors}", file=sys.stderr, flush=True)
    base = rows[0][4]
    head = [f"{c} {k}" for c in FIGURES for k in base[c] if k != "equal"]
    print("| grid | points | MB | bench s | " + " | ".join(head) + " | statuses equal | holds |")
    print("|---" * (len(head) + 6) + "|")
    for name, n, mb, seconds, errors in rows:
        cells = [f"{errors[c][k]:.2f} %" for c in FIGURES for k in base[c] if k != "equal"]
        holds = all(
            errors[c][k] <= base[c][k] * (1 + args.slack) + 0.05 for c in FIGURES for k in base[c] if k != "equal"
        )
        equal = " / ".join(f"{errors[c]['equal']:.0f}" for c in FIGURES)
        print(
            f"| {name} | {n:,} | {mb:.0f} | {seconds:.0f} | "
            + " | ".join(cells)
            + f" | {equal} | {'yes' if holds else 'no'} |"
        )


if __name__ == "__main__":
    main()
