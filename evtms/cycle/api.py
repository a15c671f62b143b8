"""Running the cycle: load LUTs, solve, energy balance, results as a dataset."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms import __version__
from evtms.benches.parameters import Parameters
from evtms.cycle.tables import CycleLut, cycle_lut, fluid_tables, made_with
from evtms.cycle.topology import INPUTS, Topology, topology
from evtms.errors import EvtmsInputError
from evtms.fluid import Fluid, SaturationCurve

if TYPE_CHECKING:
    import xarray as xr

    from evtms.cycle.results import CycleResult
    from evtms.cycle.solver import OperatingPoints
    from evtms.luts.validate import LutMetadata

#: Batches from this many points interpolate through the compiled kernel: below, numba's
#: import and load (0.3-0.5 s) cost more than it saves (about 20 ms a point).
COMPILED_FROM_POINTS = 20

#: Result variable -> (units, long_name).
RESULT_VARIABLES = {
    **{f"p_{s}": ("Pa", f"refrigerant pressure at state {s}") for s in "ABCD"},
    **{f"T_{s}": ("K", f"refrigerant temperature at state {s}") for s in "ABCD"},
    **{f"h_{s}": ("J kg-1", f"refrigerant specific enthalpy at state {s}") for s in "ABCD"},
    "mdot": ("kg s-1", "refrigerant mass flow rate"),
    "mdot_evap": ("kg s-1", "refrigerant mass flow through the cabin evaporator (0 without one)"),
    "mdot_chiller": ("kg s-1", "refrigerant mass flow through the chiller (0 without one)"),
    "Q_evap": ("W", "evaporator heat flow from refrigerant to air (< 0: cooling; 0 without one)"),
    "Q_latent": ("W", "latent (dehumidification) part of Q_evap"),
    "Q_chiller": ("W", "chiller heat flow from refrigerant to coolant (< 0: cooling; 0 without one)"),
    "Q_cond": (
        "W",
        "condensing heat flow from refrigerant to air (to the WCC's coolant where it condenses alone, hp; "
        "to both in series, cabin+wcc)",
    ),
    "Q_wcc": ("W", "the part of Q_cond the WCC gives its coolant (0 without one)"),
    "W": ("W", "compressor shaft power"),
    "W_fluid": ("W", "power given to the refrigerant, mdot (h_B - h_A)"),
    "COP": ("1", "cooling coefficient of performance (|Q_evap| + |Q_chiller|) / W"),
    "COP_heating": ("1", "heating coefficient of performance Q_cond / W (the heat pump's, hp)"),
    "dp_valve": ("Pa", "expansion-valve pressure drop p_C - p_D (of the first branch)"),
    "valve_opening": ("1", "first branch's valve opening relative to its nominal opening"),
    "valve_opening_chiller": ("1", "chiller valve opening relative to its nominal opening (NaN without a chiller)"),
    "superheat_actual": (
        "K",
        "first branch's outlet superheat: the setpoint, or floating where its valve is saturated (NaN where closed)",
    ),
    "superheat_chiller": (
        "K",
        "chiller-outlet superheat: the setpoint, or floating where its valve is saturated (NaN without a chiller "
        "or where closed)",
    ),
    "balance_residual": ("W", "Q_cond + Q_evap + Q_chiller - W_fluid, each from its own component"),
    "balance_relative": ("1", "balance_residual / W_fluid"),
}


#: The preset grid of the LUTs the cycle reads, and the demo's other grid (its folders are looked at
#: only to say what a folder holds); where each grid's LUT folder may be: :meth:`LutStore.places`.
CYCLE_GRID = "cycle"
_THESIS_GRID = "thesis"
#: What a LUT folder should be, as the error messages say it.
EXPECTED_LUT_FOLDER = (
    "give the folder of cycle-grid LUTs that 'evtms bench all --grid cycle -o DIR' writes, "
    "or the luts/ folder (or the output folder) that 'evtms demo -o OUT' wrote"
)


def _q(path: Path) -> str:
    return repr(str(path))


def _lut_files(where: Path, components: tuple[str, ...]) -> dict[str, LutMetadata | str]:
    """Each of ``components``' LUT files in ``where``: its checked header, or why it is no LUT."""
    from evtms.luts.store import LutStore
    from evtms.luts.validate import read_lut_metadata
    from evtms.paths import input_file

    found: dict[str, LutMetadata | str] = {}
    for c, path in LutStore(where).luts(components).items():
        if not (path.exists() or path.is_symlink()):
            continue
        try:
            found[c] = read_lut_metadata(input_file(path, "LUT file"), c)
        except EvtmsInputError as exc:
            found[c] = str(exc).removeprefix(f"{path}: ")
    return found


def _usable(entry: LutMetadata | str) -> bool:
    # A thesis-grid LUT is a valid file but spans temperatures, not the enthalpies and air
    # inlets the cycle queries: the cycle refuses it rather than fail at its first query.
    return not isinstance(entry, str) and entry.attrs.get("grid") != _THESIS_GRID


def _holding(where: Path, found: dict[str, LutMetadata | str], needed: tuple[str, ...]) -> str:
    """What ``where`` holds, in words: components by grid, files that are no LUT, components missing."""
    grids: dict[str, list[str]] = {}
    for c, entry in found.items():
        if not isinstance(entry, str):
            grids.setdefault(str(entry.attrs.get("grid") or "unnamed"), []).append(c)
    parts = [f"{', '.join(names)} on the {grid} grid" for grid, names in grids.items()]
    parts += [f"{c}.nc, which is no valid LUT ({entry})" for c, entry in found.items() if isinstance(entry, str)]
    text = f"{_q(where)} holds " + " and ".join(parts)
    missing = [c for c in needed if c not in found]
    if missing and any(_usable(e) for e in found.values()):
        text += f", and lacks {', '.join(missing)}"
    return text


def _find_cycle_luts(folder: Path, needed: tuple[str, ...]) -> tuple[Path, dict[str, LutMetadata]] | None:
    """(folder holding the cycle LUTs of ``needed``, their headers), or None where no LUT file is found."""
    from evtms.luts.schema import COMPONENT_AXES
    from evtms.luts.store import LutStore

    if folder.exists() and not folder.is_dir():
        raise EvtmsInputError(f"LUT folder {_q(folder)} is a file; {EXPECTED_LUT_FOLDER}")
    places = LutStore.places(folder, CYCLE_GRID)
    for where in places:
        found = _lut_files(where, needed)
        if len(found) == len(needed) and all(_usable(e) for e in found.values()):
            return where, found  # type: ignore[return-value]
    # No complete set: say what is there (every component, the thesis folders too) before
    # anything is built over it.
    held = []
    for where in places + LutStore.places(folder, _THESIS_GRID)[1:]:
        found = _lut_files(where, tuple(COMPONENT_AXES))
        if found:
            held.append(_holding(where, found, needed))
    if not held:
        return None
    raise EvtmsInputError(f"no complete set of cycle LUTs in {_q(folder)}: {'; '.join(held)}; {EXPECTED_LUT_FOLDER}")


def cycle_luts_folder(folder: str | Path, circuit: Topology | str = "cabin+chiller") -> Path | None:
    """The folder holding the cycle LUTs for a LUT folder a user gives, or None if it holds no LUTs.

    The LUTs are looked for in ``folder`` itself (as ``evtms bench all --grid
    cycle -o folder`` writes them), in ``folder/cycle`` (``folder`` is the
    ``luts/`` folder ``evtms demo -o OUT`` writes) and in ``folder/luts/cycle``
    (``folder`` is the demo's ``OUT``), in this order
    (:meth:`evtms.luts.store.LutStore.places`). The first that holds a valid
    LUT of every component of ``circuit``, none of them on the thesis grid
    (its metadata ``grid``), is the one.

    Parameters
    ----------
    folder : str or Path
        The folder the user gave.
    circuit : Topology or str, optional
        The circuit whose components are needed; default: every component
        (as the system simulator needs them).

    Returns
    -------
    Path or None
        The folder holding the cycle LUTs; None if neither ``folder`` nor
        those folders (nor the demo's ``thesis`` ones) hold any component's
        LUT file: ``folder`` is missing or holds no LUTs, so LUTs built there
        overwrite none.

    Raises
    ------
    EvtmsInputError
        ``folder`` is a file, or it holds LUT files but no complete set of
        cycle LUTs: one line saying which files were found where, on which
        grid (and which are no valid LUT), and which folder is expected.
    """
    needed = topology(circuit).components
    found = _find_cycle_luts(Path(folder), needed)
    return None if found is None else found[0]


def load_cycle_luts(folder: str | Path, circuit: Topology | str = "cabin") -> dict[str, CycleLut]:
    """The component LUTs the circuit needs, from the folder :func:`cycle_luts_folder` finds, headers checked.

    ``folder`` is the folder of the cycle LUTs, or the ``luts/`` folder or
    output folder of ``evtms demo`` (see :func:`cycle_luts_folder`). Each
    file's header is read and checked against the LUT format (and its
    component); the tables the cycle interpolates are built from the data on
    first use and cached (:class:`evtms.cycle.tables.CycleLut`),
    so a second run neither decompresses nor holds the whole tables.

    Raises
    ------
    EvtmsInputError
        The folder is missing, a file, holds no LUTs, or holds LUT files but
        no complete set of cycle LUTs (a file missing, not a valid LUT, of
        another component or on the thesis grid), or a file's parameters do
        not belong to its component (:func:`evtms.cycle.tables.made_with`) or
        name another fluid than the others; one line saying what was found and
        what is expected.
    """
    folder = Path(folder)
    needed = topology(circuit).components
    found = _find_cycle_luts(folder, needed)
    if found is None:
        state = "does not exist" if not folder.is_dir() else "holds no LUTs"
        raise EvtmsInputError(f"LUT folder {_q(folder)} {state}; {EXPECTED_LUT_FOLDER}")
    _, headers = found
    luts = {c: CycleLut(headers[c].path, c, headers[c]) for c in needed}
    fluids: dict[str, list[str]] = {}
    for c, lut in luts.items():
        made_with(lut)  # each file's parameters, checked before any work
        fluids.setdefault(lut.attrs.get("fluid", "R134a"), []).append(c)
    if len(fluids) > 1:
        made = " and ".join(f"{f!r} ({', '.join(cs)})" for f, cs in fluids.items())
        raise EvtmsInputError(f"the cycle LUTs in {_q(found[0])} are made for fluids {made}; allowed: one fluid")
    return luts


def saturation_curve(luts: dict, fluid: Fluid | None = None) -> SaturationCurve:
    """The refrigerant's saturation curve for a LUT cycle; cached (:mod:`evtms.luts.cache`) for LUT files.

    The curve is CoolProp's (:class:`SaturationCurve`) for the LUTs' fluid
    and backend, tabulated once per CoolProp version: a cached one spares a
    LUT run the import of CoolProp (about 2 s). ``fluid`` is used if given
    and nothing is cached.
    """

    def build(name: str, backend: str) -> dict:
        return SaturationCurve(fluid or Fluid(name, backend)).tables()

    arrays = fluid_tables(luts, "saturation", list(SaturationCurve.__init__.__defaults__), build)
    return SaturationCurve.from_tables(arrays)


def parameter_conflicts(luts: dict[str, xr.Dataset], params: Parameters) -> list[str]:
    """Dotted parameter names (``condenser.n_tubes``) where ``params`` differs from the LUTs' provenance.

    In LUT mode the cycle's physics is the LUTs', made with the parameters
    and air boundary each file records; a parameter set that differs would be
    silently ignored, so the caller refuses it.
    """
    conflicts: list[str] = []
    for c, ds in luts.items():
        conflicts += params.differences(made_with(cycle_lut(ds, c)), sections=("fluid", "backend", c, "environment"))
    return list(dict.fromkeys(conflicts))


def cycle_encoding(ds: xr.Dataset) -> dict[str, dict]:
    """netCDF encoding of a cycle sweep: CF-clean and compressed.

    Coordinates carry no ``_FillValue``; the float results are zlib-compressed
    with NaN as fill; ``reason`` is a fixed-width UTF-8 character array (a
    variable-length string breaks CF checkers).
    """
    encoding: dict[str, dict] = {d: {"_FillValue": None} for d in ds.coords}
    for name, var in ds.data_vars.items():
        if name == "reason":
            encoding[name] = {"dtype": "S1", "char_dim_name": "reason_strlen", "zlib": True}
        elif var.dtype.kind == "f":
            encoding[name] = {"_FillValue": np.nan, "zlib": True, "shuffle": True, "complevel": 4}
        else:
            encoding[name] = {"_FillValue": None, "zlib": True, "shuffle": True, "complevel": 4}
    return encoding


def energy_balance(result: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """First-law residual of the cycle, each term from its own component.

    ``residual = Q_cond + Q_evap + Q_chiller - W_fluid`` [W] (``Q_evap``,
    ``Q_chiller`` < 0), and
    ``relative = residual / W_fluid`` [1]. The valve is isenthalpic, so with
    exact components the residual is zero; with LUTs it measures how
    consistently the separately interpolated LUTs describe the same states.
    """
    residual = result["Q_cond"] + result["Q_evap"] + result.get("Q_chiller", 0.0) - result["W_fluid"]
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = residual / result["W_fluid"]
    return {"residual": residual, "relative": relative}


def run_cycle(
    points: OperatingPoints,
    luts: dict[str, xr.Dataset] | None = None,
    params: Parameters | None = None,
    fluid: Fluid | None = None,
    circuit: Topology | str = "cabin",
    compiled: bool | None = None,
    closure: str = "auto",
) -> CycleResult:
    """Solve operating points of a circuit on LUTs, or with the bench physics if ``luts`` is None.

    ``compiled``: interpolate through the compiled kernels (True) or on the NumPy path
    (False); None chooses by the batch's size (:data:`COMPILED_FROM_POINTS`). The two
    agree to round-off, so a job that must give the same bits however it is split into
    batches (the simulator's maps) fixes it, as it fixes ``closure`` (:class:`CycleSolver`).

    Returns the solver's result (see :meth:`CycleSolver.solve`) with
    ``balance_residual`` and ``balance_relative`` (:func:`energy_balance`).
    """
    # The solver and its models load here: finding and reading LUT folders (the simulator's use) needs neither.
    from evtms.cycle.models import DirectModels, LutModels
    from evtms.cycle.solver import CycleSolver

    params = params or Parameters()
    circuit = topology(circuit)
    if luts is None:
        fluid = fluid or Fluid(params.fluid, params.backend)
        models, saturation = DirectModels(params, fluid), fluid.saturation_curve()
    else:  # no CoolProp needed where the cache has the saturation curve
        if compiled is None:  # the compiled closure reads compiled LUTs
            compiled = closure == "compiled" or len(points) >= COMPILED_FROM_POINTS
        saturation = saturation_curve(luts, fluid)
        models = LutModels(luts, circuit.components, compiled, saturation=saturation)
    solver = CycleSolver(models, saturation, circuit, closure)
    result = solver.solve(points)
    bal = energy_balance(result)
    return result.with_balance(bal["residual"], bal["relative"])


def solve_grid(
    grid: dict[str, list[float] | np.ndarray],
    luts: dict[str, xr.Dataset] | None = None,
    params: Parameters | None = None,
    circuit: Topology | str = "cabin",
    fluid: Fluid | None = None,
) -> tuple[OperatingPoints, CycleResult]:
    """Solve the circuit on every combination of its inputs' values (the CLI's and the demo's sweep).

    ``grid`` gives each input of ``circuit`` (``Topology.inputs``) its
    values; an input it lacks takes its default (:data:`INPUTS`). Returns
    the operating points (C order of the grid) and :func:`run_cycle`'s result.
    """
    from evtms.cycle.solver import OperatingPoints

    circuit = topology(circuit)
    axes = [np.asarray(grid.get(k, [INPUTS[k].default]), float) for k in circuit.inputs]
    mesh = np.meshgrid(*axes, indexing="ij")
    points = OperatingPoints(**{k: m.ravel() for k, m in zip(circuit.inputs, mesh, strict=True)})
    return points, run_cycle(points, luts, params, fluid, circuit)


def cycle_dataset(
    grid: dict[str, np.ndarray], result: Mapping[str, np.ndarray], source: str, circuit: Topology | str = "cabin"
) -> xr.Dataset:
    """Results of a cycle sweep on a grid of inputs as a dataset with units.

    ``grid`` gives each input of the circuit its values (one dimension per
    input, in ``Topology.inputs`` order); ``result`` holds flat arrays in C
    order of that grid.
    """
    import datetime as dt

    import xarray as xr

    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS

    circuit = topology(circuit)
    dims = circuit.inputs
    shape = tuple(len(grid[d]) for d in dims)
    coords = {
        d: xr.Variable(d, np.asarray(grid[d], float), {"units": INPUTS[d].units, "long_name": INPUTS[d].long_name})
        for d in dims
    }
    data = {}
    for name, (units, long_name) in RESULT_VARIABLES.items():
        data[name] = xr.Variable(
            dims, np.asarray(result[name], float).reshape(shape), {"units": units, "long_name": long_name}
        )
    codes = sorted(CYCLE_FLAGS)
    data["status"] = xr.Variable(
        dims,
        np.asarray(result["status"], np.int8).reshape(shape),
        {
            "units": "1",
            "long_name": "cycle status",
            "flag_values": np.array(codes, np.int8),
            "flag_meanings": " ".join(CYCLE_FLAGS[c] for c in codes),
            "valid_flag_values": np.array(VALID_CYCLE_FLAGS, np.int8),
        },
    )
    data["reason"] = xr.Variable(
        dims,
        np.asarray(result["reason"], dtype=object).reshape(shape).astype(str),
        {"long_name": "why a point is invalid (empty when converged)"},
    )
    created = dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    attrs = {
        "Conventions": "CF-1.10",
        "title": "evtms vapor-compression cycle sweep",
        "evtms_version": __version__,
        "models": source,
        "topology": circuit.name,
        "created": created,
        "history": f"{created} evtms cycle sweep",
        "inputs": json.dumps({d: list(map(float, grid[d])) for d in dims}),
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)
