"""N-D multilinear interpolation on LUT grids, built once and called many times.

The cycle model calls this in its inner loop, so the batched path avoids
per-point Python work: per axis, the cell index comes from arithmetic on a
uniform axis or ``searchsorted`` on a non-uniform one; the ``2^d`` corner
values are gathered from the flattened table and reduced axis by axis with
linear blends (``v0 + t (v1 - v0)``). The NumPy path runs queries in blocks
of 16,384 points so that the temporaries stay in the CPU cache. A pure-Python
path serves single points (:meth:`Interpolator.point`) without arrays.

Invalid table entries are NaN: a NaN corner that carries weight makes the
result NaN (never a silently wrong number); a corner with zero weight (a query
exactly on a node or cell face) does not.

Calls go through a compiled kernel (numba, :mod:`evtms.luts._kernels`) when
numba is importable: the cycle solver calls the interpolator about ninety
times per operating point on batches of a few points, where NumPy's per-call
overhead costs far more than the arithmetic. The kernel does the NumPy path's
arithmetic in the same order (the two agree to rounding, in practice to the
bit); the NumPy path stays as the reference and the fallback. Set the
environment variable ``EVTMS_NO_NUMBA=1`` to use the NumPy path (it is read
when an interpolator is built). A process pays for numba once: about 0.2 s to
import it when the first interpolator is built, about 0.3 s on the first call
to load the kernel's cached machine code (numba sets up its compiler then and
imports ``scipy.linalg``, except in the command line's process:
:func:`evtms._jit.lean_numba`), several seconds to compile it if there is no cache.
"""

from __future__ import annotations

import bisect
import math
import os
from collections.abc import Mapping, Sequence

import numpy as np

from evtms.errors import EvtmsInputError

POLICIES = ("error", "clip", "nan")
_BLOCK = 16384
_kernel_module = None  # evtms.luts._kernels once imported, False if numba is not importable
_NO_POINTS = np.zeros(0, bool)  # the kernel's "no point is outside already"
_FLOAT64 = np.dtype(np.float64)


def compiled_kernel():
    """The compiled interpolation kernel, or None (numba not importable, or ``EVTMS_NO_NUMBA`` set).

    Imports numba on first use only (about 0.2 s), so that importing evtms stays light.
    """
    global _kernel_module
    if os.environ.get("EVTMS_NO_NUMBA", "") not in ("", "0"):
        return None
    if _kernel_module is None:
        try:
            from evtms.luts import _kernels
        except ImportError:  # numba missing or broken: the NumPy path does the same work
            _kernel_module = False
        else:
            _kernel_module = _kernels
    return _kernel_module.interpolate if _kernel_module else None


class Interpolator:
    """Multilinear interpolator over a rectilinear grid.

    Parameters
    ----------
    axes : sequence of (str, array_like)
        Axis names and strictly increasing values, in table dimension order.
        Axes of length 1 are allowed (queries must sit on that value, or be
        clipped to it).
    tables : mapping of str to array_like
        Variable name -> array shaped like the grid.
    out_of_range : {"error", "clip", "nan"}
        Default policy for queries outside an axis' range: raise
        :class:`EvtmsInputError` naming the axis, value and range; clip to the
        range; or return NaN for those points.
    curvature : bool or sequence of str
        For all variables (True) or the named ones: add to the multilinear
        value a quadratic correction along each axis,
        from second differences of the table interpolated to the query
        (exact for functions quadratic along each axis, error third order in
        the node spacing where the table is smooth). It costs one more gathered
        column per variable and axis. Default off.
    fixed : mapping of str to float, optional
        Inputs the table was computed at a single value of (a LUT's
        ``fixed_inputs``): not axes, but a query (mapping) may name them. A
        value that differs from the fixed one (beyond 1e-9 relative) is out
        of range: the policy decides (``clip`` uses the fixed value anyway).

    Examples
    --------
    >>> itp = Interpolator.from_dataset(ds, ["Q"])          # doctest: +SKIP
    >>> itp({"mdot": [0.005], "fan": [0.2], ...})["Q"]      # doctest: +SKIP
    """

    def __init__(
        self,
        axes: Sequence[tuple[str, np.ndarray]],
        tables: Mapping[str, np.ndarray],
        out_of_range: str = "error",
        curvature: bool | Sequence[str] = False,
        fixed: Mapping[str, float] | None = None,
    ) -> None:
        _check_policy(out_of_range)
        self.names = tuple(name for name, _ in axes)
        self.fixed = {k: float(v) for k, v in (fixed or {}).items()}
        both = set(self.fixed) & set(self.names)
        if both:
            raise ValueError(f"{sorted(both)[0]} is both an axis and a fixed input")
        self.axes = [np.ascontiguousarray(values, dtype=np.float64) for _, values in axes]
        shape = tuple(len(a) for a in self.axes)
        for name, a in zip(self.names, self.axes, strict=True):
            if a.ndim != 1 or a.size == 0 or np.any(np.diff(a) <= 0) or not np.all(np.isfinite(a)):
                raise ValueError(f"axis {name} must be 1-D, finite and strictly increasing")
        self.variables = tuple(tables)
        for name, table in tables.items():
            if np.shape(table) != shape:
                raise ValueError(f"table {name} has shape {np.shape(table)}, the grid is {shape}")
        curved = list(self.variables) if curvature is True else [v for v in (curvature or ()) if v in tables]
        self.curvature = bool(curved)
        self._curved_vars = [self.variables.index(v) for v in curved]
        self._curved_axes = curved_axes(self.axes) if curved else []
        table = RowTable(self.axes, [tables[v] for v in self.variables], self._curved_vars, self._curved_axes)
        self._finish(table.materialize(), out_of_range)

    @classmethod
    def table_arrays(
        cls,
        axes: Sequence[tuple[str, np.ndarray]],
        tables: Mapping[str, np.ndarray],
        out_of_range: str = "error",
        curvature: bool | Sequence[str] = False,
        fixed: Mapping[str, float] | None = None,
    ) -> tuple[dict[str, np.ndarray | RowTable], dict]:
        """What :meth:`to_arrays` gives for ``Interpolator(axes, tables, ...)``, without building it:
        the table is a :class:`RowTable`, computed slab by slab as a cache writes it (see
        :meth:`RowTable.write_npy`), so the whole table is never held in memory."""
        names = [name for name, _ in axes]
        grid = [np.ascontiguousarray(values, dtype=np.float64) for _, values in axes]
        variables = list(tables)
        curved = variables if curvature is True else [v for v in (curvature or ()) if v in tables]
        curved_vars = [variables.index(v) for v in curved]
        on = curved_axes(grid) if curved else []
        table = RowTable(grid, [tables[v] for v in variables], curved_vars, on)
        arrays = {"values": table, **{f"axis_{j}": a for j, a in enumerate(grid)}}
        info = {
            "names": names,
            "variables": variables,
            "curved": curved,
            "curved_axes": on,
            "fixed": {k: float(v) for k, v in (fixed or {}).items()},
            "out_of_range": out_of_range,
        }
        return arrays, info

    def _finish(self, values: np.ndarray, out_of_range: str, compiled: bool = True) -> None:
        """Everything a call needs besides the table ``values`` (rows: grid points; columns:
        the variables, then the curvature columns)."""
        self._values = values
        self.out_of_range = out_of_range
        self.shape = shape = tuple(len(a) for a in self.axes)
        strides = np.cumprod((1,) + shape[::-1])[:-1][::-1]
        self._strides = [int(s) for s in strides]
        self._uniform = []
        self._buckets = []
        for a in self.axes:
            step = (a[-1] - a[0]) / (len(a) - 1) if len(a) > 1 else 1.0
            uniform = len(a) > 1 and np.allclose(np.diff(a), step, rtol=1e-12, atol=0.0)
            self._uniform.append((float(a[0]), float(step)) if uniform else None)
            self._buckets.append(None if uniform or len(a) == 1 else _bucket_index(a))
        self._prepare_kernel(compiled)
        # Pure-Python copies for the single-point path, made on its first use.
        self._axes_list: list[list[float]] | None = None
        self._values_list: list[list[float]] | None = None

    def _prepare_kernel(self, compiled: bool = True) -> None:
        """Set up the compiled path from the grid attributes (call it too where an instance skips __init__).

        ``compiled=False`` keeps this instance on the NumPy path without importing
        numba (a one-shot job of a few calls, where numba's import costs more).
        """
        self._name_set = set(self.names)
        #: True when calls go through the compiled kernel (set it False to use the NumPy path).
        self.compiled = compiled and compiled_kernel() is not None
        if not self.compiled:
            return
        # The grid as the kernel's two packed arrays, so that a call only stacks the query.
        self._floats, self._ints = _kernel_module.pack(
            self.axes, self._strides, self._uniform, self._buckets, self._curved_axes, self._curved_vars
        )
        # The table as a plain read-only array whatever it came as (a memory-mapped file is
        # read-only): numba compiles one kernel per argument type, so keep it to one.
        values = np.ascontiguousarray(self._values).view(np.ndarray)
        values.flags.writeable = False
        self._kernel_values = values

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The interpolator as named arrays and a JSON-serialisable dict (for a cache; see :meth:`from_arrays`)."""
        arrays = {"values": self._values, **{f"axis_{j}": a for j, a in enumerate(self.axes)}}
        info = {
            "names": list(self.names),
            "variables": list(self.variables),
            "curved": [self.variables[k] for k in self._curved_vars],
            "curved_axes": list(self._curved_axes),
            "fixed": self.fixed,
            "out_of_range": self.out_of_range,
        }
        return arrays, info

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], info: Mapping, compiled: bool = True) -> Interpolator:
        """The interpolator :meth:`to_arrays` described, without recomputing its table (which may
        be a read-only memory map: a query touches only the rows of its cells). ``compiled``:
        as :meth:`_prepare_kernel`."""
        itp = cls.__new__(cls)
        itp.names = tuple(info["names"])
        itp.fixed = {k: float(v) for k, v in info["fixed"].items()}
        itp.axes = [np.asarray(arrays[f"axis_{j}"], np.float64) for j in range(len(itp.names))]
        itp.variables = tuple(info["variables"])
        itp._curved_vars = [itp.variables.index(v) for v in info["curved"]]
        itp.curvature = bool(itp._curved_vars)
        itp._curved_axes = [int(j) for j in info["curved_axes"]]
        values = arrays["values"]
        if isinstance(values, RowTable):  # not cached (no cache folder): computed here
            values = values.materialize()
        ncols = len(itp.variables) + len(itp._curved_vars) * len(itp._curved_axes)
        if values.ndim != 2 or values.shape[1] != ncols or values.shape[0] != math.prod(len(a) for a in itp.axes):
            raise ValueError(f"table of shape {values.shape} does not fit the described grid")
        itp._finish(values, info["out_of_range"], compiled)
        return itp

    @property
    def inputs(self) -> tuple[str, ...]:
        """Every name a query may give: the axes, then the fixed inputs."""
        return self.names + tuple(self.fixed)

    @classmethod
    def from_dataset(
        cls,
        ds,
        variables: Sequence[str] | None = None,
        out_of_range: str = "error",
        curvature: bool | Sequence[str] = False,
    ) -> Interpolator:
        """Interpolator over the axes of an xarray LUT dataset.

        ``variables`` defaults to every float data variable (not ``status``).
        The dataset's ``fixed_inputs`` become the interpolator's ``fixed``.
        """
        from evtms.luts.validate import fixed_inputs

        dims = list(ds["status"].dims if "status" in ds.data_vars else ds[next(iter(ds.data_vars))].dims)
        if variables is None:
            variables = [v for v in ds.data_vars if v != "status" and ds[v].dtype.kind == "f"]
        tables = {}
        for v in variables:
            if v not in ds.data_vars:
                raise EvtmsInputError(f"variable {v!r} is not in the LUT; allowed: {', '.join(ds.data_vars)}")
            tables[v] = ds[v].transpose(*dims).values
        return cls([(d, ds[d].values) for d in dims], tables, out_of_range, curvature, fixed_inputs(ds))

    # ------------------------------------------------------------------
    def _prepare(self, query, policy: str) -> tuple[np.ndarray, np.ndarray]:
        """Query as an (n, d) float array, checked against the policy; returns (points, nan_mask)."""
        outside = None
        if isinstance(query, Mapping):
            unknown = set(query) - set(self.inputs)
            missing = [n for n in self.names if n not in query]
            if unknown:
                raise EvtmsInputError(
                    f"unknown axis {sorted(unknown)[0]!r} in query; allowed: {', '.join(self.inputs)}"
                )
            if missing:
                raise EvtmsInputError(
                    f"query has no value for axis {missing[0]!r}; give all of {', '.join(self.names)}"
                )
            given = [n for n in self.fixed if n in query]
            names = [*self.names, *given]
            cols = np.broadcast_arrays(*[np.asarray(query[n], np.float64).reshape(-1) for n in names])
            if self.names:
                pts = np.stack(cols[: len(self.names)], axis=1)
            else:  # every input fixed: one value per query point (one point if none is given)
                pts = np.zeros((len(cols[0]) if cols else 1, 0))
            for n, col in zip(given, cols[len(self.names) :], strict=True):
                bad = self._fixed_off(n, col, policy)
                if bad is not None:
                    outside = bad if outside is None else outside | bad
        else:
            pts = np.asarray(query, np.float64)
            if pts.ndim == 1:
                pts = pts[None, :]
            if pts.shape[1] != len(self.names):
                raise EvtmsInputError(f"query has {pts.shape[1]} columns; the LUT has axes {', '.join(self.names)}")
        outside = np.zeros(len(pts), bool) if outside is None else outside
        for j, (name, a) in enumerate(zip(self.names, self.axes, strict=True)):
            col = pts[:, j]
            bad = ~((col >= a[0]) & (col <= a[-1]))  # NaN queries count as outside
            if not bad.any():
                continue
            if policy == "error":
                v = col[np.argmax(bad)]
                raise EvtmsInputError(_outside_message(name, v, a[0], a[-1]))
            if policy == "clip":
                if pts is query:
                    pts = pts.copy()
                pts[:, j] = np.clip(np.nan_to_num(col, nan=a[0]), a[0], a[-1])
            else:
                outside |= bad
        return pts, outside

    def __call__(self, query, out_of_range: str | None = None) -> dict[str, np.ndarray]:
        """Interpolate every variable at many points.

        Parameters
        ----------
        query : mapping of str to array_like, or array_like of shape (n, d)
            Axis values (SI, same units as the LUT), broadcast together.
        out_of_range : {"error", "clip", "nan"}, optional
            Overrides the interpolator's default policy for this call.

        Returns
        -------
        dict of str to numpy.ndarray
            One 1-D array of n values per variable.
        """
        policy = self.out_of_range if out_of_range is None else out_of_range
        _check_policy(policy)
        if self.compiled:
            return self._call_compiled(query, policy)
        return self._call_numpy(query, policy)

    def _call_numpy(self, query, policy: str) -> dict[str, np.ndarray]:
        """The NumPy path: the reference for the compiled one, and its fallback."""
        pts, outside = self._prepare(query, policy)
        n = len(pts)
        result = np.empty((n, len(self.variables)))
        for start in range(0, n, _BLOCK):
            stop = min(start + _BLOCK, n)
            result[start:stop] = self._block(pts[start:stop])
        result[outside] = np.nan
        return {v: result[:, k] for k, v in enumerate(self.variables)}

    def _call_compiled(self, query, policy: str) -> dict[str, np.ndarray]:
        """The compiled path: the query as contiguous (d, n) rows, then one kernel call.

        Written for the cycle solver's many small calls: a query naming exactly the
        axes, with equal-length float arrays, costs a few microseconds on top of the
        kernel; anything else takes the general (slower) checks.
        """
        outside = _NO_POINTS
        if isinstance(query, Mapping):
            names = self.names
            given: list[str] = []
            if query.keys() != self._name_set:
                unknown = set(query) - set(self.inputs)
                missing = [n for n in names if n not in query]
                if unknown:
                    raise EvtmsInputError(
                        f"unknown axis {sorted(unknown)[0]!r} in query; allowed: {', '.join(self.inputs)}"
                    )
                if missing:
                    raise EvtmsInputError(f"query has no value for axis {missing[0]!r}; give all of {', '.join(names)}")
                given = [n for n in self.fixed if n in query]
            cols = []
            for name in names:
                c = query[name]
                if not (type(c) is np.ndarray and c.dtype is _FLOAT64 and c.ndim == 1):
                    c = np.asarray(c, np.float64).reshape(-1)
                cols.append(c)
            for name in given:
                cols.append(np.asarray(query[name], np.float64).reshape(-1))
            n = cols[0].size if cols else 1  # every input fixed and none given: one point
            same = True
            for c in cols:
                if c.size != n:  # broadcast: every size 1 or n (else NumPy raises the NumPy path's error)
                    n = np.broadcast_arrays(*cols)[0].size
                    same = False
                    break
            if not names:
                pts = np.empty((0, n))
            elif same:
                pts = np.array(cols[: len(names)])
            else:
                pts = np.empty((len(names), n))
                for j in range(len(names)):
                    pts[j] = cols[j]
            for name, col in zip(given, cols[len(names) :], strict=True):
                bad = self._fixed_off(name, np.broadcast_to(col, (n,)), policy)
                if bad is not None:
                    outside = bad if outside is _NO_POINTS else outside | bad
        else:
            rows = np.asarray(query, np.float64)
            if rows.ndim == 1:
                rows = rows[None, :]
            if rows.ndim != 2 or rows.shape[1] != len(self.names):
                return self._call_numpy(query, policy)  # the NumPy path words the error
            pts = np.ascontiguousarray(rows.T)
            n = rows.shape[0]
        out = np.empty((len(self.variables), n))
        code = _kernel_module.interpolate(
            pts, _kernel_module.POLICY_CODES[policy], outside, self._floats, self._ints, self._kernel_values, out
        )
        if code >= 0:  # the 'error' policy: the first axis with a point outside, and its first such point
            j, p = divmod(code, n)
            a = self.axes[j]
            raise EvtmsInputError(_outside_message(self.names[j], pts[j, p], a[0], a[-1]))
        return {v: out[k] for k, v in enumerate(self.variables)}

    def _fixed_off(self, name: str, col: np.ndarray, policy: str) -> np.ndarray | None:
        """Points where fixed input ``name`` is off its value (None if none, or the policy is 'clip')."""
        v = self.fixed[name]
        bad = ~(np.abs(col - v) <= 1e-9 * max(abs(v), 1.0))  # NaN queries count as off
        if not bad.any() or policy == "clip":
            return None
        if policy == "error":
            raise EvtmsInputError(
                f"{name} = {col[np.argmax(bad)]:g} differs from the LUT's fixed input {name} = {v:g} "
                "(it is not an axis); the out-of-range policy is 'error' (use 'clip' or 'nan' to allow it)"
            )
        return bad

    def _block(self, pts: np.ndarray) -> np.ndarray:
        # NaN queries (the 'nan' policy) get NaN results later; keep their index arithmetic finite.
        pts = np.where(np.isfinite(pts), pts, np.array([a[0] for a in self.axes]))
        m = len(pts)
        base = np.zeros(m, np.intp)
        fractions = []
        bows = {}  # (x - x_i)(x - x_i+1) / 2 per curved axis
        offsets = [0]
        for j, a in enumerate(self.axes):
            x = pts[:, j]
            if len(a) == 1:
                continue  # a single node: no cell, no weight to spread
            uni = self._uniform[j]
            if uni is not None:
                i = np.floor((x - uni[0]) / uni[1]).astype(np.intp)
                np.clip(i, 0, len(a) - 2, out=i)
            else:
                # Buckets narrower than the smallest cell hold at most one node: the
                # bucket's first cell, moved on by one where x lies past that node.
                b0, width, first = self._buckets[j]
                k = ((x - b0) / width).astype(np.intp)
                np.clip(k, 0, len(first) - 1, out=k)
                i = first[k]
                i += x >= a[i + 1]
                np.clip(i, 0, len(a) - 2, out=i)
            lo = a[i]
            width = a[i + 1] - lo
            t = (x - lo) / width
            if j in self._curved_axes:
                bows[j] = 0.5 * t * (t - 1.0) * width * width
            base += i * self._strides[j]
            fractions.append(t)
            offsets = offsets + [o + self._strides[j] for o in offsets]
        # Gather the 2^d corners in one call, then blend halves along the last axis first.
        corners = np.take(self._values, base[None, :] + np.asarray(offsets, np.intp)[:, None], axis=0)
        for t in reversed(fractions):
            half = corners.shape[0] // 2
            corners = _blend(corners[:half], corners[half:], t[None, :, None])
        out = corners[0]
        if not self._curved_axes:
            return out
        # Quadratic correction along each axis: the local second derivative, itself
        # interpolated, times (x - x_i)(x - x_i+1)/2; none where it is unknown (NaN).
        nv, nc = len(self.variables), len(self._curved_vars)
        value = out[:, :nv].copy()
        for k, j in enumerate(self._curved_axes):
            d2 = out[:, nv + nc * k : nv + nc * (k + 1)]
            value[:, self._curved_vars] += np.where(np.isfinite(d2), d2 * bows[j][:, None], 0.0)
        return value

    # ------------------------------------------------------------------
    def point(self, *values: float, out_of_range: str | None = None) -> tuple[float, ...]:
        """Interpolate all variables at one point given as floats in axis order.

        Pure Python, no array allocation (about 20 us a call; with numba, a
        one-point batch through :meth:`__call__` takes about 5 us).
        Returns one float per variable, in :attr:`variables` order. With
        ``curvature`` it goes through the batched path (same numbers).
        """
        policy = self.out_of_range if out_of_range is None else out_of_range
        if self.curvature:
            res = self(np.asarray(values, float)[None, :], out_of_range=policy)
            return tuple(float(res[v][0]) for v in self.variables)
        if len(values) != len(self.names):
            raise EvtmsInputError(f"point needs {len(self.names)} values ({', '.join(self.names)})")
        if self._axes_list is None:
            self._axes_list = [a.tolist() for a in self.axes]
            self._values_list = self._values.tolist()
        index = 0
        weights = [(0, 1.0)]
        for j, x in enumerate(values):
            a = self._axes_list[j]
            if not (a[0] <= x <= a[-1]):
                if policy == "error":
                    raise EvtmsInputError(_outside_message(self.names[j], x, a[0], a[-1]))
                if policy == "nan" or math.isnan(x):
                    return tuple(math.nan for _ in self.variables)
                x = min(max(x, a[0]), a[-1])
            if len(a) == 1:
                continue
            i = min(max(bisect.bisect_right(a, x) - 1, 0), len(a) - 2)
            t = (x - a[i]) / (a[i + 1] - a[i])
            stride = self._strides[j]
            index += i * stride
            if t == 0.0:
                continue
            if t == 1.0:
                index += stride
                continue
            weights = [(o, w * (1.0 - t)) for o, w in weights] + [(o + stride, w * t) for o, w in weights]
        vals = self._values_list
        out = [0.0] * len(self.variables)  # the first columns are the variables themselves
        for o, w in weights:
            row = vals[index + o]
            for k in range(len(out)):
                out[k] += w * row[k]
        return tuple(out)


def curved_axes(axes: Sequence[np.ndarray]) -> list[int]:
    """The axes a curvature correction runs along: those of three nodes or more."""
    return [j for j, a in enumerate(axes) if len(a) >= 3]


#: Rows of a :class:`RowTable` block, about: 2^18 rows of 8 columns is 16 MB.
_TABLE_BLOCK_ROWS = 1 << 18


class RowTable:
    """An interpolation table computed on demand, in slabs of its first axis.

    One row per grid point (C order), one column per variable, then the
    second derivatives along each curved axis (a column per axis and curved
    variable, :func:`second_difference`). The rows of a slab of the first
    axis need only that slab of the variables (and one node either side of
    it for the derivative along the first axis), so a slab at a time is
    computed and written: the table, the largest array of a cycle run's
    set-up (580 MB for the cycle-grid evaporator), is never held whole.
    Every value is the same arithmetic on the same operands whatever the slab.

    Parameters
    ----------
    axes : sequence of numpy.ndarray
        Axis values [SI], in table dimension order.
    tables : sequence of array_like
        One array per variable, shaped like the grid.
    curved_vars : sequence of int
        Indices of the variables with curvature columns.
    curved_axes : sequence of int
        Axes those columns run along (each of three nodes or more).
    """

    def __init__(self, axes, tables, curved_vars, curved_axes) -> None:
        self.axes = list(axes)
        self.tables = [np.asarray(t) for t in tables]
        self.curved_vars = list(curved_vars)
        self.curved_axes = list(curved_axes)
        grid = tuple(len(a) for a in self.axes)
        ncols = len(self.tables) + len(self.curved_vars) * len(self.curved_axes)
        self.shape = (math.prod(grid), ncols)
        self.dtype = np.dtype(np.float64)
        self._grid = grid

    def blocks(self):
        """The table's rows in order, as (rows, columns) arrays of whole slabs of the first axis."""
        if not self._grid:
            yield np.array([[float(np.asarray(t)) for t in self.tables]]).reshape(1, -1)
            return
        rest = math.prod(self._grid[1:])
        step = max(1, _TABLE_BLOCK_ROWS // max(rest, 1))
        for i0 in range(0, self._grid[0], step):
            yield self._slab(i0, min(i0 + step, self._grid[0]))

    def _slab(self, i0: int, i1: int) -> np.ndarray:
        block = np.empty(((i1 - i0) * math.prod(self._grid[1:]), self.shape[1]))
        for k, t in enumerate(self.tables):
            block[:, k] = np.asarray(t[i0:i1], np.float64).reshape(-1)
        k = len(self.tables)
        for j in self.curved_axes:
            for v in self.curved_vars:
                block[:, k] = second_difference(self.tables[v], self.axes[j], j, i0, i1).reshape(-1)
                k += 1
        return block

    def materialize(self) -> np.ndarray:
        """The whole table in memory."""
        out = np.empty(self.shape)
        row = 0
        for block in self.blocks():
            out[row : row + len(block)] = block
            row += len(block)
        return out

    def write_npy(self, path) -> None:
        """Write the table as a ``.npy`` file, block by block (what :mod:`evtms.luts.cache` calls)."""
        with open(path, "wb") as fh:
            header = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": self.shape}
            np.lib.format.write_array_header_1_0(fh, header)
            for block in self.blocks():
                fh.write(np.ascontiguousarray(block).data)


def second_difference(table, axis: np.ndarray, j: int, i0: int = 0, i1: int | None = None) -> np.ndarray:
    """d2f/dx2 along dimension ``j`` at the nodes ``i0:i1`` of the first dimension (3-point divided difference).

    Interior nodes use their two neighbours on a non-uniform axis; the end
    nodes take their neighbour's value. NaN wherever a point used is NaN.

    Parameters
    ----------
    table : array_like
        Values on the grid.
    axis : numpy.ndarray
        The nodes of dimension ``j`` [its units]; three or more.
    j : int
        Dimension of the derivative.
    i0, i1 : int
        Slab of the first dimension to return (default all of it).
    """
    n0 = np.shape(table)[0]
    i1 = n0 if i1 is None else i1
    h = np.diff(axis)
    if j == 0:
        # Each node's difference is centred on it, clamped to the interior at the ends.
        centre = np.clip(np.arange(i0, i1), 1, n0 - 2)
        lo, hi = int(centre[0]) - 1, int(centre[-1]) + 2
        f = np.asarray(table[lo:hi], np.float64)
        c = centre - lo
        shape = (-1,) + (1,) * (f.ndim - 1)
        h0, h1 = h[centre - 1].reshape(shape), h[centre].reshape(shape)
        return 2.0 * ((f[c + 1] - f[c]) / h1 - (f[c] - f[c - 1]) / h0) / (h0 + h1)
    f = np.moveaxis(np.asarray(table[i0:i1], np.float64), j, 0)
    shape = (-1,) + (1,) * (f.ndim - 1)
    h0, h1 = h[:-1].reshape(shape), h[1:].reshape(shape)
    d2 = 2.0 * ((f[2:] - f[1:-1]) / h1 - (f[1:-1] - f[:-2]) / h0) / (h0 + h1)
    full = np.concatenate([d2[:1], d2, d2[-1:]], axis=0)
    return np.moveaxis(full, 0, j)


def _bucket_index(a: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(start, width, first cell index per bucket) of uniform buckets over a non-uniform axis."""
    count = int(min(np.ceil((a[-1] - a[0]) / np.diff(a).min()) * 2 + 1, 1 << 20))
    width = (a[-1] - a[0]) / count
    starts = a[0] + width * np.arange(count)
    first = np.clip(np.searchsorted(a, starts, side="right") - 1, 0, len(a) - 2).astype(np.intp)
    return float(a[0]), float(width), first


def _blend(c0: np.ndarray, c1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """c0 + t (c1 - c0), where a NaN corner of zero weight does not poison the result."""
    out = c1 - c0
    out *= t
    out += c0
    # t == 0 exactly: the result is c0 even if c1 is NaN; t == 1: c1 even if c0 is NaN.
    if np.isnan(out).any():
        on_lo = (t == 0.0) & np.isnan(out)
        out = np.where(on_lo, c0, out)
        on_hi = (t == 1.0) & np.isnan(out)
        out = np.where(on_hi, c1, out)
    return out


def _outside_message(name: str, value: float, lo: float, hi: float) -> str:
    return (
        f"{name} = {value:g} is outside the LUT range [{lo:g}, {hi:g}]; "
        "the out-of-range policy is 'error' (use 'clip' or 'nan' to allow it)"
    )


def _check_policy(policy: str) -> None:
    if policy not in POLICIES:
        raise EvtmsInputError(f"out-of-range policy {policy!r} is not allowed; allowed: {', '.join(POLICIES)}")
