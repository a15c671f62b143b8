"""One LUT folder: where its files sit, when a file made from them is stale, and the cache.

This module is the only code that knows how LUT files are laid out on disk::

    <folder>/<component>.nc                  a component's LUT ('evtms bench all --grid G -o <folder>')
    <folder>/maps/<name>.nc                  a map built from the folder's LUTs, cached beside them
    <cache>/maps/<folder hash>/<name>.nc     the same map where <folder> cannot be written
    <cache>/<name>-<sources hash>-<key>/     arrays derived from LUT files (:mod:`evtms.luts.cache`)
    <out>/luts/<grid>/                       the LUT folder of grid G that 'evtms demo -o <out>' writes

``<cache>`` is :func:`cache_root`. Where a command asks for the LUT folder of
a grid, a user may give that folder, the demo's ``<out>/luts`` or ``<out>``
itself (:meth:`LutStore.places`). A :class:`LutStore` names the files of one
folder; it knows no physics and no component: the caller says which
components it needs, and a map's builder is handed in (:meth:`LutStore.load_maps`).

A map is current when its file carries the key of what it is made from: the
builder's recipe (its format, settings and axes) and the signature of the
LUT files it reads (name, size, modification time), so a rewritten or
touched LUT, other settings or another map format rebuild it; so does an
unreadable file, or one that is no valid map LUT: never silently old.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from evtms.luts.io import MapTable

T = TypeVar("T")

#: Environment variable naming the cache folder.
CACHE_DIR_ENV = "EVTMS_CACHE_DIR"
#: Set to 1 to neither read nor write any cache (derived arrays and maps are built in memory).
DISABLE_ENV = "EVTMS_NO_CACHE"
#: The suffix of every LUT and map file.
SUFFIX = ".nc"
#: The folder beside the LUTs that holds the maps built from them (also under :func:`cache_root`).
MAPS_FOLDER = "maps"
#: The folder of an 'evtms demo' output folder that holds its LUT folders, one per grid.
DEMO_LUTS_FOLDER = "luts"
#: Global attribute of a map file: the cache key it was built for (:meth:`LutStore.map_key`).
KEY_ATTR = "map_key"


def cache_root() -> Path:
    """The cache folder: ``$EVTMS_CACHE_DIR``, ``$XDG_CACHE_HOME/evtms`` or ``~/.cache/evtms``."""
    if os.environ.get(CACHE_DIR_ENV):
        return Path(os.environ[CACHE_DIR_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "evtms"


def caching() -> bool:
    """False when ``EVTMS_NO_CACHE=1``: no cache file is read or written."""
    return os.environ.get(DISABLE_ENV) != "1"


def _digest(text: str, length: int) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:length]


def array_entry(name: str, sources: Iterable[str | Path], key: str) -> Path:
    """The cache folder of the arrays ``name`` derived from ``sources`` with cache key ``key`` (hex).

    ``<cache>/<name>-<sources hash>-<key[:32]>``: the sources hash is over
    their resolved paths, so each set of files has its own entries.
    """
    where = _digest("\n".join(str(Path(p).resolve()) for p in sources), 12)
    return cache_root() / f"{name}-{where}-{key[:32]}"


def array_entries(name: str, key: str) -> list[Path]:
    """Every cache folder of arrays ``name`` with cache key ``key``, whatever their sources' paths."""
    return sorted(cache_root().glob(f"{name}-*-{key[:32]}"))


def stale_array_entries(entry: Path) -> list[Path]:
    """The cache folders of the same arrays and sources as ``entry`` (from :func:`array_entry`) but another key."""
    prefix = entry.name[:-33]  # without "-<key[:32]>"
    stale = re.compile(rf"{re.escape(prefix)}-[0-9a-f]{{32}}")
    if not entry.parent.is_dir():
        return []
    return [old for old in entry.parent.iterdir() if old != entry and stale.fullmatch(old.name) and old.is_dir()]


@dataclass(frozen=True)
class LutStore:
    """The files of one LUT folder: the component LUTs in it and the maps built from them.

    Parameters
    ----------
    folder : str or Path
        The folder holding the LUTs (it need not exist yet).
    """

    folder: Path

    def __post_init__(self) -> None:
        object.__setattr__(self, "folder", Path(self.folder))

    # ---- where the files are -------------------------------------------------------------------
    def lut(self, component: str) -> Path:
        """The LUT file of ``component``: ``<folder>/<component>.nc``."""
        return self.folder / f"{component}{SUFFIX}"

    def luts(self, components: Iterable[str]) -> dict[str, Path]:
        """The LUT file of each of ``components``, in their order."""
        return {c: self.lut(c) for c in components}

    @property
    def maps_folder(self) -> Path:
        """``<folder>/maps``: where the maps built from the folder's LUTs are cached."""
        return self.folder / MAPS_FOLDER

    def map_file(self, name: str) -> Path:
        """The map ``name`` cached beside the LUTs: ``<folder>/maps/<name>.nc``."""
        return self.maps_folder / f"{name}{SUFFIX}"

    def map_fallback(self, name: str) -> Path:
        """The map ``name`` in the user cache, for a folder that cannot be written.

        ``<cache>/maps/<folder hash>/<name>.nc``, the hash over the folder's resolved path.
        """
        return cache_root() / MAPS_FOLDER / _digest(str(self.folder.resolve()), 16) / f"{name}{SUFFIX}"

    def map_places(self, name: str) -> tuple[Path, Path]:
        """Where map ``name`` is looked for and written, in that order: beside the LUTs, then the user cache."""
        return self.map_file(name), self.map_fallback(name)

    def files(self) -> list[Path]:
        """The files of the folder a command reads: its LUT files, then its cached maps (each sorted)."""
        return sorted(self.folder.glob(f"*{SUFFIX}")) + sorted(self.maps_folder.glob(f"*{SUFFIX}"))

    @classmethod
    def containing(cls, path: str | Path) -> LutStore:
        """The store whose folder holds the LUT file ``path``."""
        return cls(Path(path).parent)

    @classmethod
    def demo(cls, out: str | Path, grid: str) -> LutStore:
        """The LUT folder of ``grid`` that 'evtms demo -o ``out``' writes: ``<out>/luts/<grid>``."""
        return cls(Path(out) / DEMO_LUTS_FOLDER / grid)

    @staticmethod
    def places(folder: str | Path, grid: str) -> tuple[Path, Path, Path]:
        """Where the LUT folder of ``grid`` may be for a folder a user gives, in the order looked at.

        ``folder`` itself ('evtms bench all --grid G -o folder'), ``folder/<grid>``
        (``folder`` is the demo's ``luts/``) and ``folder/luts/<grid>``
        (``folder`` is the demo's output folder).
        """
        folder = Path(folder)
        return folder, folder / grid, LutStore.demo(folder, grid).folder

    # ---- staleness -------------------------------------------------------------------------------
    def signature(self, components: Iterable[str]) -> dict[str, dict]:
        """Each component's LUT file as a file made from it records it: name, size and mtime_ns.

        A file made from the LUTs (a map) is stale when the signature it
        records differs from this one: a LUT rewritten, touched or replaced.

        Raises
        ------
        OSError
            A LUT file is missing or cannot be read.
        """
        out = {}
        for c, path in self.luts(components).items():
            st = os.stat(path)
            out[c] = {"file": path.name, "size": st.st_size, "mtime_ns": st.st_mtime_ns}
        return out

    def map_key(self, recipe: Mapping[str, Any], components: Iterable[str]) -> tuple[str, dict]:
        """The cache key of a map made by ``recipe`` from the LUTs of ``components``, and its provenance.

        Parameters
        ----------
        recipe : mapping
            Everything besides the LUT files the map depends on (JSON-serialisable):
            its format version, settings, axes, ...
        components : iterable of str
            The components whose LUTs in this folder the map is made from.

        Returns
        -------
        (str, dict)
            SHA-256 (hex) of the provenance, and the provenance: ``recipe`` with
            ``lut_files`` (:meth:`signature`).

        Raises
        ------
        OSError
            A LUT file is missing or cannot be read.
        """
        provenance = {**recipe, "lut_files": self.signature(components)}
        key = hashlib.sha256(json.dumps(provenance, sort_keys=True).encode()).hexdigest()
        return key, provenance

    # ---- maps: the cache and building on demand ----------------------------------------------------
    def load_maps(
        self,
        keys: Mapping[str, str],
        build: Callable[[Sequence[str]], Mapping[str, MapTable]],
        convert: Callable[[MapTable], T] = lambda table: table,
        read: Callable[[Path, str], T] | None = None,
    ) -> dict[str, T]:
        """The maps named in ``keys``, each read from the first of its :meth:`map_places` that holds it, else built.

        A file is taken when it is a valid map LUT carrying the map's key
        (global attribute :data:`KEY_ATTR`) and ``convert`` accepts it; any
        other (stale, damaged, of another format) is rebuilt. The maps to
        build are built by one call of ``build``, get their key and are
        written atomically to the first of their places that can be written
        (none: kept in memory only), so a concurrent run never reads a
        partial file (the last writer wins). ``EVTMS_NO_CACHE=1`` neither
        reads nor writes any file.

        Parameters
        ----------
        keys : mapping of str to str
            Map name -> its cache key (:meth:`map_key`), in the order wanted.
        build : callable
            ``build(names)`` -> map name -> :class:`~evtms.luts.io.MapTable`, for the maps to build.
        convert : callable, optional
            Turns a map table into what the caller uses; raises ValueError,
            KeyError or TypeError for a file it cannot use (rebuilt then).
        read : callable, optional
            ``read(path, key)``: what ``convert`` makes of the map file ``path``
            carrying ``key``, raising as the default does (``convert`` of
            :func:`~evtms.luts.validate.read_map_lut` with the key expected),
            e.g. through a cache of its arrays.

        Returns
        -------
        dict of str to the result of ``convert``
            In the order of ``keys``.
        """
        from evtms.errors import EvtmsInputError
        from evtms.luts.validate import read_map_lut

        use_files = caching()
        if read is None:

            def read(path: Path, key: str) -> T:
                return convert(read_map_lut(path, {KEY_ATTR: key}))

        maps: dict[str, T] = {}
        for name, key in keys.items():
            for path in self.map_places(name) if use_files else ():
                if not path.is_file():
                    continue
                try:
                    maps[name] = read(path, key)
                    break
                except (EvtmsInputError, OSError, ValueError, KeyError, TypeError):
                    continue  # stale, damaged or of another format: the next place, else rebuild
        stale = [name for name in keys if name not in maps]
        if stale:
            built = build(stale)
            for name in stale:
                table = built[name]
                table.attrs[KEY_ATTR] = keys[name]
                if use_files:
                    self._save(table, self.map_places(name))
                maps[name] = convert(table)
        return {name: maps[name] for name in keys}

    @staticmethod
    def _save(table: MapTable, places: Sequence[Path]) -> Path | None:
        """Write ``table`` to the first of ``places`` that can be written; None if none can."""
        from evtms.luts.io import write_map_lut

        for path in places:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                return write_map_lut(table, path)
            except (OSError, RuntimeError):
                continue
        return None
