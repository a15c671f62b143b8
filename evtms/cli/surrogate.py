"""evtms surrogate train: the data-driven mode models."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, _ProgressBar, fail, print_json
from evtms.cli.simulate import _system_refrigerant
from evtms.paths import input_file, output_folder
from evtms.workflows.simulate import cycle_luts as _cycle_luts

surrogate_app = typer.Typer(
    help="Data-driven mode models: train them on the simulator (evtms simulate --model surrogate runs them).",
    no_args_is_help=True,
)


@surrogate_app.command("train")
def surrogate_train(
    output: Annotated[Path, typer.Option("--output", "-o", help="Output folder; the file is mode_models.npz.")],
    mode: Annotated[
        str,
        typer.Option(
            "--mode", help="Modes, comma-separated: off, bh, bc, cc, ch, ch+bh, ch+bc, cc+bc, or all (every one)."
        ),
    ] = "all",
    luts: Annotated[
        Path,
        typer.Option(
            "--luts", help="Cycle LUT folder, or evtms demo's luts/ or output folder; built if missing or empty."
        ),
    ] = Path("luts"),
    params: Annotated[Path | None, typer.Option("--params", help="System TOML, as evtms simulate.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the scenario design and of every fit.")] = 0,
    runs_per_mode: Annotated[int, typer.Option("--runs-per-mode", help="Training simulations per mode.")] = 24,
    quick: Annotated[
        bool, typer.Option("--quick", help="Small design and tiny networks (tests; errors not representative).")
    ] = False,
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Train the mode models: simulate a designed set of scenarios on the cycle maps (dt 1 s), fit per mode a
    power and a dynamics network (scikit-learn, pip install 'evtms[surrogate]'), check them on held-out cycles
    and ambients (WLTC, NEDC), and write OUTPUT/mode_models.npz. Modes already in that file and not retrained
    are kept.

    Example: evtms surrogate train --mode all -o models/ && evtms simulate --cycle wltc3b --t-amb 30 --model
    surrogate --surrogates models/ -o run.nc
    """
    from evtms.surrogates.train import check_modes, train_surrogates
    from evtms.system.params import load_system_params

    if not 1 <= runs_per_mode <= 500:
        fail(f"--runs-per-mode {runs_per_mode} is not allowed; allowed: 1 to 500")
    if not 0 <= seed < 2**32:
        fail(f"--seed {seed} is not allowed; allowed: 0 to 2**32 - 1")
    modes = [m.strip() for m in mode.split(",") if m.strip()]
    check_modes(modes)  # before any LUT or map work
    inputs = [input_file(params, "params file")] if params is not None else []
    system = load_system_params(params)
    lut_folder, lut_files = _cycle_luts(luts)
    inputs += lut_files
    output_folder(output, inputs)
    refrigerant = _system_refrigerant(luts, lut_folder, system, quiet=json_out)
    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        task = None

        def progress(done: int, total: int, text: str) -> None:
            nonlocal task
            if task is None:
                task = bar.task("training", total)
            task(done, total)

        report = train_surrogates(
            refrigerant, modes, output, params=system, progress=progress, seed=seed, quick=quick,
            runs_per_mode=runs_per_mode,
        )  # fmt: skip
    if json_out:
        print_json(report.to_dict())
        return
    for name, m in report.modes.items():
        line = f"{name}: {m.n_train} steps, fit {m.fit_power.time_s + m.fit_dynamics.time_s:.0f} s"
        if m.rollout:
            line += ", held-out RMSE " + ", ".join(
                f"{v} {m.rollout[v]['rmse']:.3g}" for v in ("T_battery", "T_cabin", "T_coolant") if v in m.rollout
            )
        typer.echo(line)
    if report.auto:
        typer.echo(
            "auto (held out): RMSE "
            + ", ".join(f"{v} {report.auto[v]['rmse']:.3g}" for v in ("T_battery", "T_cabin") if v in report.auto)
        )
    for name, why in report.skipped.items():
        typer.echo(f"{name}: skipped ({why})")
    typer.echo(f"wrote {report.path} ({report.total_time_s:.0f} s)")
