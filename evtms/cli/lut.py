"""evtms lut info|query|export|diff: read, check, query, export and compare LUT files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from evtms.cli.common import JsonOut, print_json

lut_app = typer.Typer(help="Read, check, query, export and compare LUT files.", no_args_is_help=True)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


@lut_app.command("info")
def lut_info(
    file: Annotated[Path, typer.Argument(help="LUT file (.nc).")],
    json_out: JsonOut = False,
) -> None:
    """Show a LUT's component, axes, variables, invalid points and provenance.

    Reads the metadata and streams the data once for the ranges, so it stays
    fast and small on large LUTs.

    Example: evtms lut info luts/condenser.nc
    """
    from evtms.workflows.lut import lut_info as summary

    s = summary(file)
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
    json_out: JsonOut = False,
) -> None:
    """Interpolate LUT variables at points (N-D multilinear).

    Example: evtms lut query luts/condenser.nc --at mdot=0.005,fan=0.2,p_in=1e6,T_in=340,T_res=300 --var Q
    """
    from evtms.workflows.lut import query_lut

    q = query_lut(file, at, var, out_of_range)
    if json_out:
        print_json(
            {
                "file": str(file),
                "axes": list(q.axes),
                "fixed_inputs": q.fixed_inputs,
                "variables": list(q.variables),
                "units": q.units,
                "points": q.points,
            }
        )
        return
    typer.echo("  ".join(f"{n} [{q.units[n]}]" for n in (*q.axes, *q.variables)))
    for p in q.points:
        typer.echo("  ".join(_fmt(p[n]) for n in (*q.axes, *q.variables)))


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
    from evtms.workflows.lut import export_lut

    typer.echo(f"wrote {export_lut(file, fmt, output)}")


@lut_app.command("diff")
def lut_diff_cmd(
    a: Annotated[Path, typer.Argument(help="First LUT file.")],
    b: Annotated[Path, typer.Argument(help="Second LUT file.")],
    json_out: JsonOut = False,
) -> None:
    """Compare two LUTs: per-variable max and RMS differences, parameter and version changes.

    Example: evtms lut diff luts/condenser.nc luts/condenser_44.nc
    """
    import dataclasses

    from evtms.workflows.lut import diff_luts

    d = diff_luts(a, b)
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
