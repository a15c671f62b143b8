"""Library messages name request fields, never command-line options; the CLI shows each field as its option.

A message of the library (an exception, a warning, a note, a status or skip
reason, a text written to a file) is read from Python and in files as much as
on the command line, so it names a request field in backticks (```max_points```)
and the CLI's error boundary shows it as its option (``--max-points``,
:func:`evtms.cli.common.cli_message`). Docstrings may explain the command line.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest
import typer

from evtms.cli import app
from evtms.cli.common import cli_message, option_of

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = ROOT / "evtms"

#: A command-line option: two dashes and a lower-case name (not ``---`` rules nor ``a--b``), or a short
#: option (``-o DIR``: a dash, a lower-case letter and a space).
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*|(?<![\w-])-[a-z](?= )")
#: A whole command quoted in a message (``'evtms bench all --grid cycle'``, or as ``<code>`` in a page): a
#: remedy to copy into a shell, as true from Python as on the command line; its options stay.
QUOTED_COMMAND = re.compile(r"'evtms [^']*'|<code>evtms [^<]*</code>")
#: Texts that may name an option, each with why (the file and the text with ``{}`` for each placeholder).
ALLOWED = {
    # The CF ``history`` attribute of a LUT records the command line that writes the file.
    ("evtms/benches/sweep.py", "evtms bench {} --grid {}"),
    # The pip command that installs scikit-learn: python's option, not one of evtms.
    (
        "evtms/surrogates/train.py",
        "surrogate training needs scikit-learn; install it with: python3 -m pip install scikit-learn",
    ),
}


def _texts(tree: ast.AST):
    """(line, text) of every string literal that is not a docstring; an f-string with ``{}`` per placeholder."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                skip.add(id(body[0].value))
        if isinstance(node, ast.JoinedStr):
            skip.update(id(inner) for inner in ast.walk(node) if inner is not node)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            yield node.lineno, node.value
        elif isinstance(node, ast.JoinedStr):
            parts = (v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
            yield node.lineno, "".join(parts)


def _library_modules():
    for path in sorted(LIBRARY.rglob("*.py")):
        if path.relative_to(LIBRARY).parts[0] != "cli":
            yield path


def test_no_library_message_names_a_command_line_option():
    found = []
    for path in _library_modules():
        rel = path.relative_to(ROOT).as_posix()
        for line, text in _texts(ast.parse(path.read_text(encoding="utf-8"))):
            if (rel, text) in ALLOWED:
                continue
            options = OPTION.findall(QUOTED_COMMAND.sub("", text))
            if options:
                found.append(f"{rel}:{line}: {', '.join(options)} in {text!r}")
    assert not found, "name the request field in backticks instead:\n" + "\n".join(found)


def test_the_allowed_texts_are_still_there():
    """An allow-list entry whose text is gone is removed with it."""
    for rel, text in ALLOWED:
        assert text in {t for _, t in _texts(ast.parse((ROOT / rel).read_text(encoding="utf-8")))}, (rel, text)


def test_the_scan_sees_raise_warn_and_fstring_texts():
    source = (
        "def f(x):\n"
        '    """Docstrings may say --anything."""\n'
        "    warn('use --old')\n"
        "    notify(f'-o {x}: exists; 1-D, -5 K')\n"
        "    raise ValueError(f'--model {x!r} is unknown; run ' \"'evtms bench all --grid cycle'\")\n"
    )
    texts = [t for _, t in _texts(ast.parse(source))]
    assert texts == [
        "use --old",
        "-o {}: exists; 1-D, -5 K",
        "--model {} is unknown; run 'evtms bench all --grid cycle'",
    ]
    assert [OPTION.findall(QUOTED_COMMAND.sub("", t)) for t in texts] == [["--old"], ["-o"], ["--model"]]


def _options(*path: str) -> set[str]:
    import click

    command = typer.main.get_command(app)
    for name in path:  # get_command: a group may make its commands when first asked (evtms bench)
        command = command.get_command(click.Context(command), name)
    return {opt for p in command.params for opt in p.opts if opt.startswith("--")}


def _requests():
    from evtms.cycle.topology import INPUTS
    from evtms.system.inputs import INPUT_NAMES
    from evtms.workflows.bench import BenchRequest
    from evtms.workflows.compare import CompareRequest
    from evtms.workflows.cycle import CycleRequest
    from evtms.workflows.simulate import SimulationRequest
    from evtms.workflows.train import TrainRequest

    # (command, request, the keys of its ``inputs`` field, fields the command sets itself, not by an option)
    return [
        (("bench", "condenser"), BenchRequest, (), {"names"}),
        (("cycle", "sweep"), CycleRequest, tuple(INPUTS), set()),
        (("simulate",), SimulationRequest, INPUT_NAMES, set()),
        (("report", "compare"), CompareRequest, (), set()),
        (("surrogate", "train"), TrainRequest, (), set()),
    ]


@pytest.mark.parametrize(("path", "request_type", "inputs", "own"), _requests(), ids=lambda v: str(v)[:20])
def test_every_request_field_a_message_names_is_shown_as_an_option_of_its_command(path, request_type, inputs, own):
    """``cli_message`` turns each field (and each key of ``inputs``) into an option the command has."""
    options = _options(*path)
    names = [f.name for f in dataclasses.fields(request_type) if f.name not in own and f.name != "inputs"]
    missing = [f"{n} -> {option_of(n)}" for n in [*names, *inputs] if option_of(n) not in options]
    assert not missing, f"evtms {' '.join(path)} has no option for: {', '.join(missing)}"


def test_cli_message_shows_fields_and_inputs_as_options():
    assert cli_message("raise it with `max_points`") == "raise it with --max-points"
    assert cli_message("`T_coolant_in`: not an input; its inputs: `T_amb`, `mdot_coolant`") == (
        "--t-coolant: not an input; its inputs: --t-amb, --coolant-flow"
    )
    assert (
        cli_message("`Q_battery_ext` 1e9 W, `SP_CoHX` 100 degC, `fmt`")
        == "--q-battery 1e9 W, --sp-cohx 100 degC, --format"
    )
    assert cli_message("write it with 'evtms bench all --grid cycle'") == "write it with 'evtms bench all --grid cycle'"
