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
components it needs.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

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
