"""LUT files: summary, queries at points, export and comparison (``evtms lut ...``).

Every function takes file paths, checks them (a missing, unreadable or
invalid LUT is one :class:`~evtms.errors.EvtmsInputError` line) and returns
plain results; nothing is printed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file

__all__ = ["LutQuery", "diff_luts", "export_lut", "lut_info", "open_lut_file", "parse_point", "query_lut"]

#: Most points one query interpolates.
MAX_QUERY_POINTS = 100_000


def open_lut_file(path: str | Path, **kwargs):
    """A validated LUT (see :func:`evtms.luts.open_lut`), once ``path`` is checked to be a file."""
    from evtms.luts import open_lut

    return open_lut(input_file(path, "LUT file"), **kwargs)


def lut_info(path: str | Path) -> dict:
    """A LUT's component, axes, variables with their ranges, status counts and provenance.

    Reads the metadata and streams the data once (:func:`evtms.luts.summary.lut_summary`).
    """
    from evtms.luts.summary import lut_summary

    return lut_summary(input_file(path, "LUT file"))


def parse_point(text: str, names: tuple[str, ...], partial: bool = False, fixed: dict | None = None) -> dict:
    """``name=value[unit],...`` (a point, the request field ``at``) -> SI values (units as for a bench axis).

    A fixed input of the LUT (``fixed``: name -> value) may be given too; it
    must then equal the LUT's value, as the LUT holds no other.
    """
    from evtms.benches.grid import parse_value

    fixed = fixed or {}
    point: dict[str, float] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise EvtmsInputError(f"`at` item {item!r} is not name=value")
        if name not in names and name not in fixed:
            raise EvtmsInputError(f"unknown axis {name!r} in `at`; allowed: {', '.join((*names, *fixed))}")
        if name in point:
            raise EvtmsInputError(f"axis {name!r} is given twice in `at`")
        x = parse_value(name, value)
        if name in fixed:
            if not math.isclose(x, fixed[name], rel_tol=1e-9, abs_tol=1e-12):
                raise EvtmsInputError(
                    f"{name} = {x:g} in `at`: the LUT holds {name} fixed at {fixed[name]:g} only (not an axis)"
                )
            continue
        point[name] = x
    missing = [n for n in names if n not in point]
    if missing and not partial:
        raise EvtmsInputError(f"`at` has no value for axis {missing[0]!r}; give all of {', '.join(names)}")
    return point


@dataclass
class LutQuery:
    """Variables of a LUT interpolated at points (:func:`query_lut`).

    Attributes
    ----------
    axes : tuple of str
        The LUT's axes, in order.
    fixed_inputs : dict of str to float
        Inputs the LUT holds at one value (not axes) [SI].
    variables : tuple of str
        The variables interpolated.
    units : dict of str to str
        Units of every axis and variable.
    points : list of dict of str to float
        Per point, its axis values and the interpolated variables [SI].
    """

    axes: tuple[str, ...]
    fixed_inputs: dict[str, float]
    variables: tuple[str, ...]
    units: dict[str, str]
    points: list[dict[str, float]]


def query_lut(
    path: str | Path, at: Sequence[str], var: Sequence[str] | None = None, out_of_range: str = "error"
) -> LutQuery:
    """Interpolate LUT variables at points (N-D multilinear).

    Parameters
    ----------
    path : str or Path
        The LUT file.
    at : sequence of str
        Points as ``name=value,...`` (SI, or with a unit suffix), every axis given.
    var : sequence of str, optional
        Variables (each item may be comma-separated); default all.
    out_of_range : str
        Outside the grid: ``error``, ``clip`` or ``nan``.

    Returns
    -------
    LutQuery
    """
    from evtms.luts import Interpolator
    from evtms.luts.validate import fixed_inputs

    if len(at) > MAX_QUERY_POINTS:
        raise EvtmsInputError(f"{len(at)} `at` points is above the limit of {MAX_QUERY_POINTS:,}")
    if out_of_range not in ("error", "clip", "nan"):
        raise EvtmsInputError(f"`out_of_range` {out_of_range!r} is not allowed; allowed: error, clip, nan")
    variables = [v.strip() for item in (var or []) for v in item.split(",") if v.strip()] or None
    if variables is not None and len(set(variables)) != len(variables):
        raise EvtmsInputError(f"`var` names a variable twice: {', '.join(variables)}")
    ds = open_lut_file(path, variables=variables)
    names = tuple(ds["status"].dims)
    fixed = fixed_inputs(ds)
    itp = Interpolator.from_dataset(ds, variables, out_of_range)
    points = [parse_point(text, names, fixed=fixed) for text in at]
    result = itp({n: [p[n] for p in points] for n in names})
    return LutQuery(
        axes=names,
        fixed_inputs=fixed,
        variables=tuple(itp.variables),
        units={n: ds[n].attrs["units"] for n in (*names, *itp.variables)},
        points=[
            {**{n: p[n] for n in names}, **{v: float(result[v][i]) for v in itp.variables}}
            for i, p in enumerate(points)
        ],
    )


def export_lut(path: str | Path, fmt: str, output: str | Path) -> Path:
    """Export a LUT to ``.mat`` (MATLAB/Simulink; length-1 axes dropped into ``lut.fixed_inputs``) or ``.csv``.

    Returns
    -------
    Path
        The file written.
    """
    from evtms.luts.export import FORMATS, to_csv, to_mat

    if fmt not in FORMATS:
        raise EvtmsInputError(f"export format {fmt!r} is not allowed; allowed: {', '.join(FORMATS)}")
    output_file(output, [path])
    ds = open_lut_file(path)
    with creating_parents(output):
        return (to_mat if fmt == "mat" else to_csv)(ds, output)


def diff_luts(a: str | Path, b: str | Path):
    """Per-variable max and RMS differences of two LUTs, parameter and version changes.

    Returns
    -------
    LutDiff
        :func:`evtms.luts.diff.lut_diff` of the two files.
    """
    from evtms.luts.diff import lut_diff

    return lut_diff(open_lut_file(a), open_lut_file(b))
