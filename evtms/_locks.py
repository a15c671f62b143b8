"""An exclusive lock between processes on a file, waited for a bounded time."""

from __future__ import annotations

import contextlib
import os
import time


@contextlib.contextmanager
def file_lock(path: str | os.PathLike, wait: float):
    """Hold an exclusive POSIX lock on ``path`` (made, with its folder, if missing) while the block runs.

    Another process holding it is waited for ``wait`` seconds at most; then the block runs without
    it (a stopped process releases its locks, so this only bounds a slow holder). Where POSIX
    locks or the file are not to be had (Windows, a read-only folder), the block runs unlocked.
    The lock file stays: removing it would let a later process lock another file of that name.
    """
    try:
        import fcntl

        os.makedirs(os.path.dirname(os.fspath(path)) or ".", exist_ok=True)
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
    except (ImportError, OSError):
        yield
        return
    try:
        deadline = time.monotonic() + wait
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.05)
        yield
    finally:
        os.close(fd)  # releases the lock
