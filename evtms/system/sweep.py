"""Many system simulations at once: runs cut into batches, computed in this process or on dask workers.

What ``evtms sweep`` (a product of ambients, drive cycles and parameter
sets) and ``evtms surrogate train`` (its training simulations) share. A
:class:`SweepContext` holds everything the runs have in common: the scenario
setups (drive cycle read, parameters applied), the cycle maps, the mode
models, the simulator's options and a ``reduce(index, run, result)`` that
turns a finished simulation into what the caller keeps (a summary row, the
training pairs), so a whole time series never travels back. A :class:`Run`
is small (a setup's index, the ambient, an initial cabin temperature): the
runs are numbered and cut into batches of consecutive runs
(:func:`batches`), and each batch is one task.

The context is installed once per process that computes (:func:`install`):
in this process, or on every dask worker by a worker plugin
(:mod:`evtms.system._sweep_plugin`; a worker that joins or restarts gets it
too). Installing unpickles the maps once per process and runs one short
simulation, so the compiled loop is loaded from numba's cache before the
first batch; a run then costs what the simulator costs, whatever the number
of runs. Every mode computes the same runs with the same code, and
:func:`run_batches` returns the results in run order, so the output does not
depend on the runner, the number of workers or the batch size.

The runners are those of the bench sweeps
(:class:`evtms.benches.chunked.InProcessRunner` and
:class:`~evtms.benches.chunked.DaskRunner`: local worker processes on the
loopback, or a ``tcp://host:port`` scheduler); :func:`make_runner` picks one.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import uuid
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from evtms.errors import EvtmsInputError

#: Largest batch [runs]: a WLTC on the cycle maps takes about 10 ms, so a batch of 64 is under a second of work.
MAX_BATCH = 64
#: Batches per worker a sweep is cut into at least (the slowest batch then delays the end by a fraction only).
BATCHES_PER_WORKER = 4


@dataclass(frozen=True)
class Run:
    """One simulation of a sweep: a setup of the context at an ambient.

    Attributes
    ----------
    setup : int
        Index of the scenario setup in :attr:`SweepContext.setups`.
    T_amb : float
        Ambient temperature [K].
    RH_amb : float, optional
        Ambient relative humidity [1] in place of the setup's.
    sun : float, optional
        Solar irradiance [W/m2] in place of the setup's.
    soak_cabin : float, optional
        Initial cabin air, wall and interior temperature [K] in place of the context's option.
    refrigerant : int
        Index of the cycle maps in :attr:`SweepContext.refrigerants` (the maps depend on the coolant's
        parameters).
    """

    setup: int
    T_amb: float
    RH_amb: float | None = None
    sun: float | None = None
    soak_cabin: float | None = None
    refrigerant: int = 0


@dataclass
class SweepContext:
    """What the runs of a sweep share, installed once per computing process.

    Attributes
    ----------
    setups : list of ScenarioSetup
        Scenario setups (:meth:`evtms.system.scenarios.Scenario.setup`).
    refrigerants : list of Refrigerant
        Cycle maps and saturation curves (:func:`evtms.system.refrigerant.load_refrigerant`).
    runs : list of Run
        Every run, in order.
    reduce : callable
        ``reduce(index, run, result)``: what is kept of a finished run (picklable: a module-level
        function or a :func:`functools.partial` of one).
    options : dict
        Keyword arguments of :func:`evtms.system.simulate.simulate` for every run (``dt``,
        ``output_every``, ``precondition``, ``model``, ``soak_cabin`` [K], ``keep_trace``).
    mode_models : ModeModels, optional
        The mode models of the surrogate model.
    failed : callable, optional
        ``failed(index, run, message)``: what is kept of a run that raised (picklable, as ``reduce``);
        None: the error ends the sweep.
    token : str
        The context's name in each process's registry.
    """

    setups: list[Any]
    refrigerants: list[Any]
    runs: list[Run]
    reduce: Callable[[int, Run, Any], Any]
    options: dict = field(default_factory=dict)
    mode_models: Any = None
    failed: Callable[[int, Run, str], Any] | None = None
    token: str = field(default_factory=lambda: uuid.uuid4().hex)


#: Contexts installed in this process, by token.
_INSTALLED: dict[str, SweepContext] = {}


def install(context: SweepContext) -> None:
    """Make ``context`` available to the batches run in this process, and load the compiled loop."""
    _INSTALLED[context.token] = context
    warm_up(context)


def uninstall(token: str) -> None:
    """Forget the context ``token`` in this process (no error if it is not there)."""
    _INSTALLED.pop(token, None)


def warm_up(context: SweepContext) -> None:
    """Run ten parked seconds on the context's first maps: numba loads the loop from its cache (or compiles it)."""
    from evtms.system.drive_cycles import parked_cycle
    from evtms.system.simulate import simulate

    if context.refrigerants:
        simulate(parked_cycle(10.0), 298.15, context.refrigerants[0], dt=1.0)


def simulate_run(context: SweepContext, index: int) -> Any:
    """Simulate run ``index`` of ``context`` and return what its ``reduce`` keeps of it."""
    from evtms.system.scenarios import run_scenario

    run = context.runs[index]
    setup = context.setups[run.setup]
    changed = {k: v for k, v in (("RH_amb", run.RH_amb), ("sun", run.sun)) if v is not None}
    if changed:
        setup = dataclasses.replace(setup, **changed)
    options = dict(context.options)
    if run.soak_cabin is not None:
        options["soak_cabin"] = run.soak_cabin
    if context.mode_models is not None:
        options["mode_models"] = context.mode_models
    try:
        result = run_scenario(setup, context.refrigerants[run.refrigerant], run.T_amb, **options)
    except Exception as exc:  # one run's failure is its row's status; the other runs go on
        if context.failed is None:
            raise
        return context.failed(index, run, " ".join(str(exc).split()) or type(exc).__name__)
    return context.reduce(index, run, result)


def batches(n: int, size: int) -> list[range]:
    """Runs ``0 .. n-1`` cut into consecutive batches of ``size`` (the last may be shorter)."""
    if size < 1:
        raise ValueError(f"batch size {size} is not allowed; allowed: 1 or more")
    return [range(i, min(i + size, n)) for i in range(0, n, size)]


def batch_size(n: int, workers: int) -> int:
    """Runs per batch for ``n`` runs on ``workers``: at least :data:`BATCHES_PER_WORKER` batches each, at most
    :data:`MAX_BATCH` runs a batch (dask's per-task cost, a few ms, stays small beside the runs)."""
    return max(1, min(MAX_BATCH, math.ceil(n / (BATCHES_PER_WORKER * max(workers, 1)))))


class BatchJob:
    """A picklable task: the runs of batch ``k`` of the installed context ``token``.

    Small (a token and the batch ranges), so that a task costs its runs, not
    the context's maps and setups.
    """

    def __init__(self, token: str, ranges: Sequence[range]) -> None:
        self.token, self.ranges = token, list(ranges)

    def __call__(self, k: int) -> list[Any]:
        context = _INSTALLED.get(self.token)
        if context is None:  # a worker that never received the plugin: a bug, not the user's input
            raise RuntimeError(f"sweep context {self.token} is not installed in this process")
        return [simulate_run(context, i) for i in self.ranges[k]]


def make_runner(workers: int | None = None, scheduler: str | None = None):
    """The runner of a sweep: this process (neither given), ``workers`` local dask workers, or ``scheduler``.

    Raises
    ------
    EvtmsInputError
        ``workers`` below 1, both given, dask missing, or a scheduler that does not answer.
    """
    from evtms.benches.chunked import DaskRunner, InProcessRunner

    check_runner(workers, scheduler)
    if workers is None and scheduler is None:
        return InProcessRunner()
    return DaskRunner(workers=workers, scheduler=scheduler, warm_up=None)


def check_runner(workers: int | None, scheduler: str | None) -> None:
    """``workers`` at least 1 and not with ``scheduler``; the address ``tcp://host:port`` (before any work)."""
    from evtms.benches.chunked import check_scheduler_address

    if workers is not None and workers < 1:
        raise EvtmsInputError(f"`workers` {workers} is not allowed; allowed: 1 or more")
    if workers is not None and scheduler is not None:
        raise EvtmsInputError("give `workers` or `scheduler`, not both")
    if scheduler is not None:
        check_scheduler_address(scheduler)


def run_batches(
    context: SweepContext,
    runner=None,
    *,
    size: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[Any]:
    """Every run of ``context`` on ``runner``, in batches; what ``context.reduce`` keeps, in run order.

    Parameters
    ----------
    context : SweepContext
        The runs and what they share.
    runner : InProcessRunner or DaskRunner, optional
        Where the batches run (default: this process). A dask runner gets the
        context through a worker plugin, removed again when the runs are done.
    size : int, optional
        Runs per batch (default :func:`batch_size` for the runner's workers).
    progress : callable, optional
        ``progress(runs_done, runs_total)`` after each batch.

    Returns
    -------
    list
        ``reduce(i, run, result)`` for every run ``i``.
    """
    from evtms.benches.chunked import InProcessRunner

    runner = runner or InProcessRunner()
    n = len(context.runs)
    ranges = batches(n, size or batch_size(n, getattr(runner, "workers", 1)))
    results: list[Any] = [None] * n
    done = 0
    with _installed(context, runner):
        for k, values in runner.run(BatchJob(context.token, ranges), range(len(ranges))):
            for i, value in zip(ranges[k], values, strict=True):
                results[i] = value
            done += len(ranges[k])
            if progress is not None:
                progress(done, n)
    return results


@contextlib.contextmanager
def _installed(context: SweepContext, runner) -> Iterator[None]:
    """``context`` installed where ``runner`` computes (this process, or every dask worker), for the block."""
    client = getattr(runner, "client", None)
    if client is None:
        install(context)
        try:
            yield
        finally:
            uninstall(context.token)
        return
    from evtms.system._sweep_plugin import register, unregister

    plugin = register(client, context)
    try:
        yield
    finally:
        unregister(client, plugin)


def iter_installed() -> Iterator[str]:
    """Tokens of the contexts installed in this process (tests)."""
    yield from _INSTALLED
