"""Figures of the controller comparison: cabin air, vent air, blower, HVAC power and battery, one colour per
controller."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evtms.system import loop as L  # noqa: N812 - the loop's index constants


def trajectory_figure(runs: dict[str, dict], path: Path, title: str, T_set: float) -> Path:
    """Overlay each controller's trajectories (a run's ``trace``) in five panels; returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(5, 1, figsize=(9, 11), sharex=True)
    for label, tr in runs.items():
        t = np.cumsum(tr["dts"]) / 60.0
        out = tr["out"]
        (line,) = ax[0].plot(t, tr["states"][1:, L.S_TA] - 273.15, lw=1.2, label=label)
        c = line.get_color()
        ax[1].plot(t, out[:, L.O_T_SUPPLY] - 273.15, lw=0.8, color=c)
        ax[2].plot(t, out[:, L.O_BLOWER], lw=0.8, color=c)
        ax[3].plot(t, out[:, L.O_P_HVAC] / 1e3, lw=0.6, color=c)
        ax[4].plot(t, tr["states"][1:, L.S_TB] - 273.15, lw=1.2, color=c)
    ax[0].axhspan(T_set - 274.15, T_set - 272.15, color="0.9", zorder=0, label="setpoint +-1 K")
    ax[0].set_ylabel("cabin air [degC]")
    ax[1].set_ylabel("vent air [degC]")
    ax[2].set_ylabel("blower [1]")
    ax[3].set_ylabel("HVAC power [kW]")
    ax[4].set_ylabel("battery [degC]")
    ax[4].set_xlabel("time [min]")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
