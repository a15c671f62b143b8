"""What every command shares: the error boundary, JSON printing and progress bars.

Every error leaves as one ``error: ...`` line (bad input: exit 2, no traceback); ``--json``
prints one strict JSON object; progress goes to a rich bar on stderr.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import NoReturn

import typer
from typer.core import TyperGroup

try:  # typer >= 0.20 carries its own copy of click
    from typer._click.exceptions import UsageError
except ImportError:  # pragma: no cover - older typer on click
    from click.exceptions import UsageError

from evtms.errors import EvtmsInputError


class _EvtmsGroup(TyperGroup):
    """The root command: every error leaves as one ``error: ...`` line.

    Usage errors (a missing option, an unknown command) are one line, exit 2,
    instead of click's usage block; an :class:`EvtmsInputError` or an OS error
    (a read-only folder, a full disk, a name too long) that escapes a command
    is one line naming the path and the reason, exit 2, never a traceback.
    """

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        _ARGV[:] = list(sys.argv[1:] if args is None else args)
        code = 0
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            code = rv if isinstance(rv, int) else 0
        except UsageError as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # 'evtms lut' alone: the help, as click shows it
                exc.show()
                code = exc.exit_code
            else:
                code = _error(_usage_message(exc))
        except typer.Abort:
            code = _error("aborted", 130)
        except EvtmsInputError as exc:
            code = _error(str(exc))
        except OSError as exc:
            code = _error(_os_message(exc))
        except MemoryError:
            code = _error("out of memory; use a coarser grid or a smaller --chunk-points")
        if standalone_mode:
            sys.exit(code)
        return code


#: The arguments of this call (for the exact resume command after Ctrl-C).
_ARGV: list[str] = []


def _error(message: str, code: int = 2) -> int:
    typer.echo(f"error: {' '.join(str(message).split())}", err=True)
    return code


def _usage_message(exc: UsageError) -> str:
    message = exc.format_message()
    ctx = exc.ctx
    if message.startswith("No such command") and ctx is not None:
        names = [n for n in ctx.command.list_commands(ctx) if not ctx.command.get_command(ctx, n).hidden]
        message = f"{message.rstrip('.')} (allowed: {', '.join(names)})"
    where = ctx.command_path if ctx is not None else "evtms"
    return f"{message} (see '{where} --help')"


def _os_message(exc: OSError) -> str:
    path = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or type(exc).__name__
    return f"{str(path)!r}: {reason}" if path else reason


def fail(message: str) -> NoReturn:
    """Print a one-line error and exit with code 2 (bad input)."""
    raise typer.Exit(_error(message))


def _json_safe(value):
    """``value`` with NaN and infinities as null (strict JSON), numpy scalars as Python numbers."""

    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def print_json(obj) -> None:
    """One JSON object on stdout, nothing else."""
    typer.echo(json.dumps(_json_safe(obj), allow_nan=False, sort_keys=False))


_JSON = typer.Option("--json", help="Print one JSON object on stdout (SI units) instead of the text summary.")


class _ProgressBar:
    """A rich progress bar on stderr, one task per bench."""

    def __init__(self, quiet: bool) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        self._progress = Progress(
            TextColumn("{task.description:<16}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeRemainingColumn(),
            console=Console(stderr=True),
            disable=quiet,
            transient=False,
        )

    def __enter__(self) -> _ProgressBar:
        self._progress.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.__exit__(*exc)

    def task(self, name: str, total: int):
        task = self._progress.add_task(name, total=total, rate="")
        t0 = time.perf_counter()

        def update(done: int, total: int) -> None:
            rate = done / max(time.perf_counter() - t0, 1e-9)
            self._progress.update(task, completed=done, total=total, rate=f"{rate:,.0f} pt/s")

        return update
