"""Cycle figures: p-h and p-T diagrams on R134a's saturation curve, energy balance.

Each figure function builds its plot data with a separate, testable function
(``*_data``) and draws it with matplotlib's object API (no global state, the
Agg backend), writing PNG or SVG by the file suffix.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.fluid import Fluid
from evtms.luts.io import atomic_output

if TYPE_CHECKING:
    import xarray as xr

STATES = ("A", "B", "C", "D")
STATE_LABELS = {
    "A": "A evaporator outlet",
    "B": "B compressor outlet",
    "C": "C condenser outlet",
    "D": "D valve outlet",
}


def _figure(figsize=(7.0, 5.0)):
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, layout="constrained")


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=120)
    return path


def saturation_dome(fluid: Fluid, n: int = 200) -> dict[str, np.ndarray]:
    """Saturation curve [Pa, K, J/kg] from 0.03 MPa to just below the critical point."""
    p = np.geomspace(3e4, 0.999 * fluid.p_crit, n)
    sat = fluid.saturation(p)
    return {"p": p, "T": sat["T"], "h_l": sat["h_l"], "h_v": sat["h_v"]}


def cycle_path(states: dict[str, float], fluid: Fluid, n: int = 30) -> dict[str, np.ndarray]:
    """p, T, h along the cycle A-B-C-D-A [Pa, K, J/kg].

    Compression A-B is drawn as a straight line in p-h; the condenser B-C and
    the evaporator D-A follow their pressure (linear in h between inlet and
    outlet pressures) with temperatures from CoolProp, so the path runs along
    the saturation curve inside the dome; the valve C-D is isenthalpic.
    """
    segments = []
    for a, b in (("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")):
        t = np.linspace(0.0, 1.0, n)
        p = states[f"p_{a}"] + t * (states[f"p_{b}"] - states[f"p_{a}"])
        h = states[f"h_{a}"] + t * (states[f"h_{b}"] - states[f"h_{a}"])
        segments.append((p, h))
    p = np.concatenate([s[0] for s in segments])
    h = np.concatenate([s[1] for s in segments])
    T = fluid.state("PH", p, h, ("T",))["T"]
    return {"p": p, "T": T, "h": h}


def diagram_data(ds: xr.Dataset, point: dict[str, int] | None = None) -> dict[str, float]:
    """States A-D of one operating point of a cycle sweep dataset (default: the first solved)."""
    valid = np.isin(ds["status"].values, ds["status"].attrs["valid_flag_values"])
    if not valid.any():
        raise ValueError("the cycle sweep has no solved operating point")
    if point is None:
        flat = int(np.argmax(valid.ravel()))
        index = dict(zip(ds["status"].dims, np.unravel_index(flat, valid.shape), strict=True))
    else:
        index = point
    sel = ds.isel({k: int(v) for k, v in index.items()})
    if int(sel["status"]) not in ds["status"].attrs["valid_flag_values"]:
        raise ValueError(f"operating point {index} was not solved: {sel['reason'].item()}")
    out = {f"{q}_{s}": float(sel[f"{q}_{s}"]) for s in STATES for q in ("p", "T", "h")}
    out.update({k: float(sel[k]) for k in ds["status"].dims})
    return out


def ph_diagram(states: dict[str, float], fluid: Fluid, path: str | Path) -> Path:
    """Draw the p-h diagram (log p) of one operating point on the saturation dome."""
    dome = saturation_dome(fluid)
    # The dome: liquid line up to the critical point, vapour line back down.
    line = (np.r_[dome["h_l"], dome["h_v"][::-1]], np.r_[dome["p"], dome["p"][::-1]])
    return _state_diagram(states, fluid, path, "h", lambda h: h / 1e3, line, "specific enthalpy h [kJ/kg]")


def pt_diagram(states: dict[str, float], fluid: Fluid, path: str | Path) -> Path:
    """Draw the p-T diagram of one operating point on the saturation curve."""
    dome = saturation_dome(fluid)
    return _state_diagram(
        states, fluid, path, "T", lambda T: T - 273.15, (dome["T"], dome["p"]), "temperature T [degC]"
    )


def _state_diagram(states, fluid: Fluid, path, key: str, shown, saturation, xlabel: str) -> Path:
    """Log-p diagram against quantity ``key`` (displayed through ``shown``): saturation, cycle path, states A-D."""
    cyc = cycle_path(states, fluid)
    fig = _figure()
    ax = fig.add_subplot()
    ax.plot(shown(saturation[0]), saturation[1] / 1e6, color="0.5", lw=1.2, label=f"saturation ({fluid.name})")
    ax.plot(shown(cyc[key]), cyc["p"] / 1e6, color="tab:blue", lw=2, label="cycle")
    for s in STATES:
        xy = (shown(states[f"{key}_{s}"]), states[f"p_{s}"] / 1e6)
        ax.plot(*xy, "o", color="tab:red")
        ax.annotate(s, xy, textcoords="offset points", xytext=(6, 4))
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("pressure p [MPa]")
    ax.set_title(_title(states))
    ax.legend(loc="lower right")
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def _title(states: dict[str, float]) -> str:
    parts = []
    if "speed" in states:
        parts.append(f"speed {states['speed']:g}")
    if "T_amb" in states:
        parts.append(f"ambient {states['T_amb'] - 273.15:.1f} degC")
    if "T_cabin" in states:
        parts.append(f"cabin air {states['T_cabin'] - 273.15:.1f} degC")
    return "R134a cycle: " + ", ".join(parts)


def energy_balance_data(ds: xr.Dataset, x: str) -> dict[str, np.ndarray]:
    """Per-component terms [W] and residual along input ``x`` of a cycle sweep.

    The sweep must vary only ``x`` (other inputs of length 1). Invalid points
    are NaN (gaps in the plot).
    """
    if x not in ds["status"].dims:
        raise ValueError(f"{x!r} is not an input of the sweep; allowed: {', '.join(ds['status'].dims)}")
    others = [d for d in ds["status"].dims if d != x and ds.sizes[d] > 1]
    if others:
        raise ValueError(f"the sweep varies {', '.join(others)} as well; an energy balance plot takes one input")
    line = ds.squeeze([d for d in ds["status"].dims if d != x])
    valid = np.isin(line["status"].values, ds["status"].attrs["valid_flag_values"])

    def v(name):
        return np.where(valid, line[name].values, np.nan)

    return {
        "x": line[x].values,
        "Q_cond": v("Q_cond"),
        "Q_evap": -v("Q_evap"),
        # A sweep of a circuit with a chiller (older sweeps have none: 0).
        "Q_chiller": -v("Q_chiller") if "Q_chiller" in line else np.zeros(line[x].size),
        "W_fluid": v("W_fluid"),
        "residual": v("balance_residual"),
        "relative": v("balance_relative"),
    }


def energy_balance_figure(ds: xr.Dataset, x: str, path: str | Path) -> Path:
    """Draw Q_cond, |Q_evap|, |Q_chiller| (where the circuit has a chiller), W_fluid and the residual
    against input ``x``; write a CSV table beside."""
    d = energy_balance_data(ds, x)
    units = ds[x].attrs.get("units", "")
    xs = d["x"] - 273.15 if units == "K" and x.startswith("T") else d["x"]
    xlabel = f"{ds[x].attrs.get('long_name', x)} [{'degC' if units == 'K' and x.startswith('T') else units}]"
    fig = _figure(figsize=(7.0, 6.0))
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
    top.plot(xs, d["Q_cond"] / 1e3, "o-", label="Q_cond (condenser LUT)")
    chiller = bool(np.nan_to_num(d["Q_chiller"]).any())
    evaporator = bool(np.nan_to_num(d["Q_evap"]).any())
    if evaporator:
        top.plot(xs, d["Q_evap"] / 1e3, "s-", label="|Q_evap| (evaporator)")
    if chiller:
        top.plot(xs, d["Q_chiller"] / 1e3, "D-", label="|Q_chiller| (chiller)")
    top.plot(xs, d["W_fluid"] / 1e3, "^-", label="W_fluid (compressor)")
    taken = " + ".join([*(["|Q_evap|"] if evaporator else []), *(["|Q_chiller|"] if chiller else []), "W_fluid"])
    top.plot(xs, (d["Q_evap"] + d["Q_chiller"] + d["W_fluid"]) / 1e3, "k--", lw=1, label=taken)
    top.set_ylabel("heat flow, power [kW]")
    top.legend()
    top.grid(alpha=0.3)
    bottom.plot(xs, 100 * d["relative"], "o-", color="tab:red")
    bottom.axhline(0, color="0.5", lw=0.8)
    bottom.set_ylabel("residual [% of W_fluid]")
    bottom.set_xlabel(xlabel)
    bottom.grid(alpha=0.3)
    top.set_title(f"Cycle energy balance: Q_cond - ({taken})")
    out = _save(fig, path)
    table = Path(path).with_suffix(".csv")
    header = f"{x} [{units}],Q_cond [W],Q_evap_abs [W],Q_chiller_abs [W],W_fluid [W],residual [W],residual_relative [1]"
    columns = ("x", "Q_cond", "Q_evap", "Q_chiller", "W_fluid", "residual", "relative")
    rows = np.column_stack([d[c] for c in columns])
    with atomic_output(table) as tmp:
        np.savetxt(tmp, rows, delimiter=",", header=header, comments="", fmt="%.10g")
    return out
