"""Input and output paths: checked before any work, created only when writing.

Every command reads its inputs through :func:`input_file` and writes through
:func:`output_file` / :func:`output_folder` and :func:`creating_parents`, so a
bad path is one :class:`~evtms.errors.EvtmsInputError` line before anything
is computed, an output is never one of the command's inputs (however the
path is spelled), and a failed command leaves no folder it created behind.
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

from evtms.errors import EvtmsInputError

#: Longest file name component most file systems accept [bytes].
NAME_MAX = 255
#: Bytes an output's name leaves for the suffixes of evtms's temporary files and folders
#: (``.name.XXXXXXXX.tmp``, ``name.partial.<pid>.<token>.new``).
TEMP_SUFFIX_BYTES = 64


def _q(path: Path | str) -> str:
    return repr(str(path))


def file_slug(text: str, default: str = "cycle") -> str:
    """``text`` (e.g. a drive cycle's name, ``parked:300`` or a trace's path) as part of a file name:
    every run of characters other than letters, digits and ``_.+-`` becomes one ``_``; ``default``
    where nothing is left."""
    import re

    return re.sub(r"[^A-Za-z0-9_.+-]+", "_", text).strip("_.") or default


def input_file(path: str | Path, what: str = "input file") -> Path:
    """``path`` if it is an existing regular file, else a one-line error.

    A FIFO, a device or a folder is refused before it is opened, so reading
    never blocks on a pipe nor streams a device.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise EvtmsInputError(f"{what} {_q(path)}: no such file") from None
    except OSError as exc:
        raise EvtmsInputError(f"{what} {_q(path)} cannot be read: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise EvtmsInputError(f"{what} {_q(path)} is a folder; give a file")
    if not stat.S_ISREG(st.st_mode):
        raise EvtmsInputError(f"{what} {_q(path)} is not a regular file (a pipe or a device); give a file")
    return path


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _check_names(path: Path) -> None:
    *folders, name = path.parts or ("",)
    for part in folders:
        if len(os.fsencode(part)) > NAME_MAX:
            raise EvtmsInputError(f"output {_q(path)}: the name {part[:40]!r}... is longer than {NAME_MAX} bytes")
    limit = NAME_MAX - TEMP_SUFFIX_BYTES
    if len(os.fsencode(name)) > limit:
        raise EvtmsInputError(
            f"output {name[:40]!r}... is a name of {len(os.fsencode(name))} bytes; allowed: at most {limit} "
            f"(the file system takes {NAME_MAX}, evtms's temporary files add up to {TEMP_SUFFIX_BYTES})"
        )


def same_path(a: str | Path, b: str | Path) -> bool:
    """True if ``a`` and ``b`` name the same file (resolving ``..``, links and hard links)."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def _check_not_input(path: Path, inputs: Iterable[str | Path]) -> None:
    for src in inputs:
        if src is not None and same_path(path, src):
            raise EvtmsInputError(
                f"output {_q(path)} is the input {_q(src)}; write to another file (the input is kept as it is)"
            )


def _check_parent(path: Path) -> None:
    parent = path.parent
    existing = _nearest_existing(parent)
    if not existing.is_dir():
        raise EvtmsInputError(f"output folder {_q(parent)} cannot be created: {_q(existing)} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        what = "output folder" if existing == parent else "folder"
        raise EvtmsInputError(f"{what} {_q(existing)} is not writable")


def output_file(path: str | Path, inputs: Iterable[str | Path] = (), suffixes: tuple[str, ...] = ()) -> Path:
    """Check an output file path before any work.

    Refuses a folder, a special file, a name too long for the file system, an
    output that is one of ``inputs``, a suffix not in ``suffixes`` (when
    given), and a parent folder that cannot be created or written. A missing
    parent folder is allowed: :func:`creating_parents` makes it when writing.
    """
    path = Path(path)
    _check_names(path)
    if path.is_dir():
        raise EvtmsInputError(f"output {_q(path)} is a folder; give a file path")
    if suffixes and path.suffix.lower() not in suffixes:
        raise EvtmsInputError(f"output {_q(path)} must end in {' or '.join(suffixes)}")
    if path.exists() and not path.is_file():
        raise EvtmsInputError(f"output {_q(path)} is not a regular file (a pipe or a device)")
    _check_not_input(path, inputs)
    _check_parent(path)
    return path


def output_folder(path: str | Path, inputs: Iterable[str | Path] = ()) -> Path:
    """Check an output folder path before any work (created by :func:`creating_parents`)."""
    path = Path(path)
    _check_names(path)
    if path.exists() and not path.is_dir():
        raise EvtmsInputError(f"output {_q(path)} is a file; give a folder for several outputs")
    _check_not_input(path, inputs)
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise EvtmsInputError(f"output folder {_q(path)} is not writable")
    else:
        _check_parent(path)
    return path


@contextlib.contextmanager
def creating_parents(path: str | Path, folder: bool = False) -> Iterator[Path]:
    """Create the missing folders of ``path`` (``path`` itself if ``folder``) for the block.

    On any exception the folders it created are removed again if they are
    still empty, so a failed command leaves no empty folder behind.
    """
    path = Path(path)
    target = path if folder else path.parent
    missing = []
    p = target
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    try:
        for d in reversed(missing):
            d.mkdir()
        yield path
    except BaseException:
        for d in missing:  # deepest first
            with contextlib.suppress(OSError):
                d.rmdir()
        raise


@contextlib.contextmanager
def staged_folder(folder: str | Path) -> Iterator[Path]:
    """Yield an empty staging folder beside ``folder``; move its files into ``folder`` on success.

    A report drawn into the staging folder appears in ``folder`` only when
    every file of it is written; on any exception the staging folder is
    removed and ``folder`` is left as it was (not created if it was missing).
    """
    import shutil
    import tempfile

    folder = Path(folder)
    with creating_parents(folder):
        try:
            stage = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
        except OSError as exc:  # name the folder asked for, not the staging folder
            raise OSError(exc.errno, exc.strerror, str(folder)) from None
    try:
        yield stage
        folder.mkdir(exist_ok=True)
        for f in sorted(stage.iterdir()):
            os.replace(f, folder / f.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def read_small_text(
    path: str | Path, what: str, max_bytes: int, expected: str, hint: str, encoding: str = "utf-8"
) -> str:
    """The text of a small input file (CSV traces, measurements), checked before it is read.

    Raises :class:`EvtmsInputError` ``"<path>: <rule>"`` when the file cannot
    be read, is not a regular file (``give <expected>``), is larger than
    ``max_bytes`` or is not text in ``encoding`` (``not UTF-8 text (<hint>)``).
    ``what`` names the file (``drive cycle``).
    """
    where = str(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise EvtmsInputError(f"{where}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise EvtmsInputError(f"{where}: not a regular file; give {expected}")
    if st.st_size > max_bytes:
        raise EvtmsInputError(f"{where}: {st.st_size:,} bytes is above the limit of {max_bytes:,} for a {what}")
    try:
        return Path(path).read_bytes().decode(encoding)
    except UnicodeDecodeError:
        raise EvtmsInputError(f"{where}: not UTF-8 text ({hint})") from None
    except OSError as exc:
        raise EvtmsInputError(f"{where}: cannot read the {what} ({exc.strerror or exc})") from None


def csv_rows(text: str) -> Iterator[tuple[int, str, list[str]]]:
    """The data lines of a small CSV text: ``(line number, stripped line, cells)``, blank and ``#`` lines skipped.

    Cells are split on commas and stripped; the caller checks the header and
    the values (each reader has its own columns and rules).
    """
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield number, line, [c.strip() for c in line.split(",")]
