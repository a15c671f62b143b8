"""Two or more simulation files side by side: cabin air (with its 60-s mean and the set point's +-1 K),
vent and evaporator air, and the mode over time.

Run:  python benchmarks/runs_figure.py A.nc B.nc --labels "v1,v2" --t-set 22 -o docs/figures/x.png

The before/after figure of docs/guide/system.md of the climate control is drawn with it
(the "before" file written by the first version's `evtms simulate`, which has
no vent or evaporator air records: those panels then show what the file has).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402


def moving_mean(t: np.ndarray, v: np.ndarray, window: float) -> np.ndarray:
    """Trailing mean over ``window`` [s] (trapezoids); NaN before one window."""
    integral = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
    mean = (integral - np.interp(t - window, t, integral)) / window
    return np.where(t - t[0] >= window, mean, np.nan)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, nargs="+")
    ap.add_argument("--labels", required=True, help="Comma-separated, one per file.")
    ap.add_argument("--t-set", type=float, required=True, help="Cabin set point [degC].")
    ap.add_argument("--title", default="")
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args()
    labels = args.labels.split(",")
    if len(labels) != len(args.runs):
        ap.error("give one label per file")
    fig, axes = plt.subplots(len(args.runs), 1, figsize=(10, 3.2 * len(args.runs)), sharex=True, squeeze=False)
    for ax, path, label in zip(axes[:, 0], args.runs, labels, strict=True):
        with xr.open_dataset(path) as ds:
            t = ds["time"].values / 60.0
            T = ds["T_cabin"].values - 273.15
            m60 = moving_mean(ds["time"].values, T, 60.0)
            ax.axhspan(args.t_set - 1.0, args.t_set + 1.0, color="0.9", label="set point +-1 K")
            ax.plot(t, T, color="C0", lw=0.8, label="cabin air")
            ax.plot(t, m60, color="C0", lw=2.0, label="cabin air, 60-s mean")
            ax.plot(t, ds["T_supply"].values - 273.15, color="C1", lw=0.6, alpha=0.7, label="vent air")
            if "T_evap_air" in ds:
                ax.plot(t, ds["T_evap_air"].values - 273.15, color="C2", lw=0.6, alpha=0.7, label="evaporator air")
            changes = int(np.count_nonzero(np.diff(ds["mode"].values[1:].astype(int))))
            ax.set_title(f"{label}: {changes} mode changes", fontsize=10)
            ax.set_ylabel("degC")
            ax.set_ylim(0.0, 40.0)
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1, 0].set_xlabel("time [min]")
    if args.title:
        fig.suptitle(args.title)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)


if __name__ == "__main__":
    main()
