"""The heat pump against the resistive heaters, and the e-drive loop in the heat: the figures of its acceptance.

Run:  python benchmarks/heat_pump_study.py LUT_FOLDER [--json] [--minutes 60] [--skip-range]

LUT_FOLDER holds the cycle LUTs (``evtms bench all --grid cycle -o luts/``); the cycle maps, the heat pump's
included, are built there on first use. It prints:

- **steady heating**: 50 km/h on the level, ambient -10, 0 and 10 degC at RH 0.7, the cabin held at its set
  point, for ``--minutes`` after a soak at the ambient; over the last 20 minutes the heat pump's system COP
  (the heater core's heat less the backup PTC's over the compressor's electrical power and the low-voltage
  power it adds at the pack), its heat into the cabin, the backup's share, where its source heat came from,
  and the cabin's mean; the resistive heaters' electrical power for the same cabin beside it;
- **range in the cold**: the SAE J1634 multi-cycle test at -10 degC with ``ptc_air`` and ``heat_pump``, the
  heat pump's gain with its breakdown (as ``evtms report range --json`` gives it);
- **the e-drive loop in the heat**: HWFET at 40 degC, sun 600 W/m2: the motor's hottest, the pump and the fan
  against their motor-temperature table, the radiator's heat and the ledgers.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import DriveCycle, drive_cycle
from evtms.system.params import system_params_from_dict
from evtms.system.refrigerant import load_refrigerant
from evtms.system.simulate import MOTOR_TABLE, heat_pump_metrics, simulate

AMBIENTS_C = (-10.0, 0.0, 10.0)
HEATINGS = ("ptc_air", "ptc_coolant", "heat_pump")
#: The spec's bands for the heat pump's system COP at 50 km/h (v2 section 10.9) by ambient [degC].
COP_BANDS = {-10.0: (1.3, 2.3), 0.0: (1.8, 3.0), 10.0: (2.2, 3.8)}


def steady(speed_kmh: float, minutes: float) -> DriveCycle:
    """A level drive at ``speed_kmh``, reached over the first 10 s."""
    t = np.concatenate(([0.0], np.arange(10.0, minutes * 60.0 + 1.0)))
    v = np.full(t.size, speed_kmh / 3.6)
    v[0] = 0.0
    return DriveCycle(f"steady {speed_kmh:g} km/h", t, v, np.zeros_like(t), "constant speed")


def steady_heating(luts: str, minutes: float) -> list[dict]:
    rows = []
    cycle = steady(50.0, minutes)
    for T_c in AMBIENTS_C:
        T = T_c + 273.15
        row: dict = {"T_amb_degC": T_c}
        for heating in HEATINGS:
            params = system_params_from_dict({"hvac": {"heating": heating}})
            ref = load_refrigerant(luts, params)
            r = simulate(cycle, T, ref, params, dt=1.0, RH_amb=0.7, keep_trace=True)
            tr = r.trace
            last = np.cumsum(tr["dts"]) > (minutes - 20.0) * 60.0
            k = int(np.argmax(last))
            out, dts = tr["out"][k:], tr["dts"][k:]
            p_hvac = float(np.sum(out[:, L.O_P_HVAC] * dts) / np.sum(dts))
            q_hc = float(np.sum((out[:, L.O_Q_HC] + out[:, L.O_P_PTC]) * dts) / np.sum(dts))
            cabin = float(np.mean(tr["states"][k + 1 :, L.S_TA]) - 273.15)
            entry = {
                "P_hvac_W": p_hvac,
                "Q_cabin_heat_W": q_hc,
                "T_cabin_degC": cabin,
                "ledger": r.summary["ledger_worst"],
            }
            if heating == "heat_pump":
                m = heat_pump_metrics(tr["par"], tr["states"][k:], out, tr["flags"][k:], dts)
                hp_share = float(np.mean(out[:, L.O_CIRCUIT] == L.CIRCUIT_HP))
                entry.update(
                    m,
                    hp_running_share=hp_share,
                    T_coolant_ed_degC=float(np.mean(tr["states"][k + 1 :, L.S_TE]) - 273.15),
                )
                lo, hi = COP_BANDS[T_c]
                cop = m["cop_sys_mean"]
                entry["cop_band"] = [lo, hi]
                entry["cop_in_band"] = cop is not None and lo <= cop <= hi
            row[heating] = entry
        rows.append(row)
    return rows


def cold_range(luts: str) -> dict:
    from evtms.reports.system_plots import depletion_report
    from evtms.system.output import to_dataset
    from evtms.system.range_test import run_range_test

    results = []
    for heating in ("ptc_air", "heat_pump"):
        params = system_params_from_dict({"hvac": {"heating": heating}})
        ref = load_refrigerant(luts, params)
        r = run_range_test("mct", 263.15, ref, params)[0]
        r.summary["heating"] = heating
        results.append(r)
    report = depletion_report(to_dataset(results))
    return {"gain": report["heat_pump_gain"], "runs": [r.summary for r in results]}


def hot_hwfet(luts: str) -> dict:
    params = system_params_from_dict({})
    ref = load_refrigerant(luts, params)
    r = simulate(drive_cycle("hwfet"), 313.15, ref, params, dt=0.1, sun=600.0, keep_trace=True)
    st, out = r.trace["states"], r.trace["out"]
    need = np.interp(st[:-1, L.S_TM], *MOTOR_TABLE)
    pump_min = params.edrive.pump_min
    pumping = out[:, L.O_U_PUMP_E] > 0
    return {
        "T_motor_max_degC": r.summary["T_motor_max_degC"],
        "T_coolant_ed_max_degC": float(np.max(st[:, L.S_TE]) - 273.15),
        "pump_follows_table": bool(np.allclose(out[pumping, L.O_U_PUMP_E], np.clip(need[pumping], pump_min, 1.0))),
        "fan_at_least_motor_need": bool(np.all(out[:, L.O_FAN] >= need - 1e-12)),
        "radiator_in_share": float(np.mean(out[:, L.O_RAD_IN])),
        "Q_radiator_mean_W": float(np.mean(out[:, L.O_Q_RAD])),
        "fan_energy_Wh": float(np.sum(out[:, L.O_P_FAN] * r.trace["dts"]) / 3600.0),
        "ledger_worst": r.summary["ledger_worst"],
    }


def _fmt(value, spec: str) -> str:
    return "" if value is None else format(value, spec)


def markdown(res: dict) -> str:
    lines = [
        "| ambient | heating | cabin [degC] | heat to cabin [W] | electrical [W] | COP_sys (band) | backup share "
        "| HP running | loop E [degC] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in res["steady"]:
        for h in HEATINGS:
            e = row[h]
            cop = e.get("cop_sys_mean")
            band = e.get("cop_band")
            cop_txt = "" if cop is None else f"{cop:.2f} ({band[0]:g}-{band[1]:g})"
            lines.append(
                f"| {row['T_amb_degC']:g} degC | {h} | {e['T_cabin_degC']:.1f} | {e['Q_cabin_heat_W']:.0f} | "
                f"{e['P_hvac_W']:.0f} | {cop_txt} | {_fmt(e.get('backup_share'), '.0%')} | "
                f"{_fmt(e.get('hp_running_share'), '.0%')} | {_fmt(e.get('T_coolant_ed_degC'), '.1f')} |"
            )
    if "range" in res:
        for g in res["range"]["gain"]:
            lines.append(
                f"\nMCT at {g['T_amb_degC']:g} degC: heat_pump {g['range_km']:.0f} km against {g['base']} "
                f"{g['base_range_km']:.0f} km, gain {g['gain_pct']:+.1f} % (HVAC share {g['hvac_share']:.0%} against "
                f"{g['base_hvac_share']:.0%}, COP_sys {g['cop_sys_mean']:.2f}, backup share {g['backup_share']:.0%}, "
                f"waste heat {g['waste_heat_kWh']:.2f} kWh, ambient heat {g['ambient_heat_kWh']:.2f} kWh)"
            )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("luts")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--skip-range", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = {"steady": steady_heating(args.luts, args.minutes), "hot": hot_hwfet(args.luts)}
    if not args.skip_range:
        res["range"] = cold_range(args.luts)
    res["seconds"] = time.perf_counter() - t0
    print(json.dumps(res, indent=1, default=float) if args.json else markdown(res) + f"\n\nhot: {res['hot']}")


if __name__ == "__main__":
    main()
