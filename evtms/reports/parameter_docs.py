"""The parameter tables of ``docs/system-parameters.md``, drawn from the declarations.

Each system parameter is declared once, beside its default, with its range,
units and source (:func:`evtms.params.param`, the tables of
:mod:`evtms.system.params`); the document's tables are generated from those
declarations between the markers ``<!-- parameters: [table] -->`` and
``<!-- end parameters -->`` and the prose around them is kept. The tests
check the document against :func:`render`; ``python3 -m
evtms.reports.parameter_docs FILE`` rewrites it.
"""

from __future__ import annotations

import dataclasses
import re
import sys
from pathlib import Path

from evtms.params import Range
from evtms.params import _number as number_text
from evtms.system.params import SECTIONS, parameter_fields

_BLOCK = re.compile(r"<!-- parameters: \[(\w+)\] -->\n.*?<!-- end parameters -->", re.S)


def _number(value: object) -> str:
    """A default or bound as the table shows it: numbers as the parameter messages write them."""
    if value is None:
        return "unset"
    if isinstance(value, str):
        return f"`{value}`"
    return number_text(value)


def _allowed(f: dataclasses.Field) -> str:
    choices = f.metadata.get("choices")
    if choices is not None:
        return ", ".join(f"`{c}`" for c in choices)
    rng: Range = f.metadata["range"]
    lo = "<" if rng.lo_open else "<="
    hi = "<" if rng.hi_open else "<="
    whole = ", whole" if rng.whole else ""
    return f"{_number(rng.lo)} {lo} x {hi} {_number(rng.hi)}{whole}"


def parameter_table(section: str) -> str:
    """The Markdown table of table ``section``: name, default, units, allowed values and source, one row each."""
    rows = ["| name | default | units | allowed | source |", "|---|---|---|---|---|"]
    for f in parameter_fields(section):
        units = f.metadata["units"]
        source = f.metadata["source"].replace("|", "\\|")
        rows.append(f"| `{f.name}` | {_number(f.default)} | {units} | {_allowed(f)} | {source} |")
    return "\n".join(rows)


def render(text: str) -> str:
    """``text`` (the document) with every generated block replaced by the current declarations."""

    def block(match: re.Match) -> str:
        section = match.group(1)
        if section not in SECTIONS:
            raise ValueError(f"docs block names table [{section}]; allowed: {', '.join(SECTIONS)}")
        return f"<!-- parameters: [{section}] -->\n{parameter_table(section)}\n<!-- end parameters -->"

    return _BLOCK.sub(block, text)


def documented_sections(text: str) -> list[str]:
    """The tables ``text`` has a generated block for, in order."""
    return [m.group(1) for m in _BLOCK.finditer(text)]


if __name__ == "__main__":  # pragma: no cover - the maintainer's rewrite of the document
    path = Path(sys.argv[1])
    path.write_text(render(path.read_text(encoding="utf-8")), encoding="utf-8")
