"""What every command shares: the error boundary, JSON printing, notes and progress bars.

Every error leaves as one ``error: ...`` line (bad input: exit 2, no traceback); a request
field a library message names (```max_points```) is shown as its option (``--max-points``);
``--json`` prints one strict JSON object; progress goes to a rich bar on stderr.
"""

from __future__ import annotations

import inspect
import json
import math
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperGroup

try:  # typer >= 0.20 carries its own copy of click
    from typer._click.exceptions import UsageError
except ImportError:  # pragma: no cover - older typer on click
    from click.exceptions import UsageError

from evtms.errors import EvtmsInputError, EvtmsInterrupted


class _EvtmsGroup(TyperGroup):
    """The root command: every error leaves as one ``error: ...`` line.

    Usage errors (a missing option, an unknown command) are one line, exit 2,
    instead of click's usage block; an :class:`EvtmsInputError` or an OS error
    (a read-only folder, a full disk, a name too long) that escapes a command
    is one line naming the path and the reason, exit 2, never a traceback.
    """

    def invoke(self, ctx):
        # Ctrl-C would end as a silent exit 130: a long job's own interrupt says what stopped and what was kept.
        try:
            return super().invoke(ctx)
        except EvtmsInterrupted as exc:
            raise typer.Exit(_error(str(exc), 130)) from None

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
            code = _error(cli_message(str(exc)))
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


#: Request fields (and the cycle's and the simulator's inputs, the keys of a request's ``inputs``)
#: whose option is not ``--`` and the name in lower case with dashes (``T_amb``: ``--t-amb``).
_OPTION_OF = {
    "fmt": "--format",
    "range_test": "--range",
    "mdot_coolant": "--coolant-flow",
    "T_coolant_in": "--t-coolant",
    "mdot_coolant_h": "--coolant-flow-h",
    "T_coolant_h_in": "--t-coolant-h",
    "Q_battery_ext": "--q-battery",
}
_FIELD = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`")


def option_of(field: str) -> str:
    """The option of a request field or input (``max_points``: ``--max-points``, ``T_amb``: ``--t-amb``)."""
    return _OPTION_OF.get(field, "--" + field.lower().replace("_", "-"))


def cli_message(message: str) -> str:
    """A library message with the request fields it names (```max_points```) as options (``--max-points``)."""
    return _FIELD.sub(lambda m: option_of(m[1]), message)


def note(message: str) -> None:
    """A workflow's note on stderr: ``note: ...``, or as it is when indented (a detail of the note before)."""
    message = cli_message(message)
    typer.echo(message if message.startswith(" ") else f"note: {message}", err=True)


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
JsonOut = Annotated[bool, _JSON]


def with_options(block: Callable, at: int = 0) -> Callable:
    """Decorator: the parameters of ``block`` become options of the command, from its ``at``-th option on.

    An option block shared by several commands is declared once, as the
    signature of ``block``; the command receives those options in its
    ``**options`` dictionary, by name.
    """
    shared = list(inspect.signature(block, eval_str=True).parameters.values())

    def decorate(command: Callable) -> Callable:
        own = [p for p in inspect.signature(command, eval_str=True).parameters.values() if p.kind is not p.VAR_KEYWORD]
        params = [*own[:at], *shared, *own[at:]]
        command.__signature__ = inspect.Signature(params)
        command.__annotations__ = {p.name: p.annotation for p in params}
        return command

    return decorate


class _ProgressBar:
    """A rich progress bar on stderr, one task per label (a bench, a cycle map).

    rich is imported with the first task shown: a quiet run (``--json``, ``--quiet``, stderr not a
    terminal) or one with nothing to report (maps cached) does not import it.
    """

    def __init__(self, quiet: bool) -> None:
        self._quiet = quiet
        self._progress = None

    def __enter__(self) -> _ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)

    def _start(self):
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        progress = Progress(
            TextColumn("{task.description:<16}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeRemainingColumn(),
            console=Console(stderr=True),
            transient=False,
        )
        progress.__enter__()
        return progress

    def task(self, name: str, total: int):
        if self._quiet:  # nothing drawn: no bar to keep
            return lambda done, total: None
        if self._progress is None:  # shown from the first task on: a request refused before any work draws nothing
            self._progress = self._start()
        task = self._progress.add_task(name, total=total, rate="")
        t0 = time.perf_counter()

        def update(done: int, total: int) -> None:
            rate = done / max(time.perf_counter() - t0, 1e-9)
            self._progress.update(task, completed=done, total=total, rate=f"{rate:,.0f} pt/s")

        return update

    def by_label(self, first: Callable[[str], None] | None = None):
        """A workflow's ``progress(done, total, label)``: one task per label (``first(label)`` as it appears)."""
        tasks = {}

        def progress(done: int, total: int, label: str) -> None:
            if label not in tasks:
                if first is not None:
                    first(label)
                tasks[label] = self.task(label, total)
            tasks[label](done, total)

        return progress

    def single(self, name: str):
        """A workflow's ``progress(done, total, message)`` shown as one task ``name``."""
        progress = self.by_label()
        return lambda done, total, message: progress(done, total, name)
