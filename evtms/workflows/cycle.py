"""The refrigerant cycle on the component LUTs (or the bench physics): one operating point or a sweep.

:func:`run_cycle` is ``evtms cycle run`` and :func:`sweep_cycle` ``evtms cycle
sweep``: a :class:`CycleRequest` gives the circuit, its inputs (in the command
line's units: degC for temperatures, ``v1,v2,...`` or ``start:stop:count`` for
several values), where the models come from and, for a sweep, the output
file. The values, the models and the paths are checked before anything is
solved. (:func:`evtms.cycle.run_cycle` is the solver itself, on operating
points already in SI.)
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, output_file
from evtms.workflows.common import as_text, params_input

__all__ = ["DEFAULT_MAX_CYCLE_POINTS", "CyclePoint", "CycleRequest", "CycleSweep", "run_cycle", "sweep_cycle"]

#: Operating points one sweep solves at most unless the request raises the limit.
DEFAULT_MAX_CYCLE_POINTS = 2_000_000


@dataclass
class CycleRequest:
    """Operating points of a circuit and the models to solve them with.

    Attributes
    ----------
    topology : str
        Circuit: ``cabin``, ``chiller`` or ``cabin+chiller``.
    inputs : mapping of str to str, float or sequence of float
        Inputs by name (:data:`evtms.cycle.topology.INPUTS`: ``speed``, ``T_amb`` ...) in the command line's
        units (temperatures in degC); text as on the command line (``0.2:1:9``). An input not given takes its
        default.
    luts : Path, optional
        Folder of the cycle LUTs (or ``evtms demo``'s luts/ or output folder); default ``luts/``.
    direct : bool
        Solve with the bench physics instead of LUTs.
    params : Path, optional
        TOML parameters (direct); with LUTs they must agree with the LUTs' own.
    output : Path, optional
        The sweep's netCDF file (:func:`sweep_cycle`; none: not written).
    max_points : int
        Most operating points of a sweep.
    """

    topology: str = "cabin"
    inputs: Mapping[str, str | float | Sequence[float] | None] = field(default_factory=dict)
    luts: Path | None = None
    direct: bool = False
    params: Path | None = None
    output: Path | None = None
    max_points: int = DEFAULT_MAX_CYCLE_POINTS


@dataclass
class CyclePoint:
    """One solved operating point (:func:`run_cycle`).

    Attributes
    ----------
    topology : str
        Circuit name.
    components : tuple of str
        Its components.
    inputs : dict of str to float
        The inputs [SI].
    models : str
        ``direct``, or the folder of the LUTs.
    status : int
        Solver flag (:data:`evtms.cycle.CYCLE_FLAGS`), a valid one.
    status_meaning, note : str
        The flag's meaning and the solver's remark (empty if none).
    values : dict of str to float
        Every number the solver returns: states ``p_A`` ... ``h_D`` and performance (``Q_evap``, ``W``,
        ``COP``, ``balance_residual`` ...) [SI].
    """

    topology: str
    components: tuple[str, ...]
    inputs: dict[str, float]
    models: str
    status: int
    status_meaning: str
    note: str
    values: dict[str, float]


@dataclass
class CycleSweep:
    """A solved grid of operating points (:func:`sweep_cycle`).

    Attributes
    ----------
    dataset : xarray.Dataset
        The sweep (docs/cycle-format.md), as written to ``path``.
    path : Path or None
        The file written.
    points, solved : int
        Operating points, and those solved.
    seconds : float
        Solve time [s].
    status : dict of str to int
        Points per solver flag.
    """

    dataset: Any
    path: Path | None
    points: int
    solved: int
    seconds: float
    status: dict[str, int]


def _cycle_inputs(request: CycleRequest, max_points: int = DEFAULT_MAX_CYCLE_POINTS):
    """(circuit, grid of its inputs) from the request; the library checks every value."""
    from evtms.cycle.topology import INPUTS, parse_inputs
    from evtms.cycle.topology import topology as circuit_named

    unknown = [k for k in request.inputs if k not in INPUTS]
    if unknown:
        raise EvtmsInputError(f"cycle input {unknown[0]!r} is unknown; allowed: {', '.join(INPUTS)}")
    circuit = circuit_named(request.topology)
    texts = {k: as_text(request.inputs.get(k)) for k in INPUTS}
    return circuit, parse_inputs(texts, circuit, max_points)


def _cycle_models(luts: Path | None, direct: bool, params: Path | None, circuit):
    """(LUT tables or None, parameters); ``params`` that the LUTs contradict are refused."""
    from evtms.cycle import load_cycle_luts
    from evtms.system.params import load_parameter_tree
    from evtms.workflows.common import check_lut_components

    if direct and luts is not None:
        raise EvtmsInputError("give `direct` (bench physics) or `luts` (LUT folder), not both")
    params_input(params)
    tree = load_parameter_tree(params)
    if direct:
        return None, tree.components
    folder = luts or Path("luts")
    tables = load_cycle_luts(folder, circuit)
    check_lut_components(tables, tree, params, folder, " or use `direct`")
    return tables, tree.components


def _lut_folder(tables: dict) -> Path:
    """The folder the cycle LUTs were found in (one folder for all of them)."""
    return next(iter(tables.values())).path.parent


def run_cycle(request: CycleRequest) -> CyclePoint:
    """Solve one operating point.

    Parameters
    ----------
    request : CycleRequest
        One value per input.

    Returns
    -------
    CyclePoint

    Raises
    ------
    EvtmsInputError
        A bad input value or an input given several values, an unknown
        topology, LUTs missing or made with other parameters, or a point the
        solver does not solve.
    """
    from evtms.cycle.api import solve_grid
    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS

    circuit, grid = _cycle_inputs(request)
    several = [f"`{k}` ({len(v)} values)" for k, v in grid.items() if len(v) != 1]
    if several:
        raise EvtmsInputError(
            f"{', '.join(several)}: cycle run takes one value per input; use 'evtms cycle sweep' for several"
        )
    tables, parameters = _cycle_models(request.luts, request.direct, request.params, circuit)
    _, r = solve_grid(grid, tables, parameters, circuit)
    status = int(r["status"][0])
    if status not in VALID_CYCLE_FLAGS:
        raise EvtmsInputError(f"operating point not solved: {r['reason'][0]}")
    return CyclePoint(
        topology=circuit.name,
        components=tuple(circuit.components),
        inputs={k: v[0] for k, v in grid.items()},
        models="direct" if tables is None else str(_lut_folder(tables)),
        status=status,
        status_meaning=CYCLE_FLAGS[status],
        note=str(r["reason"][0]),
        values={k: float(v[0]) for k, v in r.items() if k not in ("status", "reason")},
    )


def sweep_cycle(request: CycleRequest) -> CycleSweep:
    """Solve every combination of the inputs' values and write the sweep to ``request.output``.

    Parameters
    ----------
    request : CycleRequest
        Any input as ``v1,v2,...`` or ``start:stop:count``; ``output`` a ``.nc`` file (or None).

    Returns
    -------
    CycleSweep

    Raises
    ------
    EvtmsInputError
        ``max_points`` below 1 or more points than it allows, a bad input value,
        LUTs missing or made with other parameters, or an output path that is
        not allowed (one of the LUTs, not ``.nc``).
    """
    import numpy as np

    from evtms.cycle import cycle_dataset
    from evtms.cycle.api import cycle_encoding, solve_grid
    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS
    from evtms.luts.io import atomic_output

    if request.max_points < 1:
        raise EvtmsInputError(f"`max_points` {request.max_points} is not allowed; allowed: 1 or more")
    circuit, grid = _cycle_inputs(request, request.max_points)
    tables, parameters = _cycle_models(request.luts, request.direct, request.params, circuit)
    output = request.output
    if output is not None:
        # The LUT files found (headers read, data not yet): the output may not be one of them.
        inputs = [request.params] + ([] if tables is None else [t.path for t in tables.values()])
        output_file(output, inputs, (".nc",))
    t0 = time.perf_counter()
    points, r = solve_grid(grid, tables, parameters, circuit)
    wall = time.perf_counter() - t0
    ds = cycle_dataset(grid, r, "direct" if tables is None else f"LUTs in {_lut_folder(tables)}", circuit)
    if output is not None:
        with creating_parents(output), atomic_output(output) as tmp:
            ds.to_netcdf(tmp, engine="netcdf4", encoding=cycle_encoding(ds))
    status = np.asarray(r["status"])
    return CycleSweep(
        dataset=ds,
        path=output,
        points=len(points),
        solved=int(np.isin(status, VALID_CYCLE_FLAGS).sum()),
        seconds=wall,
        status={CYCLE_FLAGS[c]: int((status == c).sum()) for c in sorted(CYCLE_FLAGS)},
    )
