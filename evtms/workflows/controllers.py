"""Controllers side by side on one plant: ``evtms report compare --controllers rules,mpc``.

Every (cycle, ambient) runs once with the rule-based climate control and
once per MPC preview, on the same simulator (LUT model), parameters and
conditions; the table gives battery and HVAC energy, comfort (minutes with
the cabin's 60-s mean more than 1 K off after the pull-down, RMS
deviation), the battery's temperature range and the MPC's solve times, with
each controller's HVAC saving against the rules.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from evtms.errors import EvtmsInputError
from evtms.paths import input_file, output_folder
from evtms.workflows.common import Notify, Progress, as_text

#: Irradiance [W/m2] of a run above the setpoint when none is given: the summer scenarios' (MW M); the cold
#: runs have none.
SUMMER_SUN = 600.0


@dataclass(frozen=True)
class ControllerRequest:
    """What to compare: cycles x ambients x controllers (and the MPC's previews)."""

    cycle: str | Sequence[str] = "wltc3b,udds"
    t_amb: str | Sequence[float] = "-10,30,40"
    controllers: str | Sequence[str] = "rules,mpc"
    previews: str | Sequence[str] = "perfect,none"
    luts: Path = Path("luts")
    params: Path | None = None
    sun: float | None = None
    horizon: float = 180.0
    control_step: float = 10.0
    output: Path | None = None
    fmt: str = "png"


@dataclass
class ControllerRow:
    """One run's figures (energies [kWh], temperatures [degC], times [ms])."""

    cycle: str
    T_amb_degC: float
    sun_W_m2: float
    controller: str
    hvac_kWh: float
    battery_kWh: float
    hvac_saving_pct: float | None
    minutes_outside_1K: float | None
    cabin_rms_K: float | None
    t_pulldown_s: float | None
    T_battery_min_degC: float
    T_battery_max_degC: float
    solve_mean_ms: float | None
    solve_max_ms: float | None
    fallbacks: int | None
    wall_s: float


def _names(value: str | Sequence[str]) -> list[str]:
    items = value.split(",") if isinstance(value, str) else list(value)
    return [v.strip() for v in items if v.strip()]


def _plan(r: ControllerRequest):
    from evtms.cycle.topology import parse_values
    from evtms.system.controllers import check_controller
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.mpc import MpcOptions

    controllers = _names(r.controllers)
    if not controllers:
        raise EvtmsInputError(f"`controllers` {r.controllers!r} names none; allowed: rules, mpc, comma-separated")
    for c in controllers:
        check_controller(c, "`controllers`")
    previews = _names(r.previews)
    if "mpc" in controllers and not previews:
        raise EvtmsInputError(f"`preview` {r.previews!r} names none; allowed: perfect, none, noisy, comma-separated")
    if r.fmt not in ("png", "svg"):
        raise EvtmsInputError(f"`fmt` {r.fmt!r} is unknown; allowed: png, svg")
    if r.sun is not None and not (math.isfinite(r.sun) and 0.0 <= r.sun <= 1500.0):
        raise EvtmsInputError(f"`sun` {r.sun:g} is not allowed; allowed: 0 to 1500 W/m2")
    names = _names(r.cycle)
    if not names or len(names) > 10:
        raise EvtmsInputError(f"`cycle`: {len(names)} cycles; allowed: 1 to 10")
    ambients = parse_values("T_amb", as_text(r.t_amb), 10, "`t_amb`")
    options = [MpcOptions(horizon=r.horizon, step=r.control_step, preview=p) for p in previews]
    runs = [("rules", None)] if "rules" in controllers else []
    if "mpc" in controllers:
        runs += [("mpc" if len(options) == 1 else f"mpc, preview {o.preview}", o) for o in options]
    return [drive_cycle(c) for c in names], ambients, runs


def compare_controllers(
    request: ControllerRequest, *, notify: Notify | None = None, progress: Progress | None = None, on_run=None
) -> tuple[list[ControllerRow], list[Path]]:
    """Run the comparison; returns its rows and the files written (table and trajectories, if ``output``).

    Raises
    ------
    EvtmsInputError
        An unknown controller or preview, a bad cycle or ambient, MPC options out of range, or the ``mpc``
        extra missing; before any run.
    """
    from evtms.system.mpc import CabinMpc, casadi_module
    from evtms.system.params import load_parameter_tree
    from evtms.system.simulate import simulate
    from evtms.workflows.simulate import cycle_luts, system_refrigerant

    cycles, ambients, runs = _plan(request)
    if any(o is not None for _, o in runs):
        casadi_module()
    inputs = [Path(c.source) for c in cycles if Path(c.source).is_file()]
    if request.params is not None:
        inputs.append(input_file(request.params, "params file"))
    tree = load_parameter_tree(request.params)
    lut_folder, lut_files = cycle_luts(request.luts)
    if request.output is not None:
        output_folder(request.output, inputs + lut_files)
    refrigerant = system_refrigerant(request.luts, lut_folder, tree, notify, progress)
    params = tree.system
    rows, traces = [], {}
    total, done = len(cycles) * len(ambients) * len(runs), 0
    for cycle in cycles:
        for T in ambients:
            sun = _sun(request.sun, T, params.cabin.T_set)
            base = None
            for label, options in runs:
                ctl = None if options is None else CabinMpc(options)
                res = simulate(cycle, T, refrigerant, params, sun=sun, controller=ctl, keep_trace=True)
                s = res.summary
                if label == "rules":
                    base = s["hvac_energy_kWh"]
                rows.append(_row(cycle.name, T, sun, label, s, base))
                traces[(cycle.name, T, label)] = res.trace
                done += 1
                if on_run is not None:
                    on_run(done, total, f"{cycle.name} {T - 273.15:g} degC {label}")
    files = []
    if request.output is not None:
        files = _write(rows, traces, request.output, request.fmt, params.cabin.T_set)
    return rows, files


def _sun(sun: float | None, T_amb: float, T_set: float) -> float:
    if sun is not None:
        return float(sun)
    return SUMMER_SUN if T_amb > T_set else 0.0


def _row(cycle: str, T: float, sun: float, label: str, s: dict, base: float | None) -> ControllerRow:
    def ms(key: str) -> float | None:
        return None if s.get(key) is None else 1e3 * s[key]

    saving = None
    if base is not None and label != "rules" and base > 0.0:
        saving = 100.0 * (1.0 - s["hvac_energy_kWh"] / base)
    return ControllerRow(
        cycle=cycle,
        T_amb_degC=T - 273.15,
        sun_W_m2=sun,
        controller=label,
        hvac_kWh=s["hvac_energy_kWh"],
        battery_kWh=s["battery_energy_kWh"],
        hvac_saving_pct=saving,
        minutes_outside_1K=s.get("cabin_minutes_outside"),
        cabin_rms_K=s.get("cabin_rms_K"),
        t_pulldown_s=s.get("t_pulldown_s"),
        T_battery_min_degC=s["T_battery_min_degC"],
        T_battery_max_degC=s["T_battery_max_degC"],
        solve_mean_ms=ms("controller_solve_mean_s"),
        solve_max_ms=ms("controller_solve_max_s"),
        fallbacks=s.get("controller_fallbacks"),
        wall_s=s["wall_time_s"],
    )


def _write(rows: list[ControllerRow], traces: dict, folder: Path, fmt: str, T_set: float) -> list[Path]:
    """Table and one trajectory figure per (cycle, ambient), drawn into a staging folder and moved in whole."""
    from evtms.paths import file_slug, staged_folder
    from evtms.reports.controllers import trajectory_figure

    names = ["controllers.csv"]
    with staged_folder(folder) as stage:
        with open(stage / names[0], "w", newline="") as f:
            table = csv.writer(f)
            table.writerow(list(asdict(rows[0])))
            table.writerows([_cell(v) for v in asdict(r).values()] for r in rows)
        for cycle, T in dict.fromkeys((k[0], k[1]) for k in traces):
            runs = {label: tr for (c, t, label), tr in traces.items() if c == cycle and t == T}
            name = f"controllers_{file_slug(cycle)}_{T - 273.15:g}degC.{fmt}"
            trajectory_figure(runs, stage / name, f"{cycle}, {T - 273.15:g} degC", T_set)
            names.append(name)
    return [folder / n for n in names]


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def read_rows(path: Path) -> list[dict]:
    """The rows of a ``controllers.csv`` (for reports and tests)."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def controller_table(rows: Sequence[ControllerRow]) -> str:
    """The comparison as a Markdown table (energies kWh, comfort min and K, battery degC, solve ms)."""

    def f(v, fmt: str) -> str:
        if v is None:
            return "-"
        return format(v, fmt[:-1]) + " %" if fmt.endswith("%") else format(v, fmt)

    head = (
        "| cycle | T_amb | controller | HVAC kWh | saving | battery kWh | min outside +-1 K | RMS K | "
        "battery degC | solve mean / worst ms |\n|---|---|---|---|---|---|---|---|---|---|"
    )
    lines = [head]
    for r in rows:
        solve = "-" if r.solve_mean_ms is None else f"{r.solve_mean_ms:.1f} / {r.solve_max_ms:.0f}"
        lines.append(
            f"| {r.cycle} | {r.T_amb_degC:g} | {r.controller} | {r.hvac_kWh:.3f} | {f(r.hvac_saving_pct, '+.1f%')} "
            f"| {r.battery_kWh:.3f} | {f(r.minutes_outside_1K, '.1f')} | {f(r.cabin_rms_K, '.2f')} "
            f"| {r.T_battery_min_degC:.1f} to {r.T_battery_max_degC:.1f} | {solve} |"
        )
    return "\n".join(lines)
