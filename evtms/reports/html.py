"""Self-contained HTML pages: figures beside the page, tables inline, no server needed."""

from __future__ import annotations

import html
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from evtms.luts.io import atomic_output
from evtms.luts.summary import lut_summary

if TYPE_CHECKING:
    import xarray as xr

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; font-size: 0.9em; }
figure { display: inline-block; margin: 0.5em; }
figure img { max-width: 520px; border: 1px solid #eee; }
figcaption { font-size: 0.85em; color: #555; }
pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 0.8em; }
"""


def _page(title: str, body: str) -> str:
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head>\n"
        f"<body>\n<h1>{html.escape(title)}</h1>\n{body}\n</body></html>\n"
    )


def _table(rows: Sequence[Sequence[object]], header: Sequence[str]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _rel(path: Path, folder: Path) -> str:
    return Path(os.path.relpath(path, folder)).as_posix()


def write_page(path: str | Path, title: str, body: str) -> Path:
    """Write an HTML page atomically."""
    path = Path(path)
    with atomic_output(path) as tmp:
        tmp.write_text(_page(title, body), encoding="utf-8")
    return path


def bench_report_page(ds: xr.Dataset, figures: list[tuple[str, Path]], path: str | Path, source: str) -> Path:
    """``index.html`` for one LUT: provenance, invalid points by status, and the figures."""
    path = Path(path)
    s = lut_summary(ds)
    prov = s["provenance"]
    body = [
        f"<p>LUT file: <code>{html.escape(source)}</code></p>",
        "<h2>Provenance</h2>",
        _table(
            [
                ("component", s["component"]),
                ("fluid", s["fluid"]),
                ("grid", s["grid"]),
                ("LUT format", s["format"]),
                ("evtms", prov["evtms_version"]),
                ("CoolProp", prov["coolprop_version"]),
                ("created", prov["created"]),
                ("history", prov["history"]),
            ],
            ("attribute", "value"),
        ),
        "<h2>Axes</h2>",
        _table(
            [(a["name"], a["size"], a["min"], a["max"], a["units"]) for a in s["axes"]],
            ("axis", "values", "min", "max", "units"),
        ),
        "<h2>Points by status</h2>",
        _table([(c["code"], c["meaning"], c["count"]) for c in s["status"]], ("code", "meaning", "points")),
        f"<p>{s['valid']} valid of {s['points']} points.</p>",
        "<h2>Figures</h2>",
    ]
    for caption, fig in figures:
        rel = _rel(fig, path.parent)
        body.append(
            f'<figure><a href="{rel}"><img src="{rel}" alt="{html.escape(caption)}"></a>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
    body.append("<h2>Parameters and environment</h2>")
    inputs = {"parameters": s["parameters"], "environment": s["environment"]}
    body.append(f"<pre>{html.escape(json.dumps(inputs, indent=1))}</pre>")
    return write_page(path, f"evtms {s['component']} bench report", "\n".join(body))


def referenced_files(page: str | Path) -> list[Path]:
    """Local files an HTML page links to (href and src), resolved beside it."""
    import re

    page = Path(page)
    text = page.read_text(encoding="utf-8")
    refs = re.findall(r'(?:href|src)="([^"#:]+)"', text)
    return [(page.parent / r).resolve() for r in refs]
