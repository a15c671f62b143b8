"""The partial folder of a chunked sweep (``<output>.partial``): an unfinished sweep's state.

It holds an ownership marker (``evtms-partial.json``: a folder of that name
without it, a file or a symbolic link is never deleted nor reused), the
exclusive lock of the sweep that runs (``lock.json`` plus an ``flock``), the
manifest of the sweep's inputs, the token that tells a worker it sees the
folder, the finished chunks (one ``.npy`` each, with its SHA-256 beside it,
checked on resume) and the LUT file being written (``lut.nc.tmp``).
:func:`evtms.benches.chunked.sweep_to_file` uses it.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import io
import json
import os
import shutil
import socket
import time
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

try:
    import fcntl
except ImportError:  # not POSIX: the lock file and the pid check alone
    fcntl = None

import numpy as np

from evtms import __version__
from evtms.errors import EvtmsInputError

if TYPE_CHECKING:
    from evtms.benches.base import Bench
    from evtms.benches.chunked import ChunkPlan
    from evtms.benches.parameters import Parameters

#: File of the partial folder holding the running sweep's token (see :func:`sees_folder`).
TOKEN = "token"


def one_line(exc: BaseException) -> str:
    """An exception as one short line (its type when it has no message)."""
    text = " ".join(str(exc).split())
    return text[:200] if text else type(exc).__name__


def sees_folder(folder: str, token: str | None) -> bool:
    """True if this process sees ``folder`` as the main process does (its token file matches).

    Checked again before every save (one small read): a task that outlives
    its sweep (a dask task cannot be stopped mid-run) must not write into the
    folder once a later sweep has taken it over with a token of its own. A
    folder not seen is remembered as such.
    """
    unseen = sees_folder.__dict__.setdefault("unseen", set())
    key = (folder, token)
    if token is None or key in unseen:
        return False
    try:
        seen = (Path(folder) / TOKEN).read_text() == token
    except OSError:
        seen = False
    if not seen:
        unseen.add(key)
    return seen


def sweep_manifest(bench: Bench, grid: dict, params: Parameters, grid_name: str, plan: ChunkPlan) -> dict:
    from evtms.fluid import coolprop_version

    manifest = {
        "bench": bench.name,
        "grid_name": grid_name,
        "axes": {k: [float(x) for x in v] for k, v in grid.items()},
        "parameters": json.loads(params.component_json(bench.name)),
        "environment": json.loads(params.environment_json()),
        "evtms_version": __version__,
        "coolprop_version": coolprop_version(),
        "chunks": {"lead": plan.lead, "rows": plan.rows, "checksum": "sha256"},
    }
    return json.loads(json.dumps(manifest))  # as it reads back from disk (tuples become lists)


def chunk_file(folder: Path, k: int) -> Path:
    return folder / f"chunk_{k:06d}.npy"


def _checksum_file(folder: Path, k: int) -> Path:
    return folder / f"chunk_{k:06d}.sha256"


def write_atomically(path: Path, data: bytes | memoryview) -> None:
    """Write ``data`` to ``path`` through a temporary file of this process, renamed over it."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def save_chunk(folder: Path, k: int, arrays: dict[str, np.ndarray]) -> None:
    """Save chunk ``k`` atomically as one (variables, points) float64 array, in ``arrays``' order.

    One plain ``.npy`` per chunk: loading it parses one header (an ``.npz`` parses
    a zip directory and a header per variable, which the main process would pay
    for every chunk). The int8 status is exact in float64. The SHA-256 of the
    file's bytes goes beside it first (``chunk_k.sha256``), so a chunk file
    always has the checksum ``resume`` checks it against.
    """
    stacked = np.stack([np.asarray(a, np.float64) for a in arrays.values()])
    buffer = io.BytesIO()
    np.save(buffer, stacked)
    data = buffer.getbuffer()
    write_atomically(_checksum_file(folder, k), hashlib.sha256(data).hexdigest().encode())
    write_atomically(chunk_file(folder, k), data)


def done_chunks(folder: Path, plan: ChunkPlan, names: list[str]) -> tuple[set[int], int]:
    """Chunks of an interrupted sweep that are whole, and how many saved ones are not.

    A chunk is whole when its bytes match its saved SHA-256 and it holds
    ``names`` over the chunk's points; any other saved chunk (flipped bits, a
    truncated file, a missing checksum) is counted as damaged and recomputed.
    """
    done, damaged = set(), 0
    for f in folder.glob("chunk_*.npy"):
        try:
            k = int(f.stem.split("_")[1])
        except (IndexError, ValueError):
            continue
        if not 0 <= k < plan.count:
            continue
        try:
            data = f.read_bytes()
            expected = _checksum_file(folder, k).read_text().strip()
            whole = hashlib.sha256(data).hexdigest() == expected
            whole = whole and np.load(io.BytesIO(data), mmap_mode=None).shape == (len(names), plan.size(k))
        except (OSError, ValueError, UnicodeDecodeError):
            whole = False
        if whole:
            done.add(k)
        else:
            damaged += 1
    return done, damaged


def saved_chunks(folder: Path) -> int:
    """Chunk files in ``folder`` (0 if it is gone)."""
    try:
        return sum(1 for _ in folder.glob("chunk_*.npy"))
    except OSError:
        return 0


# --- Ownership marker and exclusive lock -------------------------------------------------------

MARKER = "evtms-partial.json"
MAGIC = "evtms chunked sweep state (a partial LUT): evtms may delete this folder"
LOCK = "lock.json"
#: Own entries of a partial folder that a fresh (not resumed) sweep clears.
_STATE = ("manifest.json", TOKEN, "lut.nc.tmp", "chunk_*.npy", "chunk_*.sha256", ".chunk_*")
#: Seconds to sort out a lock that is changing hands before giving up.
LOCK_SETTLE_SECONDS = 5.0


def _lock_record() -> dict:
    now = time.time()
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": now,
        "started_at": datetime.datetime.fromtimestamp(now).astimezone().isoformat(timespec="seconds"),
    }


def _describe(record: dict | None) -> str:
    if not record:
        return "pid unknown (its lock file is unreadable)"
    return f"pid {record.get('pid')} on host {record.get('host')}, started {record.get('started_at')}"


def read_record(path: Path) -> dict | None:
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return record if isinstance(record, dict) else None


def _flock(fd: int) -> bool | None:
    """Try an exclusive ``flock`` on ``fd``: True taken, False held elsewhere, None unsupported here."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # a file system without flock (some network mounts)
        return None
    return True


def _same_file(fd: int, path: Path) -> bool:
    try:
        st = os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    own = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)


def _pid_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    except (OSError, OverflowError):
        return False
    return True


def _process_started(pid: int) -> float | None:
    """Start time (epoch seconds) of process ``pid`` from /proc, or None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        ticks = int(stat[stat.rindex(")") + 2 :].split()[19])
        boot = next(
            float(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines() if line.startswith("btime")
        )
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def _stale(record: dict | None) -> str | None:
    """Why the lock of ``record`` (whose flock nobody holds) is stale, or None if its sweep may run."""
    if record is None:
        return "its lock file is unreadable"
    if record.get("host") != socket.gethostname():
        return None  # no way to check a process on another machine
    pid, started = record.get("pid"), record.get("started")
    if not isinstance(pid, int) or not isinstance(started, (int, float)):
        return "its lock file is unreadable"
    if pid == os.getpid():
        return "this process left it behind"
    if not _pid_running(pid):
        return f"process {pid} is not running"
    began = _process_started(pid)
    if began is not None and began > started + 2.0:
        return f"process {pid} is not running (that pid is now a later process)"
    return None


class _Lock:
    """An exclusive lock on a partial folder: ``lock.json`` (our record) held with ``flock``."""

    def __init__(self, fd: int, path: Path) -> None:
        self.fd, self.path = fd, path

    def release(self) -> None:
        """Remove the lock file (if it is still ours) and drop the flock; idempotent."""
        if self.fd < 0:
            return
        if _same_file(self.fd, self.path):
            self.path.unlink(missing_ok=True)
        os.close(self.fd)
        self.fd = -1


def _new_lock(path: Path, replace: bool = False) -> _Lock | None:
    """Create lock file ``path`` with our record, already flocked; None if it exists (and not ``replace``).

    The record is written to a temporary file that is then linked (or, to take
    over, renamed) to ``path``: the lock file appears whole and held, never
    empty.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    try:
        _flock(fd)  # a new inode nobody else knows: always ours
        os.write(fd, json.dumps(_lock_record()).encode())
        os.fsync(fd)
        if replace:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                os.close(fd)
                return None
    except BaseException:
        with contextlib.suppress(OSError):
            os.close(fd)
        raise
    finally:
        tmp.unlink(missing_ok=True)
    return _Lock(fd, path)


def _check_owned(partial: Path) -> None:
    """Raise unless ``partial`` is a real folder with evtms's ownership marker."""
    hint = "move it away (evtms never deletes nor reuses it)"
    if partial.is_symlink():
        raise EvtmsInputError(f"{str(partial)!r} is a symbolic link, not a partial sweep of evtms; {hint}")
    if not partial.is_dir():
        raise EvtmsInputError(f"{str(partial)!r} is a file, not a partial sweep of evtms; {hint}")
    marker = read_record(partial / MARKER)
    if marker is None or marker.get("magic") != MAGIC or (partial / MARKER).is_symlink():
        raise EvtmsInputError(f"{str(partial)!r} exists but is not a partial sweep of evtms (no {MARKER}); {hint}")


def _create_partial(partial: Path) -> _Lock | None:
    """Create ``partial`` with its marker and our lock in one rename; None if it appeared meanwhile."""
    staging = partial.with_name(f".{partial.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.new")
    staging.mkdir()
    lock = None
    try:
        marker = {"magic": MAGIC, "created": _lock_record()}
        (staging / MARKER).write_text(json.dumps(marker))
        lock = _new_lock(staging / LOCK)
        if lock is None or os.path.lexists(partial):
            raise FileExistsError(partial)
        # Atomic: the folder appears with its marker and held lock, or not at
        # all (a non-empty folder of that name makes the rename fail).
        os.rename(staging, partial)
        lock.path = partial / LOCK
        return lock
    except (FileExistsError, OSError) as exc:
        if lock is not None:
            os.close(lock.fd)
        shutil.rmtree(staging, ignore_errors=True)
        if isinstance(exc, FileExistsError) or os.path.lexists(partial):
            return None
        raise
    except BaseException:
        if lock is not None:
            os.close(lock.fd)
        shutil.rmtree(staging, ignore_errors=True)
        raise


def lock_partial(partial: Path, output: Path) -> tuple[_Lock, list[str]]:
    """Take the exclusive lock on ``partial``, creating it (race-free) when missing.

    Returns
    -------
    lock : _Lock
        Held; release it (or remove the folder) on every exit path.
    notes : list of str
        A line if a stale lock was taken over.

    Raises
    ------
    EvtmsInputError
        ``partial`` is not evtms's, or another sweep to ``output`` runs.
    """
    running = f"another sweep to {str(output)!r} is running"
    deadline = time.monotonic() + LOCK_SETTLE_SECONDS
    while True:
        if not os.path.lexists(partial):
            lock = _create_partial(partial)
            if lock is not None:
                return lock, []
            continue  # another sweep created it first: lock it like any existing one
        _check_owned(partial)
        path = partial / LOCK
        try:
            lock = _new_lock(path)
        except FileNotFoundError:  # the folder went away (a sweep finished)
            continue
        if lock is not None:
            return lock, []
        try:
            fd = os.open(path, os.O_RDWR | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:  # released meanwhile
            continue
        except OSError as exc:
            raise EvtmsInputError(f"{str(path)!r} cannot be opened as a lock ({one_line(exc)}); move it away") from None
        settling = time.monotonic() < deadline
        held = _flock(fd)
        if not _same_file(fd, path):  # replaced or removed while we opened it
            os.close(fd)
            continue
        record = read_record(path)
        reason = _stale(record)
        if held is False:
            os.close(fd)
            # A dead owner's record, yet the flock is held: another sweep is taking it over right now.
            if reason is not None and settling and (record or {}).get("pid") != os.getpid():
                time.sleep(0.05)
                continue
            raise EvtmsInputError(f"{running} ({_describe(record)}); wait for it to end or choose another output")
        if reason is None:
            os.close(fd)
            raise EvtmsInputError(f"{running} ({_describe(record)}); if it is not, delete {str(path)!r} and run again")
        try:
            lock = _new_lock(path, replace=True)  # a whole new record while we hold the old flock
        finally:
            os.close(fd)
        return lock, [f"took over the lock of an earlier sweep to {str(output)!r} ({_describe(record)}): {reason}"]


def remove_partial(partial: Path, lock: _Lock) -> None:
    """Delete the locked partial folder: renamed away first (still locked), then removed."""
    trash = partial.with_name(f".{partial.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.done")
    try:
        os.rename(partial, trash)
    except OSError:
        lock.release()
        return
    lock.path = trash / LOCK
    shutil.rmtree(trash, ignore_errors=True)
    lock.release()


def clear_state(partial: Path) -> None:
    """Delete a fresh sweep's leftovers of an earlier one (our files only; marker and lock stay)."""
    for pattern in _STATE:
        for f in partial.glob(pattern):
            if f.is_file() or f.is_symlink():
                f.unlink(missing_ok=True)
