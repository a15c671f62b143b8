"""Training the data-driven mode models on the simulator (``evtms surrogate train``).

:func:`train_mode_models` checks a :class:`TrainRequest` (limits, modes,
parameter file, LUT folder, output folder) before any LUT or map work,
builds the cycle LUTs and maps where missing, and trains with
:func:`evtms.surrogates.train.train_surrogates` (scikit-learn), its training
simulations in this process or on dask workers (:mod:`evtms.system.sweep`, the
engine of ``evtms sweep``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from evtms.errors import EvtmsInputError
from evtms.paths import output_folder
from evtms.workflows.common import Notify, Progress, params_input

__all__ = ["TrainRequest", "train_mode_models"]


@dataclass
class TrainRequest:
    """What to train and where to write it.

    Attributes
    ----------
    output : Path
        Output folder; the file is ``mode_models.npz`` (modes already in it and not retrained are kept).
    mode : str or sequence of str
        Modes (``off``, ``bh``, ``bc``, ``cc``, ``ch``, ``ch+bh``, ``ch+bc``, ``cc+bc``) or ``all``; text is
        comma-separated.
    luts : Path
        Cycle LUT folder (or ``evtms demo``'s luts/ or output folder); built if missing or empty.
    params : Path, optional
        System TOML, as for a simulation.
    seed : int
        Seed of the scenario design and of every fit, 0 to 2**32 - 1.
    runs_per_mode : int
        Training simulations per mode, 1 to 500.
    quick : bool
        Small design and tiny networks (tests; errors not representative).
    workers : int, optional
        Run the training simulations on that many local dask workers (default: in this process).
    scheduler : str, optional
        Run them on a dask.distributed scheduler, ``tcp://host:port``. The models are the same
        wherever the simulations run.
    """

    output: Path
    mode: str | Sequence[str] = "all"
    luts: Path = Path("luts")
    params: Path | None = None
    seed: int = 0
    runs_per_mode: int = 24
    quick: bool = False
    workers: int | None = None
    scheduler: str | None = None


def train_mode_models(request: TrainRequest, *, notify: Notify | None = None, progress: Progress | None = None):
    """Train the mode models of the request and write ``<output>/mode_models.npz``.

    Parameters
    ----------
    request : TrainRequest
        Checked in full before any LUT or map work.
    notify : callable, optional
        ``notify(message)`` for notes (LUTs or maps being built).
    progress : callable, optional
        ``progress(done, total, label)``: ``label`` a cycle map's name while maps are built, then
        ``training``.

    Returns
    -------
    TrainReport
        What was fitted, its errors and the file (:class:`evtms.surrogates.train.TrainReport`).

    Raises
    ------
    EvtmsInputError
        A limit out of range, an unknown mode, a bad parameter file, LUT folder or output folder.
    """
    from evtms.surrogates.train import check_modes, train_surrogates
    from evtms.system.params import load_parameter_tree
    from evtms.system.sweep import check_runner, make_runner
    from evtms.workflows.simulate import cycle_luts, system_refrigerant

    r = request
    if not 1 <= r.runs_per_mode <= 500:
        raise EvtmsInputError(f"`runs_per_mode` {r.runs_per_mode} is not allowed; allowed: 1 to 500")
    if not 0 <= r.seed < 2**32:
        raise EvtmsInputError(f"`seed` {r.seed} is not allowed; allowed: 0 to 2**32 - 1")
    parts = r.mode.split(",") if isinstance(r.mode, str) else r.mode
    modes = [m.strip() for m in parts if m.strip()]
    check_modes(modes)  # before any LUT or map work
    check_runner(r.workers, r.scheduler)
    inputs = params_input(r.params)
    tree = load_parameter_tree(r.params)
    lut_folder, lut_files = cycle_luts(r.luts)
    output_folder(r.output, inputs + lut_files)
    refrigerant = system_refrigerant(r.luts, lut_folder, tree, notify, progress)
    training = None if progress is None else (lambda done, total, message: progress(done, total, "training"))
    runner = make_runner(r.workers, r.scheduler)
    try:
        return train_surrogates(
            refrigerant, modes, r.output, params=tree.system, progress=training, seed=r.seed, quick=r.quick,
            runs_per_mode=r.runs_per_mode, runner=runner,
        )  # fmt: skip
    finally:
        runner.close()
