"""evtms surrogate train: the data-driven mode models."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, _ProgressBar, note, print_json
from evtms.cli.simulate import SystemToml

surrogate_app = typer.Typer(
    help="Data-driven mode models: train them on the simulator (evtms simulate --model surrogate runs them).",
    no_args_is_help=True,
)


_Output = Annotated[Path, typer.Option("--output", "-o", help="Output folder; the file is mode_models.npz.")]
_Mode = Annotated[
    str,
    typer.Option(
        "--mode", help="Modes, comma-separated: off, bh, bc, cc, ch, ch+bh, ch+bc, cc+bc, or all (every one)."
    ),
]
_Luts = Annotated[
    Path,
    typer.Option("--luts", help="Cycle LUT folder, or evtms demo's luts/ or output folder; built if missing or empty."),
]
_Seed = Annotated[int, typer.Option("--seed", help="Seed of the scenario design and of every fit.")]
_RunsPerMode = Annotated[int, typer.Option("--runs-per-mode", help="Training simulations per mode.")]
_Workers = Annotated[
    int | None, typer.Option("--workers", help="Run the training simulations in N local dask worker processes.")
]
_Scheduler = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Send the training simulations to a dask.distributed scheduler, tcp://host:port (it runs the code "
        "sent to it: use only a cluster you trust). The models are the same wherever they run.",
    ),
]
_Quick = Annotated[
    bool, typer.Option("--quick", help="Small design and tiny networks (tests; errors not representative).")
]


@surrogate_app.command("train")
def surrogate_train(
    output: _Output,
    mode: _Mode = "all",
    luts: _Luts = Path("luts"),
    params: SystemToml = None,
    seed: _Seed = 0,
    runs_per_mode: _RunsPerMode = 24,
    quick: _Quick = False,
    workers: _Workers = None,
    scheduler: _Scheduler = None,
    json_out: JsonOut = False,
) -> None:
    """Train the mode models: simulate a designed set of scenarios on the cycle maps (dt 1 s), fit per mode a
    power and a dynamics network (scikit-learn, pip install 'evtms[surrogate]'), check them on held-out cycles
    and ambients (WLTC, NEDC), and write OUTPUT/mode_models.npz. Modes already in that file and not retrained
    are kept.

    Example: evtms surrogate train --mode all -o models/ && evtms simulate --cycle wltc3b --t-amb 30 --model
    surrogate --surrogates models/ -o run.nc
    """
    options = dict(locals())  # every option by name: the request's fields
    del options["json_out"]
    from evtms.workflows.train import TrainRequest, train_mode_models

    with _ProgressBar(json_out or not sys.stderr.isatty()) as bar:
        report = train_mode_models(TrainRequest(**options), notify=note, progress=bar.by_label())
    if json_out:
        print_json(report.to_dict())
        return
    _print_report(report)


def _print_report(report) -> None:
    """The training report as text: per mode its steps, fit time and held-out errors."""
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
