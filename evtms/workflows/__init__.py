"""The application layer: what each command does, callable from Python.

Each workflow takes a request (a dataclass of the command's options, in the
command line's units: degC for temperatures, text such as ``0.2:1:9`` or
numbers for values), applies every check the command line applies, does the
work and returns a typed result; it never prints or exits. A bad request
raises :class:`evtms.errors.EvtmsInputError` whose one-line message names the
request field in backticks (the CLI shows it as the option). The CLI
(:mod:`evtms.cli`) parses options into a request, calls one workflow and prints
its result.

- :func:`~.bench.run_bench` (``evtms bench``): :class:`~.bench.BenchRequest` ->
  :class:`~.bench.BenchResult`, the LUT files written;
- :func:`~.cycle.run_cycle` (``evtms cycle run``): :class:`~.cycle.CycleRequest` ->
  :class:`~.cycle.CyclePoint`; :func:`~.cycle.sweep_cycle` (``evtms cycle sweep``): the same request ->
  :class:`~.cycle.CycleSweep`, its xarray dataset written as netCDF;
- :func:`~.simulate.run_simulation` (``evtms simulate``): :class:`~.simulate.SimulationRequest` ->
  :class:`~.simulate.SimulationRun`; :func:`~.sweep.run_sweep` (``evtms sweep``): :class:`~.sweep.SweepRequest` ->
  :class:`~.sweep.SweepResult`, its summary table written;
- :func:`~.compare.run_comparison` (``evtms report compare``): :class:`~.compare.CompareRequest` ->
  :class:`~.compare.Comparison`;
- :func:`~.train.train_mode_models` (``evtms surrogate train``): :class:`~.train.TrainRequest` ->
  the training report;
- :func:`~.demo.run_demo` (``evtms demo``): an output folder -> :class:`~.demo.DemoResult`.

Example::

    from pathlib import Path
    from evtms.workflows import CycleRequest, SimulationRequest, run_cycle, run_simulation

    point = run_cycle(CycleRequest(inputs={"speed": 0.6, "T_amb": 30}, luts=Path("luts")))
    cop, residual = point.values["COP"], point.values["balance_relative"]
    run = run_simulation(SimulationRequest(cycle="wltc3b", t_amb=30, luts=Path("luts")))
    energy = run.results[0].summary["battery_energy_kWh"]  # kWh, at the terminals

The modules are imported when a name is first used, so ``import evtms.workflows``
stays cheap. :mod:`~.lut` and :mod:`~.report` hold what the ``evtms lut`` and
``evtms report`` figure commands run.
"""

from __future__ import annotations

import importlib

#: Public name -> the module of this package that defines it (no name is also a module's name).
_API = {
    "BenchRequest": "bench",
    "BenchResult": "bench",
    "run_bench": "bench",
    "CycleRequest": "cycle",
    "CyclePoint": "cycle",
    "CycleSweep": "cycle",
    "run_cycle": "cycle",
    "sweep_cycle": "cycle",
    "SimulationRequest": "simulate",
    "SimulationRun": "simulate",
    "run_simulation": "simulate",
    "SweepRequest": "sweep",
    "SweepResult": "sweep",
    "run_sweep": "sweep",
    "CompareRequest": "compare",
    "Comparison": "compare",
    "run_comparison": "compare",
    "TrainRequest": "train",
    "train_mode_models": "train",
    "DemoResult": "demo",
    "run_demo": "demo",
}

__all__ = sorted(_API)


def __getattr__(name: str):
    if name in _API:
        return getattr(importlib.import_module(f"{__name__}.{_API[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})
