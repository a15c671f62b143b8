"""The one LUT file writer: a netCDF-4 file filled slab by slab.

:class:`LutFileWriter` knows no physics: it is given the axes, the names and
attributes of the data variables, the global attributes, the netCDF chunk
shape and the :class:`~evtms.luts.io.LutStorage`; it stores each slab as
:func:`~evtms.luts.io.variable_storage` and :func:`~evtms.luts.io.store_values`
decide and records each float variable's ``actual_range`` when it finishes.
:func:`evtms.luts.io.write_lut` writes a whole dataset as one slab;
:func:`evtms.benches.chunked.sweep_to_file` writes a sweep's chunks as they
finish.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evtms.luts.io import LutStorage, axis_storage, finite_range, store_values, variable_storage
from evtms.luts.schema import FLAG_VARIABLES


class LutFileWriter:
    """A LUT file at a temporary path, written slab by slab, then finished (or discarded).

    Used as a context manager: leaving it unfinished (an exception, or no
    :meth:`finish`) discards the file.

    Parameters
    ----------
    tmp : str or Path
        The file to write (a temporary path the caller renames, or that
        :meth:`finish` renames).
    axes : dict of str to numpy.ndarray
        The file's dimensions in order: name -> coordinate values (stored
        float64, uncompressed, without ``_FillValue``).
    names : sequence of str
        The data variables, in file order; each spans every axis (a scalar
        when there is none).
    attributes : dict of str to dict
        Attributes of each axis and data variable (without ``actual_range``,
        which the writer adds to each float variable).
    global_attributes : dict
        The file's global attributes (``fixed_inputs`` included).
    storage : LutStorage, optional
        How the float variables are stored (default: lossless).
    chunksizes : tuple of int, optional
        netCDF chunk shape of the data variables (default: the netCDF
        library's); a slab that matches it is compressed once.
    """

    def __init__(
        self,
        tmp: str | Path,
        axes: Mapping[str, np.ndarray],
        names: Sequence[str],
        attributes: Mapping[str, Mapping[str, Any]],
        global_attributes: Mapping[str, Any],
        *,
        storage: LutStorage | None = None,
        chunksizes: tuple[int, ...] | None = None,
    ) -> None:
        self.tmp = Path(tmp)
        self.axes = {name: np.asarray(values, np.float64) for name, values in axes.items()}
        self.names = list(names)
        self.attributes = attributes
        self.global_attributes = global_attributes
        self.storage = storage or LutStorage()
        self.chunksizes = chunksizes
        self.ranges: dict[str, list] = {}
        self.variables: dict[str, Any] = {}
        self.nc = None
        self.finished = False
        self._previous_cache = None

    def __enter__(self) -> LutFileWriter:
        import netCDF4

        # Each chunk is written once, so HDF5's per-variable chunk cache (netCDF's default
        # is tens of MB per variable) buys nothing and would grow memory with the grid.
        self._previous_cache = netCDF4.get_chunk_cache()
        netCDF4.set_chunk_cache(size=1 << 20, nelems=61, preemption=1.0)
        try:
            nc = self.nc = netCDF4.Dataset(self.tmp, "w", format="NETCDF4")
            for name, values in self.axes.items():
                nc.createDimension(name, len(values))
                var = nc.createVariable(name, dimensions=(name,), **axis_storage())
                var[:] = values
                var.setncatts(dict(self.attributes.get(name, {})))
            dims = tuple(self.axes)
            for name in self.names:
                kwargs = variable_storage(name, self.storage, len(dims))
                if dims and self.chunksizes is not None:
                    kwargs["chunksizes"] = tuple(self.chunksizes)
                var = nc.createVariable(name, dimensions=dims, **kwargs)
                var.setncatts(dict(self.attributes.get(name, {})))
                self.variables[name] = var
            nc.setncatts(dict(self.global_attributes))
            nc.set_auto_maskandscale(False)  # plain arrays go in; NaN already is the fill value
        except BaseException:
            self.discard()
            raise
        return self

    def write(self, index: tuple, arrays: Mapping[str, np.ndarray]) -> None:
        """Store ``arrays`` (name -> values shaped as the slab) at ``index`` of the file's variables.

        Parameters
        ----------
        index : tuple of int or slice
            Index into the file's dimensions (missing trailing ones are
            whole); ``()`` for the whole of every variable.
        arrays : dict of str to numpy.ndarray
            Values of data variables, as computed (the writer casts and rounds
            them per the storage).
        """
        index = tuple(index) + (slice(None),) * (len(self.axes) - len(index))
        for name, values in arrays.items():
            values = store_values(name, values, self.storage)
            if name not in FLAG_VARIABLES and values.dtype.kind == "f":
                lo, hi = finite_range(values)
                if lo is not None:
                    old = self.ranges.setdefault(name, [lo, hi])
                    old[:] = [min(old[0], lo), max(old[1], hi)]
            if index:
                self.variables[name][index] = values
            else:  # every input fixed: scalar variables
                self.variables[name].assignValue(np.asarray(values).reshape(()))

    def finish(self, path: str | Path | None = None) -> None:
        """Record each float variable's ``actual_range``, close the file and rename it to ``path`` (if given)."""
        for name, (lo, hi) in self.ranges.items():
            self.variables[name].setncattr("actual_range", np.array([lo, hi], dtype=self.storage.dtype))
        self.nc.close()
        self.finished = True
        self._restore_cache()
        if path is not None:
            os.replace(self.tmp, path)

    def discard(self) -> None:
        """Close the file and, unless finished, delete it; idempotent."""
        if self.nc is not None and self.nc.isopen():
            self.nc.close()
        if not self.finished:
            self.tmp.unlink(missing_ok=True)
        self._restore_cache()

    def _restore_cache(self) -> None:
        import netCDF4

        if self._previous_cache is not None:
            netCDF4.set_chunk_cache(*self._previous_cache)
            self._previous_cache = None

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.discard()
        return False
