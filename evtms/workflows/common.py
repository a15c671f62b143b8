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
