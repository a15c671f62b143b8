"""Arrays derived from LUT files, cached beside them and rebuilt when a file changes.

A cold ``evtms cycle run`` used to spend most of its time and memory turning
the LUTs into interpolation tables (decompressing the evaporator's 2.4 million
points, computing the curvature columns) and importing CoolProp for the
saturation curve. What it derives depends only on the source files and on a
recipe (evtms version, variables, options), so it is cached:

- in the user's cache folder (``$EVTMS_CACHE_DIR``, else
  ``$XDG_CACHE_HOME/evtms``, else ``~/.cache/evtms``: :func:`evtms.luts.store.cache_root`,
  which also names the entries), never beside the LUTs:
  a LUT folder may be read-only or shared, and a command's inputs stay
  untouched; one folder per entry, ``<name>-<source>-<key>/``, with one
  ``.npy`` file per array and a ``meta.json``; ``source`` hashes the source
  files' resolved paths and ``key`` the recipe, evtms's version and each
  source file's identity (device, inode, size and modification time), so
  rewriting a LUT (or upgrading evtms) makes a new key and the stale entry of
  that file is removed, and a hard link to a file (another path, the same
  inode) finds the entry made through the first path;
- read back memory-mapped: a query touches only the pages of the cells it
  lands in, so a single operating point neither reads nor holds whole tables;
- written to a temporary folder and renamed into place, so concurrent runs
  never see half an entry (the first complete one wins, the others use it);
  a run about to build an entry another process is building waits for it
  (a lock per entry, :data:`LOCK_WAIT` at most) instead of building it too;
- skipped silently where the cache folder cannot be written: the arrays are
  then built in memory, as without a cache (``EVTMS_NO_CACHE=1`` forces that).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from evtms import __version__
from evtms._locks import file_lock
from evtms.luts.store import (
    CACHE_DIR_ENV,
    DISABLE_ENV,
    array_entries,
    array_entry,
    cache_root,
    caching,
    stale_array_entries,
)

__all__ = ["CACHE_DIR_ENV", "DISABLE_ENV", "cache_key", "cache_root", "cached_arrays", "tagged", "untagged"]

#: The longest a run waits for another process building the same entry [s]; then it builds its own
#: (a lock left by a stopped process is released with it, so this only bounds a slow builder).
LOCK_WAIT = 600.0


def cache_key(sources: Sequence[str | Path], recipe: Mapping) -> str:
    """SHA-256 (hex) of the recipe, evtms's version and each source file's identity (device, inode,
    size, modification time: not its path, so that hard links share an entry)."""
    ident = []
    for src in sources:
        st = os.stat(src)
        ident.append([st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns])
    text = json.dumps({"evtms": __version__, "recipe": recipe, "sources": ident}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _load(entry: Path) -> tuple[dict[str, np.ndarray], dict] | None:
    try:
        meta = json.loads((entry / "meta.json").read_text(encoding="utf-8"))
        arrays = {name: np.load(entry / f"{name}.npy", mmap_mode="r") for name in meta["arrays"]}
    except (OSError, ValueError, KeyError):
        return None  # damaged or removed by a concurrent cleaner: build again
    return arrays, meta.get("info", {})


def cached_arrays(
    name: str,
    sources: Sequence[str | Path],
    recipe: Mapping,
    build: Callable[[], tuple[dict[str, np.ndarray], dict]],
) -> tuple[dict[str, np.ndarray], dict]:
    """The arrays ``build()`` makes from ``sources``, from the cache when it has them.

    Parameters
    ----------
    name : str
        Entry name (letters, digits, ``_``, ``-``), e.g. ``evaporator-itp``.
    sources : sequence of path
        Files the arrays derive from.
    recipe : mapping
        Everything else they depend on (JSON-serialisable).
    build : callable
        Returns ``(arrays, info)``: named arrays and a JSON-serialisable dict. An
        array may be an object that computes itself as it is written
        (``write_npy(path)``, e.g. :class:`evtms.luts.interp.RowTable`), so that
        it is never held whole; without a cache it comes back as built.

    Returns
    -------
    (dict of str to numpy.ndarray, dict)
        The arrays (memory-mapped, read-only, when from the cache) and info.
    """
    if not caching():
        return build()
    key = cache_key(sources, recipe)
    entry = array_entry(name, sources, key)
    # This path's entry, else one made through a hard link to the same files (same key).
    got = _first_loadable([entry] if entry.is_dir() else array_entries(name, key))
    if got is not None:
        return got
    with file_lock(_lock_path(name, key), LOCK_WAIT):
        got = _first_loadable(array_entries(name, key))  # finished by another process while this one waited
        if got is not None:
            return got
        arrays, info = build()
        with contextlib.suppress(OSError):
            _store(entry, arrays, info)
            got = _load(entry)
            if got is not None:
                return got
    return arrays, info


def _first_loadable(entries: Sequence[Path]) -> tuple[dict[str, np.ndarray], dict] | None:
    """The arrays and info of the first of ``entries`` that loads whole, else None."""
    for found in entries:
        got = _load(found)
        if got is not None:
            return got
    return None


def _lock_path(name: str, key: str) -> Path:
    """The build lock of the arrays ``name`` with cache key ``key``, whatever their sources' paths."""
    return cache_root() / ".locks" / f"{name}-{key[:32]}.lock"


def _store(entry: Path, arrays: Mapping[str, np.ndarray], info: dict) -> None:
    """Write an entry atomically (temporary folder, then rename) and drop the stale ones of its sources."""
    root = entry.parent
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{entry.name[:-33]}-", dir=root))
    try:
        for key, value in arrays.items():
            if hasattr(value, "write_npy"):  # computed as it is written (evtms.luts.interp.RowTable)
                value.write_npy(tmp / f"{key}.npy")
            else:
                np.save(tmp / f"{key}.npy", np.ascontiguousarray(value), allow_pickle=False)
        meta = {"arrays": list(arrays), "info": info, "evtms": __version__}
        (tmp / "meta.json").write_text(json.dumps(meta), encoding="utf-8")
        try:
            os.rename(tmp, entry)
        except OSError:
            if not entry.is_dir():  # not a concurrent writer's finished entry: a real failure
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    for old in stale_array_entries(entry):
        shutil.rmtree(old, ignore_errors=True)
        with contextlib.suppress(OSError):  # and its lock: "<name>-<sources hash>-<key>" locks as "<name>-<key>"
            _lock_path(old.name[:-46], old.name[-32:]).unlink()


def tagged(value):
    """``value`` as JSON values, its NumPy arrays, scalars and dtypes, tuples and dicts tagged so
    that :func:`untagged` gives them back as they were (types, shapes and bits; a float's JSON
    text is its shortest repr, which reads back to the same double). For an ``info`` of
    :func:`cached_arrays` holding more than JSON's types (no pickle: the cache holds data, not code).

    Raises
    ------
    TypeError
        A value of another type.
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biufcUS":
            raise TypeError(f"an array of {value.dtype} is not cached")
        return {"__nd__": [value.dtype.str, list(value.shape), value.ravel().tolist()]}
    if isinstance(value, np.generic):
        return {"__np__": [value.dtype.str, value.item()]}
    if isinstance(value, np.dtype):
        return {"__dtype__": value.str}
    if isinstance(value, tuple):
        return {"__tuple__": [tagged(v) for v in value]}
    if isinstance(value, dict):
        return {"__dict__": [[tagged(k), tagged(v)] for k, v in value.items()]}
    if isinstance(value, list):
        return [tagged(v) for v in value]
    if value is None or isinstance(value, str | bool | int | float):
        return value
    raise TypeError(f"a {type(value).__name__} is not cached")


def untagged(value):
    """What :func:`tagged` was given."""
    if isinstance(value, list):
        return [untagged(v) for v in value]
    if not isinstance(value, dict):
        return value
    (tag, body), *rest = value.items()
    if rest:
        raise ValueError("not a tagged value")
    if tag == "__nd__":
        dtype, shape, items = body
        return np.array(items, dtype=np.dtype(dtype)).reshape(shape)
    if tag == "__np__":
        return np.dtype(body[0]).type(body[1])
    if tag == "__dtype__":
        return np.dtype(body)
    if tag == "__tuple__":
        return tuple(untagged(v) for v in body)
    if tag == "__dict__":
        return {untagged(k): untagged(v) for k, v in body}
    raise ValueError(f"unknown tag {tag!r}")
