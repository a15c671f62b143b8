"""evtms: R134a refrigerant-circuit benches, N-D lookup tables and cycle models.

Importing the package is cheap on purpose: CoolProp, xarray and matplotlib
load only inside the functions that need them, so ``evtms --help`` is fast.
The workflows of :mod:`evtms.workflows` (what each command runs, e.g.
:func:`~evtms.workflows.run_cycle`, :func:`~evtms.workflows.run_simulation`)
are importable from here too; they are loaded when first used.
"""

__version__ = "0.1.0"

#: Names of evtms.workflows this package gives too (loaded when first used).
_WORKFLOWS = (
    "BenchRequest",
    "CompareRequest",
    "CycleRequest",
    "SimulationRequest",
    "TrainRequest",
    "run_bench",
    "run_comparison",
    "run_cycle",
    "run_demo",
    "run_simulation",
    "sweep_cycle",
    "train_mode_models",
)

__all__ = ["__version__", *_WORKFLOWS]


def __getattr__(name: str):
    if name in _WORKFLOWS:
        from evtms import workflows

        return getattr(workflows, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
