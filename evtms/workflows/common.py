"""What the workflows share: callback types and the reading of request values.

A workflow reports through two optional callbacks, never by printing:
``notify(message)`` for a one-line note (a message that starts with spaces
details the note before it) and ``progress(done, total, label)`` for a
progress bar per ``label``. A request field that a message names is written in
backticks (:class:`evtms.errors.EvtmsInputError`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from evtms.paths import input_file

Notify = Callable[[str], None]
Progress = Callable[[int, int, str], None]


def quiet(message: str) -> None:
    """A ``notify`` that drops the note."""


def own_process() -> None:
    """Set up a process that runs evtms alone (the command line): start-up costs only what evtms uses.

    numba, when first imported, leaves out its SciPy BLAS and cffi bindings
    (:func:`evtms._jit.lean_numba`), which no evtms kernel uses and which cost
    a short run more than its simulation.
    """
    from evtms._jit import lean_numba

    lean_numba()


def as_text(value: str | float | Sequence[float] | None) -> str | None:
    """A request value as the command line's text: a number or numbers as ``v1,v2,...``."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, int | float):
        return repr(float(value))
    return ",".join(repr(float(v)) for v in value)


def params_input(params: str | Path | None, what: str = "params file") -> list[Path]:
    """``[params]`` once it is checked to be a readable file (``[]`` without one)."""
    return [input_file(params, what)] if params is not None else []


def check_lut_components(tables: dict, tree, params: str | Path | None, folder: Path, hint: str = "") -> None:
    """Refuse a parameter file whose component tables the LUTs in ``folder`` contradict.

    The LUTs' physics is fixed by the parameters each file records; a table
    the file gives (``[condenser]``, ``fluid``, ``[environment]``, ...) that
    differs would be silently ignored. Tables the file does not give are not
    compared: a file of system tables only fits any LUTs.

    Parameters
    ----------
    tables : dict
        The cycle LUTs by component (:func:`evtms.cycle.load_cycle_luts`).
    tree : ParameterTree
        The parameters read from ``params`` (:func:`evtms.system.params.load_parameter_tree`).
    params : str or Path, optional
        The parameter file (named in the message).
    folder : Path
        The LUTs' folder (named in the message).
    hint : str
        What else the caller can do, appended to the message (``" or use `direct`"``).
    """
    from evtms.cycle.api import parameter_conflicts
    from evtms.errors import EvtmsInputError

    given = set(tree.given_components())
    if not given:
        return
    conflicts = [c for c in parameter_conflicts(tables, tree.components) if c.split(".")[0] in given]
    if conflicts:
        shown = ", ".join(conflicts[:6]) + (f" and {len(conflicts) - 6} more" if len(conflicts) > 6 else "")
        raise EvtmsInputError(
            f"`params` {str(params)!r} differs from the parameters the LUTs in {str(folder)!r} were made with "
            f"({shown}); rebuild the LUTs with these parameters{hint}"
        )
