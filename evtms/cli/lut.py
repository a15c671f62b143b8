"""evtms lut info|query|export|diff: read, check, query, export and compare LUT files."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import _JSON, fail, print_json
from evtms.errors import EvtmsInputError
from evtms.paths import creating_parents, input_file, output_file

lut_app = typer.Typer(help="Read, check, query, export and compare LUT files.", no_args_is_help=True)


def _open(path: Path, **kwargs):
    """A validated LUT (see :func:`evtms.luts.open_lut`); a bad file is one line, exit 2."""
    from evtms.luts import open_lut

    return open_lut(input_file(path, "LUT file"), **kwargs)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


@lut_app.command("info")
def lut_info(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Show a LUT's component, axes, variables, invalid points and provenance.

    Reads the metadata and streams the data once for the ranges, so it stays
    fast and small on large LUTs.

    Example: evtms lut info luts/condenser.nc
    """
    from evtms.luts.summary import lut_summary

    s = lut_summary(input_file(file, "LUT file"))
    if json_out:
        print_json({"file": str(file), **s})
        return
    typer.echo(f"{file}: {s['component']} LUT, fluid {s['fluid']}, grid {s['grid']}, format v{s['format']}")
    typer.echo("axes:")
    for a in s["axes"]:
        typer.echo(
            f"  {a['name']:<8} {a['size']:>4} values  {_fmt(a['min']):>10} .. {_fmt(a['max']):<10} "
            f"[{a['units']}]  {a['long_name']}"
        )
    for name, fixed in s.get("fixed_inputs", {}).items():
        typer.echo(f"  {name:<8} fixed at {_fmt(fixed['value'])} [{fixed['units']}] (not an axis)")
    typer.echo("variables (range over valid points):")
    for v in s["variables"]:
        typer.echo(f"  {v['name']:<10} {_fmt(v['min']):>12} .. {_fmt(v['max']):<12} [{v['units']}]  {v['long_name']}")
    typer.echo(f"points: {s['points']}, valid: {s['valid']}, invalid: {s['points'] - s['valid']}")
    for c in s["status"]:
        typer.echo(f"  status {c['code']:>3} {c['meaning']:<40} {c['count']}")
    p = s["provenance"]
    typer.echo(f"provenance: evtms {p['evtms_version']}, CoolProp {p['coolprop_version']}, created {p['created']}")
    typer.echo(f"history: {p['history']}")
    typer.echo(f"environment: {json.dumps(s['environment'], sort_keys=True)}")
    typer.echo(f"parameters: {json.dumps(s['parameters'], sort_keys=True)}")


def _parse_point(text: str, names: tuple[str, ...], partial: bool = False, fixed: dict | None = None) -> dict:
    """``name=value[unit],...`` -> SI values (units as for --axis).

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
            raise EvtmsInputError(f"--at item {item!r} is not name=value")
        if name not in names and name not in fixed:
            raise EvtmsInputError(f"unknown axis {name!r} in --at; allowed: {', '.join((*names, *fixed))}")
        if name in point:
            raise EvtmsInputError(f"axis {name!r} is given twice in --at")
        x = parse_value(name, value)
        if name in fixed:
            if not math.isclose(x, fixed[name], rel_tol=1e-9, abs_tol=1e-12):
                raise EvtmsInputError(
                    f"{name} = {x:g} in --at: the LUT holds {name} fixed at {fixed[name]:g} only (not an axis)"
                )
            continue
        point[name] = x
    missing = [n for n in names if n not in point]
    if missing and not partial:
        raise EvtmsInputError(f"--at has no value for axis {missing[0]!r}; give all of {', '.join(names)}")
    return point


_MAX_QUERY_POINTS = 100_000


@lut_app.command("query")
def lut_query(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    at: Annotated[
        list[str], typer.Option("--at", help="Point as name=value,... (SI, or with a unit suffix). Repeatable.")
    ],
    var: Annotated[list[str] | None, typer.Option("--var", help="Variable(s) to report; default all.")] = None,
    out_of_range: Annotated[
        str, typer.Option("--out-of-range", help="Policy outside the grid: error, clip or nan.")
    ] = "error",
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Interpolate LUT variables at points (N-D multilinear).

    Example: evtms lut query luts/condenser.nc --at mdot=0.005,fan=0.2,p_in=1e6,T_in=340,T_res=300 --var Q
    """
    from evtms.luts import Interpolator
    from evtms.luts.validate import fixed_inputs

    if len(at) > _MAX_QUERY_POINTS:
        fail(f"{len(at)} --at points is above the limit of {_MAX_QUERY_POINTS:,}")
    if out_of_range not in ("error", "clip", "nan"):
        fail(f"--out-of-range {out_of_range!r} is not allowed; allowed: error, clip, nan")
    variables = [v.strip() for item in (var or []) for v in item.split(",") if v.strip()] or None
    if variables is not None and len(set(variables)) != len(variables):
        fail(f"--var names a variable twice: {', '.join(variables)}")
    ds = _open(file, variables=variables)
    names = tuple(ds["status"].dims)
    fixed = fixed_inputs(ds)
    itp = Interpolator.from_dataset(ds, variables, out_of_range)
    points = [_parse_point(text, names, fixed=fixed) for text in at]
    query = {n: [p[n] for p in points] for n in names}
    result = itp(query)
    if json_out:
        print_json(
            {
                "file": str(file),
                "axes": list(names),
                "fixed_inputs": fixed,
                "variables": list(itp.variables),
                "units": {n: ds[n].attrs["units"] for n in (*names, *itp.variables)},
                "points": [
                    {**{n: p[n] for n in names}, **{v: float(result[v][i]) for v in itp.variables}}
                    for i, p in enumerate(points)
                ],
            }
        )
        return
    header = [f"{n} [{ds[n].attrs['units']}]" for n in names] + [f"{v} [{ds[v].attrs['units']}]" for v in itp.variables]
    typer.echo("  ".join(header))
    for i, p in enumerate(points):
        row = [_fmt(p[n]) for n in names] + [_fmt(float(result[v][i])) for v in itp.variables]
        typer.echo("  ".join(row))


@lut_app.command("export")
def lut_export(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    fmt: Annotated[str, typer.Option("--format", "-f", help="mat (MATLAB/Simulink) or csv (long form).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Output file.")],
) -> None:
    """Export a LUT to .mat for MATLAB/Simulink or to long-form .csv.

    Length-1 axes are dropped from the .mat tables (Simulink's n-D Lookup
    Table rejects them) and recorded in lut.fixed_inputs.

    Example: evtms lut export luts/condenser.nc --format mat -o condenser.mat
    """
    from evtms.luts.export import FORMATS, to_csv, to_mat

    if fmt not in FORMATS:
        fail(f"export format {fmt!r} is not allowed; allowed: {', '.join(FORMATS)}")
    output_file(output, [file])
    ds = _open(file)
    with creating_parents(output):
        path = (to_mat if fmt == "mat" else to_csv)(ds, output)
    typer.echo(f"wrote {path}")


@lut_app.command("diff")
def lut_diff_cmd(
    a: Annotated[Path, typer.Argument(help="First LUT file.")],
    b: Annotated[Path, typer.Argument(help="Second LUT file.")],
    json_out: Annotated[bool, _JSON] = False,
) -> None:
    """Compare two LUTs: per-variable max and RMS differences, parameter and version changes.

    Example: evtms lut diff luts/condenser.nc luts/condenser_44.nc
    """
    import dataclasses

    from evtms.luts.diff import lut_diff

    d = lut_diff(_open(a), _open(b))
    if json_out:
        summary = dataclasses.asdict(d)
        changed = {**summary.pop("attributes"), **summary.pop("parameters")}
        print_json({**summary, "changes": {k: {"from": x, "to": y} for k, (x, y) in changed.items()}})
        return
    typer.echo(
        f"common grid: {' x '.join(str(n) for n in d.common_shape)} points; status differs at {d.status_changed}"
    )
    typer.echo(f"  {'variable':<10} {'max |diff|':>12} {'RMS diff':>12} {'max rel':>10}  units")
    for v in d.variables:
        typer.echo(f"  {v.name:<10} {_fmt(v.max_abs):>12} {_fmt(v.rms):>12} {_fmt(v.max_rel):>10}  {v.units}")
    if not d.parameters and not d.attributes:
        typer.echo("parameters and versions: identical")
    for key, (x, y) in {**d.attributes, **d.parameters}.items():
        typer.echo(f"  {key}: {x} -> {y}")
