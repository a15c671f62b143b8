"""The whole job in one call: benches, LUTs, a cycle sweep, figures and an HTML index.

``run_demo(out)`` writes into ``out``::

    luts/thesis/<component>.nc     every registered bench on its thesis grid
    luts/cycle/<component>.nc      every registered bench on its cycle grid
    cycle/speed_sweep.nc           cycle on the LUTs over compressor speed
    reports/<component>/index.html bench figures (thesis LUTs) with provenance
    reports/cycle/*.png|svg|csv    p-h, p-T and energy-balance figures
    index.html                     links to everything

A LUT already in place with the same grid, parameters, air boundary, evtms
and CoolProp versions is reused (``force`` recomputes it). The benches run in
parallel processes, one per LUT, but for a grid larger than the others together
(the cycle evaporator's), whose chunks are spread over the workers.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms.benches.parameters import Parameters

GRIDS = ("thesis", "cycle")

Notify = Callable[[str], None]


@dataclass
class DemoResult:
    """What the demo wrote and reused."""

    index: Path
    computed: list[str] = field(default_factory=list)
    reused: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)


def lut_is_current(path: Path, component: str, grid: str, params: Parameters) -> bool:
    """True if ``path`` is a valid LUT made with these inputs and the current versions.

    Reads the file's header only (the data stay on disk). The preset's inputs
    must match: those of several values as the file's axes (same order and
    values), those of one value as its fixed inputs. A file of an older
    format version is not current (it is rewritten in the current one).
    """
    from evtms.benches import BENCHES
    from evtms.fluid import coolprop_version
    from evtms.luts import LutFormatError
    from evtms.luts.schema import FORMAT_VERSION
    from evtms.luts.validate import read_lut_metadata

    if not path.exists():
        return False
    try:
        meta = read_lut_metadata(path, component)
    except LutFormatError:
        return False
    a = meta.attrs
    bench = BENCHES[component]
    preset = {k: np.asarray(v, float) for k, v in bench.presets.get(grid, {}).items()}
    # The preset's axes and the bench's variables too: they change between
    # development builds of one version.
    axes = {k: v for k, v in preset.items() if v.size > 1}
    fixed = {k: float(v[0]) for k, v in preset.items() if v.size == 1}
    same_grid = (
        list(meta.dims) == list(axes)
        and all(np.array_equal(meta.axes[k], v) for k, v in axes.items())
        and meta.fixed == fixed
    )
    return (
        meta.version == FORMAT_VERSION
        and a.get("grid") == grid
        and a.get("evtms_version") == __version__
        and a.get("coolprop_version") == coolprop_version()
        and a.get("parameters") == params.component_json(component)
        and a.get("environment") == params.environment_json()
        and same_grid
        and set(bench.outputs) - set(preset) <= set(meta.variables)
    )


def _components() -> list[str]:
    """Every registered component: the demo runs each bench."""
    from evtms.benches import BENCHES

    return list(BENCHES)


def _grid_points(component: str, grid: str) -> int:
    """Points of a bench's preset grid (the demo's cost estimate for ordering the work)."""
    from evtms.benches import BENCHES

    return int(np.prod([len(v) for v in BENCHES[component].presets[grid].values()]))


def _compute_lut(component: str, grid: str, params: Parameters, path: str, workers: int = 1) -> tuple[str, float]:
    """Sweep one bench on a preset grid and write its LUT (in a child process, or in this one
    with its chunks spread over ``workers`` processes).

    The same chunked writer as ``evtms bench``: memory bounded by the chunk.
    """
    from evtms.benches import BENCHES
    from evtms.benches.chunked import PoolRunner, SweepInterrupted, sweep_to_file
    from evtms.benches.grid import build_grid

    t0 = time.perf_counter()
    bench = BENCHES[component]
    runner = PoolRunner(workers) if workers > 1 else None
    try:
        sweep_to_file(bench, build_grid(bench, grid, {}), params, path, grid_name=grid, runner=runner)
    except SweepInterrupted as exc:  # Ctrl-C, as the one-process-per-LUT path reports it
        raise KeyboardInterrupt from exc
    finally:
        if runner is not None:
            runner.close()
    return f"{grid}/{component}", time.perf_counter() - t0


def ensure_luts(
    folder: Path,
    grid: str,
    params: Parameters,
    force: bool = False,
    workers: int = 2,
    notify: Notify | None = None,
    result: DemoResult | None = None,
) -> DemoResult:
    """Every registered bench's LUT on preset ``grid`` in ``folder``, computed unless up to date.

    The LUTs are swept in ``workers`` processes, largest grids first; a grid
    with more points than the others together is swept from this process in
    chunks over ``workers`` processes while one more process sweeps the others
    (their "wrote LUT" notes then come after its own). A LUT made with these
    parameters and versions on this preset is reused (unless ``force``). Names
    go to ``result.computed`` / ``result.reused`` as ``grid/component``.
    Ctrl-C raises KeyboardInterrupt (a sweep's saved chunks stay in its
    partial folder).
    """
    from evtms.luts.store import LutStore

    notify = notify or (lambda message: None)
    result = result or DemoResult(index=folder / "index.html")
    folder.mkdir(parents=True, exist_ok=True)
    jobs, reused = [], []
    for c, path in LutStore(folder).luts(_components()).items():
        if not force and lut_is_current(path, c, grid, params):
            reused.append(f"{grid}/{c}")
        else:
            jobs.append((c, grid, path))
    result.reused += reused
    if reused:
        notify(f"reusing up-to-date LUTs: {', '.join(reused)}")
    if jobs:
        # Largest grids first, so that the workers finish together.
        jobs.sort(key=lambda j: -_grid_points(j[0], j[1]))
        notify(f"computing {len(jobs)} {grid} LUTs in {workers} processes")

        def record(name: str, seconds: float) -> None:
            result.computed.append(name)
            result.timings[name] = seconds
            notify(f"wrote LUT {name} ({seconds:.1f} s)")

        first, rest = jobs[0], jobs[1:]
        if workers > 1 and rest and _grid_points(first[0], first[1]) > sum(_grid_points(c, g) for c, g, _ in rest):
            # One grid outweighs the others together (the cycle evaporator's): one process per
            # LUT would leave the other cores idle while it runs. Its chunks go to `workers`
            # processes from here, the other LUTs to one more process, one after another.
            with ProcessPoolExecutor(max_workers=1) as pool:
                futures = [pool.submit(_compute_lut, c, g, params, str(p)) for c, g, p in rest]
                try:
                    record(*_compute_lut(first[0], first[1], params, str(first[2]), workers=workers))
                except BaseException:
                    pool.shutdown(wait=True, cancel_futures=True)  # not the other LUTs first
                    raise
                for fut in as_completed(futures):
                    record(*fut.result())
            return result
        with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
            futures = [pool.submit(_compute_lut, c, g, params, str(p)) for c, g, p in jobs]
            for fut in as_completed(futures):
                record(*fut.result())
    return result


def run_demo(
    out: str | Path,
    params: Parameters | str | Path | None = None,
    force: bool = False,
    workers: int = 2,
    notify: Notify | None = None,
    map_settings=None,
) -> DemoResult:
    """Run benches, cycle and reports into ``out`` (see the module notes); what ``evtms demo`` runs.

    Parameters
    ----------
    out : str or Path
        Output folder (created if missing; LUTs already there and up to date are reused).
    params : Parameters, or str or Path, optional
        Parameters, or a TOML file of parameter overrides (default: the defaults).
    force : bool
        Recompute LUTs even if they are up to date.
    workers : int
        Processes for the bench sweeps (1 or more).
    notify : callable, optional
        ``notify(message)`` as each step starts or ends (for progress).
    map_settings : MapSettings, optional
        Overrides the cycle maps of the system simulation (:class:`evtms.system.maps.MapSettings`;
        default: the full axes).

    Returns
    -------
    DemoResult

    Raises
    ------
    EvtmsInputError
        ``workers`` below 1, a parameter file that is missing or not valid, or
        an output folder that cannot be written (checked before any work).
    """
    from evtms.errors import EvtmsInputError
    from evtms.luts.store import LutStore
    from evtms.paths import creating_parents, output_folder
    from evtms.system.params import load_parameter_tree
    from evtms.workflows.common import params_input

    if workers < 1:
        raise EvtmsInputError(f"`workers` {workers} is not allowed; allowed: 1 or more")
    inputs = []
    if not isinstance(params, Parameters):
        inputs = params_input(params)
        params = load_parameter_tree(params).components
    out = output_folder(out, inputs)
    notify = notify or (lambda message: None)
    result = DemoResult(index=out / "index.html")
    with creating_parents(out, folder=True):
        for grid in GRIDS:
            ensure_luts(LutStore.demo(out, grid).folder, grid, params, force, workers, notify, result)
        t0 = time.perf_counter()
        simulation = _simulation(out, notify, map_settings)
        _cycle_and_reports(out, params, result, notify, simulation)
    result.timings["cycle and reports"] = time.perf_counter() - t0
    return result


#: The demo's system simulation: WLTC class 3b at 40 degC after a hot soak in the sun.
DEMO_SIMULATION = {"cycle": "wltc3b", "T_amb": 313.15, "T_init": 313.15, "sun": 600.0}


def _simulation(out: Path, notify: Notify, map_settings) -> dict:
    """One WLTC simulation on the cycle LUTs' maps: its file, figure and summary."""
    from evtms.luts.store import LutStore
    from evtms.reports.system_plots import simulation_figure
    from evtms.system.drive_cycles import drive_cycle
    from evtms.system.output import to_dataset, write_simulation
    from evtms.system.refrigerant import load_refrigerant
    from evtms.system.simulate import simulate

    notify("building the cycle maps for the system simulation (cached beside the cycle LUTs)")
    refrigerant = load_refrigerant(LutStore.demo(out, "cycle").folder, settings=map_settings)
    spec = DEMO_SIMULATION
    notify(f"simulating {spec['cycle']} at {spec['T_amb'] - 273.15:g} degC after a hot soak")
    run = simulate(
        drive_cycle(spec["cycle"]),
        spec["T_amb"],
        refrigerant,
        T_init=spec["T_init"],
        sun=spec["sun"],
        scenario="demo: hot soak",
    )
    folder = out / "simulation"
    folder.mkdir(parents=True, exist_ok=True)
    path = write_simulation([run], folder / "wltc_40C.nc")
    figure = out / "reports" / "simulation" / "wltc_40C.png"
    figure.parent.mkdir(parents=True, exist_ok=True)
    simulation_figure(to_dataset([run]), figure)
    return {"file": path, "figure": figure, "summary": run.summary}


def _cycle_and_reports(out: Path, params: Parameters, result: DemoResult, notify: Notify, simulation: dict) -> None:
    from evtms.cycle import cycle_dataset, load_cycle_luts
    from evtms.cycle.api import solve_grid
    from evtms.cycle.topology import INPUTS, TOPOLOGIES
    from evtms.fluid import Fluid
    from evtms.luts import open_lut
    from evtms.luts.io import atomic_output
    from evtms.luts.store import LutStore
    from evtms.reports.bench_plots import bench_report_figures
    from evtms.reports.cycle_plots import diagram_data, energy_balance_figure, ph_diagram, pt_diagram
    from evtms.reports.html import bench_report_page

    fluid = Fluid(params.fluid, params.backend)
    # Cycle over compressor speed at the default conditions.
    notify("solving the cycle over compressor speed on the cycle LUTs")
    cycle_store = LutStore.demo(out, "cycle")
    luts = load_cycle_luts(cycle_store.folder)
    # Over compressor speed, every other input at its default.
    grid = {"speed": np.linspace(0.2, 1.0, 9)}
    grid |= {k: np.array([INPUTS[k].default]) for k in TOPOLOGIES["cabin"].inputs if k != "speed"}
    _, res = solve_grid(grid, luts, params, "cabin", fluid)
    sweep = cycle_dataset(grid, res, f"LUTs in {cycle_store.folder.relative_to(out).as_posix()}")
    (out / "cycle").mkdir(exist_ok=True)
    with atomic_output(out / "cycle" / "speed_sweep.nc") as tmp:
        sweep.to_netcdf(tmp, engine="netcdf4")
    figs = out / "reports" / "cycle"
    figs.mkdir(parents=True, exist_ok=True)
    notify("drawing the cycle figures")
    cycle_figures = []
    for fmt in ("png", "svg"):
        energy_balance_figure(sweep, "speed", figs / f"energy_balance.{fmt}")
    cycle_figures.append(
        ("Energy balance over compressor speed (table: energy_balance.csv)", figs / "energy_balance.png")
    )
    mid = {d: 0 for d in sweep["status"].dims}
    mid["speed"] = 4  # speed 0.6
    states = diagram_data(sweep, mid)
    for fmt in ("png", "svg"):
        ph_diagram(states, fluid, figs / f"ph_diagram.{fmt}")
        pt_diagram(states, fluid, figs / f"pt_diagram.{fmt}")
    cycle_figures += [
        ("p-h diagram at speed 0.6", figs / "ph_diagram.png"),
        ("p-T diagram at speed 0.6", figs / "pt_diagram.png"),
    ]
    bench_pages = []
    for c in _components():
        notify(f"drawing the {c} bench report")
        lut_path = LutStore.demo(out, "thesis").lut(c)
        ds = open_lut(lut_path)
        folder = out / "reports" / c
        folder.mkdir(parents=True, exist_ok=True)
        figures = bench_report_figures(ds, folder)
        bench_pages.append((c, bench_report_page(ds, figures, folder / "index.html", str(lut_path.relative_to(out)))))
    _write_index(out, result, bench_pages, cycle_figures, sweep, simulation)


def _write_index(out: Path, result: DemoResult, bench_pages, cycle_figures, sweep, simulation: dict) -> None:
    import html

    from evtms.cycle.solver import CYCLE_FLAGS
    from evtms.luts.store import LutStore
    from evtms.reports.html import _rel, _table, write_page

    body = [
        "<p>Generated by <code>evtms demo</code>. All files sit beside this page.</p>",
        "<h2>Bench reports (thesis grids)</h2><ul>",
    ]
    for c, page in bench_pages:
        body.append(f'<li><a href="{_rel(page, out)}">{html.escape(c)}</a></li>')
    body.append("</ul><h2>LUT files</h2><ul>")
    for grid in GRIDS:
        for p in LutStore.demo(out, grid).luts(_components()).values():
            body.append(f'<li><a href="{_rel(p, out)}">{grid}/{p.name}</a></li>')
    body.append("</ul><h2>Cycle on the LUTs</h2>")
    rows = []
    for i, speed in enumerate(sweep["speed"].values):
        pt = sweep.isel(speed=i).squeeze()
        code = int(pt["status"])
        rows.append(
            (
                f"{speed:.2f}",
                f"{float(pt['p_A']) / 1e6:.3f}",
                f"{float(pt['p_B']) / 1e6:.3f}",
                f"{-float(pt['Q_evap']):.0f}",
                f"{float(pt['W']):.0f}",
                f"{float(pt['COP']):.2f}",
                CYCLE_FLAGS.get(code, str(code)),
            )
        )
    body.append(_table(rows, ("speed", "p_A [MPa]", "p_B [MPa]", "cooling [W]", "W [W]", "COP", "status")))
    body.append(f'<p>Sweep file: <a href="{_rel(out / "cycle" / "speed_sweep.nc", out)}">cycle/speed_sweep.nc</a></p>')
    for caption, fig in cycle_figures:
        rel = _rel(fig, out)
        body.append(
            f'<figure><a href="{rel}"><img src="{rel}" alt="{html.escape(caption)}"></a>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
    body.append("<h2>System simulation</h2>")
    s = simulation["summary"]
    body.append(
        "<p>WLTC class 3b at 40 degC, cabin, battery and coolant soaked at 40 degC, sun 600 W/m2, "
        "auto mode (<code>evtms simulate --cycle wltc3b --t-amb 40</code> with the soak).</p>"
    )
    body.append(
        _table(
            [
                ("distance", f"{s['distance_km']:.2f} km"),
                ("battery energy (terminals)", f"{s['battery_energy_kWh']:.3f} kWh"),
                ("of which HVAC", f"{s['hvac_energy_kWh']:.3f} kWh"),
                ("consumption (chemical)", f"{s['consumption_kWh_per_100km']:.1f} kWh/100 km"),
                ("SOC at the end", f"{s['soc_end']:.4f}"),
                ("cabin at the end", f"{s['T_cabin_end_degC']:.1f} degC"),
                ("battery at the end", f"{s['T_battery_end_degC']:.1f} degC"),
                ("worst ledger residual", f"{s['ledger_worst']:.1e}"),
            ],
            ("figure", "value"),
        )
    )
    rel = _rel(simulation["figure"], out)
    body.append(
        f'<figure><a href="{rel}"><img src="{rel}" alt="WLTC simulation at 40 degC"></a>'
        "<figcaption>Speed, temperatures, powers, heat flows, SOC and modes</figcaption></figure>"
    )
    body.append(f'<p>Time series: <a href="{_rel(simulation["file"], out)}">simulation/wltc_40C.nc</a></p>')
    body.append("<h2>This run</h2>")
    body.append(
        _table(
            [(n, "computed", f"{t:.1f} s") for n, t in result.timings.items() if n in result.computed]
            + [(n, "reused", "") for n in result.reused],
            ("LUT", "", "time"),
        )
    )
    write_page(out / "index.html", "evtms: R134a circuit benches, LUTs and cycle", "\n".join(body))
