"""The cycle's view of a component LUT: its checked header and interpolators built once, cached.

:func:`evtms.cycle.api.load_cycle_luts` returns one :class:`CycleLut` per
component. It reads and checks the file's header only; an interpolator the
solver asks for is built from the file's data the first time and kept in the
user's cache (:mod:`evtms.luts.cache`, memory-mapped), so a later run
neither decompresses the table nor computes its curvature columns again, and
a single operating point touches only the pages of the cells it lands in.

The WCC's tables are filled where its coolant is not below the refrigerant's
inlet temperature (:func:`not_condensing_fill`): the bench leaves those nodes
NaN, and a cycle's roots may lie inside the cells that touch them.
"""

from __future__ import annotations

import functools
import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms.cycle.approach import APPROACH, APPROACH_MIN, OUTLET, SECONDARY_INLET, SUPERHEAT_MIN, approach_log
from evtms.cycle.dome import DH_MIN, DT_MIN, SCALED, capacity_scale
from evtms.luts.cache import cached_arrays
from evtms.luts.validate import fixed_inputs, read_lut_metadata, status_flags

if TYPE_CHECKING:
    from collections.abc import Callable

    from evtms.benches.parameters import Parameters
    from evtms.fluid import SaturationCurve, VapourTable
    from evtms.luts import Interpolator
    from evtms.luts.validate import LutMetadata


#: Condensing components whose closure variables are filled at the nodes where no heat leaves the
#: refrigerant (:func:`not_condensing_fill`), by the status meanings of those nodes: the secondary
#: not below the refrigerant's inlet temperature, or (LUTs written before the WCC's bench solved
#: its desuperheating-only states) not below its saturation.
NOT_CONDENSING = {
    "wcc": ("coolant_inlet_not_colder_than_refrigerant_inlet", "coolant_inlet_not_colder_than_refrigerant_saturation")
}
#: The variables filled there.
_FILLED = ("capacity_ratio", "p_out", "Q")

#: Status meanings of a refrigerant on the wrong side of its secondary stream: the condenser's and
#: the evaporating benches' inlet, and the WCC's coolant not below the refrigerant's inlet (or, in
#: older WCC LUTs, its saturation).
_WRONG_SIDE = ("refrigerant_inlet_not_", "coolant_inlet_not_colder_than_refrigerant_")


def wrong_side_flags(flags: dict[int, str]) -> tuple[int, ...]:
    """A bench's status codes for a refrigerant on the wrong side of the secondary stream (inlet not
    warmer than the air in a condenser, saturation not warmer than the coolant in the WCC, inlet not
    colder than the air or coolant in an evaporator): no heat flows the way the circuit needs, the
    condensing side gives no liquid. The cycle's closures read them as "no heat flows", not as a
    failed point."""
    return tuple(c for c, meaning in flags.items() if meaning.startswith(_WRONG_SIDE))


def _short(recipe: dict) -> str:
    return hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()[:8]


class CycleLut:
    """One component's LUT file as the cycle uses it.

    Parameters
    ----------
    path : Path
        The LUT file (checked against the format, header only).
    component : str
        The component it must hold.
    meta : LutMetadata, optional
        The file's header, where the caller has read and checked it already.

    Attributes
    ----------
    attrs : dict
        Global attributes (``fixed_inputs`` in SI units).
    dims : tuple of str
        Axes in table order.
    axes : dict of str to numpy.ndarray
        Axis values [SI].
    encoding : dict
        ``source``: the file's path (named in reasons).
    """

    def __init__(self, path: str | Path, component: str, meta: LutMetadata | None = None) -> None:
        self.path = Path(path)
        self.component = component
        self.meta = meta if meta is not None else read_lut_metadata(self.path, component)
        self.attrs = self.meta.attrs
        self.dims = tuple(self.meta.dims)
        self.axes = self.meta.axes
        self.encoding = {"source": str(self.path)}

    def _cached(self, kind: str, recipe: dict, build) -> tuple[dict[str, np.ndarray], dict]:
        recipe = {"kind": kind, "component": self.component, **recipe}
        return cached_arrays(f"{self.component}-{kind}-{_short(recipe)}", [self.path], recipe, build)

    def interpolator(
        self,
        variables: list[str],
        curvature: tuple[str, ...],
        compiled: bool = True,
        vapour: VapourTable | None = None,
        saturation: SaturationCurve | None = None,
        window: dict[str, float] | None = None,
    ) -> Interpolator:
        """Interpolator of ``variables`` (NaN outside the axes), the ``curvature`` ones corrected;
        ``compiled=False``: on the NumPy path (see :meth:`Interpolator.from_arrays`). The variable
        :data:`~evtms.cycle.approach.APPROACH` is derived from the outlet (needs ``vapour``),
        :data:`~evtms.cycle.dome.SCALED` from the capacity ratio (needs ``saturation``).
        ``window``: the tables start at the last node at or below each value given (by axis)."""
        from evtms.luts import Interpolator

        curved = [v for v in curvature if v in variables]
        recipe = {"variables": variables, "curved": curved}
        if APPROACH in variables:
            # The derived table depends on the vapour enthalpies and the transform it was computed with.
            recipe["vapour"] = vapour.digest()
            recipe["approach"] = {"superheat_min": SUPERHEAT_MIN, "approach_min": APPROACH_MIN, "version": 1}
        if SCALED in variables:
            recipe["saturation"] = saturation.digest()
            recipe["scaled"] = {"dt_min": DT_MIN, "dh_min": DH_MIN, "version": 2}
        if self.component in NOT_CONDENSING and set(_FILLED) & set(variables):
            recipe["not_condensing_fill"] = {"variables": list(_FILLED), "version": 1}
        start = window_start(self.axes, window)
        if start:  # absent where the window keeps every node: the tables of the whole grid
            recipe["window"] = {d: float(self.axes[d][i]) for d, i in start.items()}

        def build():
            from evtms.luts import open_lut

            ds = open_lut(self.path, self.component, stored_variables(variables, self.component))
            ds = ds.isel({d: slice(i, None) for d, i in start.items()})
            return DatasetLut(ds, self.component).table_arrays(variables, tuple(curved), vapour, saturation)

        arrays, info = self._cached("itp", recipe, build)
        return Interpolator.from_arrays(arrays, info, compiled)

    def status_flags(self) -> dict[int, str]:
        """The file's status codes and their meanings (its ``flag_values`` and ``flag_meanings``)."""
        return status_flags(self.meta.variables["status"])

    def indicator(self, name: str, codes: tuple[int, ...], compiled: bool = True) -> Interpolator:
        """Interpolator of ``name``: 1 at nodes whose status is in ``codes`` (valid or not), 0 at other
        valid nodes, NaN at other invalid nodes: the share of a point's interpolation weight on nodes
        with those codes, NaN where the cell holds any other invalid node."""
        from evtms.luts import Interpolator

        def build():
            from evtms.luts import open_lut

            ds = open_lut(self.path, self.component, [])
            return DatasetLut(ds, self.component).indicator_arrays(name, codes)

        arrays, info = self._cached("flag", {"name": name, "codes": list(codes), "version": 2}, build)
        return Interpolator.from_arrays(arrays, info, compiled)

    def derived(self, name: str, recipe: dict, build) -> tuple[dict[str, np.ndarray], dict]:
        """Any arrays derived from this file (e.g. the valve's flow area), cached like the tables."""
        return self._cached(name, recipe, build)


#: Nodes per slab of the tables derived node by node (:func:`_by_slabs`), about.
_SLAB_NODES = 1 << 20


def _by_slabs(f, first: np.ndarray, *others: np.ndarray) -> np.ndarray:
    """``f`` of flattened slabs of the first axis of ``first`` and ``others`` (broadcast to its shape).

    In slabs: the table lookups hold a dozen temporaries the size of their input, and an axis's
    values are broadcast views, copied a slab at a time.
    """
    others = [np.broadcast_to(x, first.shape) for x in others]
    out = np.empty(first.shape)
    rows = max(1, _SLAB_NODES // max(first[0].size, 1))
    for i0 in range(0, len(out), rows):
        parts = (np.ascontiguousarray(x[i0 : i0 + rows]).reshape(-1) for x in (first, *others))
        out[i0 : i0 + rows] = f(*parts).reshape(out[i0 : i0 + rows].shape)
    return out


def window_start(axes: dict[str, np.ndarray], window: dict[str, float] | None) -> dict[str, int]:
    """Per axis of ``window`` that ``axes`` has, the index of its last node at or below the value
    given; only the axes where that drops nodes."""
    start = {}
    for d, value in (window or {}).items():
        if d in axes:
            i = int(np.searchsorted(axes[d], value, side="right")) - 1
            if i > 0:
                start[d] = i
    return start


class DatasetLut:
    """An in-memory LUT dataset with :class:`CycleLut`'s interface (nothing cached)."""

    def __init__(self, ds, component: str) -> None:
        self.ds = ds
        self.component = component
        self.attrs = dict(ds.attrs)
        self.dims = tuple(ds["status"].dims)
        self.axes = {d: np.asarray(ds[d].values, float) for d in self.dims}
        self.encoding = {"source": ds.encoding.get("source", component)}
        self.fixed = fixed_inputs(ds)

    def interpolator(
        self,
        variables: list[str],
        curvature: tuple[str, ...],
        compiled: bool = True,
        vapour: VapourTable | None = None,
        saturation: SaturationCurve | None = None,
        window: dict[str, float] | None = None,
    ) -> Interpolator:
        """As :meth:`CycleLut.interpolator`, built from the dataset in memory."""
        from evtms.luts import Interpolator

        start = window_start(self.axes, window)
        lut = DatasetLut(self.ds.isel({d: slice(i, None) for d, i in start.items()}), self.component) if start else self
        itp = Interpolator.from_arrays(*lut.table_arrays(variables, curvature, vapour, saturation), compiled)
        itp.compiled = itp.compiled and compiled
        return itp

    def table_arrays(
        self,
        variables: list[str],
        curvature: tuple[str, ...],
        vapour: VapourTable | None = None,
        saturation: SaturationCurve | None = None,
    ) -> tuple[dict, dict]:
        """The arrays and description of :meth:`interpolator`'s table, its rows computed as they are
        written (:meth:`evtms.luts.Interpolator.table_arrays`)."""
        from evtms.luts import Interpolator

        tables = {}
        for v in variables:
            if v == APPROACH:
                tables[v] = self._approach(vapour)
            elif v == SCALED:
                tables[v] = self._scaled(saturation)
            else:
                tables[v] = self._values(v)
        if self.component in NOT_CONDENSING:
            tables = not_condensing_fill(self.ds, self.component, self.dims, tables)
        if SCALED in variables:
            tables = self._wrong_side_fill(tables)
        axes = [(d, self.axes[d]) for d in self.dims]
        return Interpolator.table_arrays(axes, tables, "nan", curvature, self.fixed)

    def _values(self, name: str) -> np.ndarray:
        from evtms.errors import EvtmsInputError

        if name not in self.ds.data_vars:
            raise EvtmsInputError(f"variable {name!r} is not in the LUT; allowed: {', '.join(self.ds.data_vars)}")
        return self.ds[name].transpose(*self.dims).values

    def _approach(self, vapour: VapourTable) -> np.ndarray:
        """:func:`~evtms.cycle.approach.approach_log` at every node (NaN where the outlet is)."""
        h_out = self.ds[OUTLET].transpose(*self.dims).values
        p_out = self.ds["p_out"].transpose(*self.dims).values
        T_sec = np.asarray(self.secondary_inlet(), float)
        return _by_slabs(lambda h, p, T: approach_log(h, p, T, vapour), h_out, p_out, T_sec)

    def _scaled(self, saturation: SaturationCurve) -> np.ndarray:
        """The condenser's capacity ratio times :func:`~evtms.cycle.dome.capacity_scale` at every node.

        The scaled ratio tends to a finite limit where the factor's differences vanish, and the
        nodes there hold the ratio's own limits (0 at no driving difference, the models' largest
        at a liquid inlet), which would pull the interpolation of the cells beside them off. At a
        liquid inlet (less than :data:`~evtms.cycle.dome.DH_MIN` above the saturated liquid) the
        scaled ratio therefore takes the value of the nearest node up the enthalpy axis; where
        the refrigerant is barely warmer than the air (its mean saturation less than
        :data:`~evtms.cycle.dome.DT_MIN` above it) or not warmer at all (the bench's wrong-side
        status, NaN), that of the nearest node up the pressure axis.
        """
        ratio = self.ds["capacity_ratio"].transpose(*self.dims).values
        p_out = self.ds["p_out"].transpose(*self.dims).values
        p_in, h_in = (self.axes[d].reshape([-1 if e == d else 1 for e in self.dims]) for d in ("p_in", "h_in"))
        T_air = np.asarray(self.secondary_inlet(), float)
        scaled = _by_slabs(
            lambda c, p_o, p, h, T: c * capacity_scale(p, h, T, p_o, saturation), ratio, p_out, p_in, h_in, T_air
        )
        T_mean = _by_slabs(lambda p_o, p: 0.5 * (saturation.temperature(p) + saturation.temperature(p_o)), p_out, p_in)
        status = self.ds["status"].transpose(*self.dims).values
        liquid = np.broadcast_to(h_in - saturation.liquid_enthalpy(p_in) < DH_MIN, scaled.shape)
        cold = np.isin(status, wrong_side_flags(self.status_flags())) | (
            np.isfinite(scaled) & ~(T_mean - T_air >= DT_MIN)
        )
        p_axis, h_axis = self.dims.index("p_in"), self.dims.index("h_in")
        scaled = _carried(np.where(liquid | cold, np.nan, scaled), h_axis, downward=True, only=liquid)
        scaled = _carried(scaled, p_axis, downward=True, only=cold & ~liquid)
        # A cold node whose neighbours up the pressure axis are liquid: from up the enthalpy axis.
        return _carried(scaled, h_axis, downward=True, only=cold & np.isnan(scaled))

    def _wrong_side_fill(self, tables: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """A chain condenser's ``tables`` with ``capacity_ratio`` and ``p_out`` filled at the nodes
        where its refrigerant enters not warmer than the air (the bench's wrong-side status, NaN).

        Behind the WCC the condenser finishes condensing a few kelvin, or one, above the air, in
        cells that touch such nodes (the saturation or a liquid inlet below the air): left NaN,
        the outlet pressure of the whole cell is NaN, and with it the scaled ratio's factor and
        the cycle's state. There ``capacity_ratio`` takes its limit 0 (no heat flows; the scaled
        ratio, which the two-phase inlets read, is filled in :meth:`_scaled`) and ``p_out`` the
        inlet pressure times the outlet-to-inlet ratio of the nearest valid node up the pressure
        axis, else up the enthalpy axis (the drop being a few kPa).
        """
        status = self.ds["status"].transpose(*self.dims).values
        off = np.isin(status, wrong_side_flags(self.status_flags()))
        if not off.any():
            return tables
        tables = dict(tables)
        if "capacity_ratio" in tables:
            tables["capacity_ratio"] = np.where(off, 0.0, tables["capacity_ratio"])
        if "p_out" in tables:
            p_in = self.axes["p_in"].reshape([-1 if d == "p_in" else 1 for d in self.dims])
            ratio = np.where(off, np.nan, tables["p_out"] / p_in)
            ratio = _carried(ratio, self.dims.index("p_in"), downward=True, only=off)
            ratio = _carried(ratio, self.dims.index("h_in"), downward=True, only=off & np.isnan(ratio))
            tables["p_out"] = np.where(off, p_in * ratio, tables["p_out"])
        return tables

    def secondary_inlet(self) -> np.ndarray | float:
        """The secondary inlet temperature [K] at the nodes: its axis (broadcast) or the value the LUT was made at."""
        name = {**SECONDARY_INLET, "condenser": "T_air_in"}[self.component]
        if name in self.dims:
            return self.axes[name].reshape([-1 if d == name else 1 for d in self.dims])
        return values_made_at(self.attrs)[name]

    def status_flags(self) -> dict[int, str]:
        """As :meth:`CycleLut.status_flags`."""
        return status_flags(self.ds["status"].attrs)

    def indicator(self, name: str, codes: tuple[int, ...], compiled: bool = True) -> Interpolator:
        """As :meth:`CycleLut.indicator`, built from the dataset in memory."""
        from evtms.luts import Interpolator

        itp = Interpolator.from_arrays(*self.indicator_arrays(name, codes), compiled)
        itp.compiled = itp.compiled and compiled
        return itp

    def indicator_arrays(self, name: str, codes: tuple[int, ...]) -> tuple[dict, dict]:
        """The arrays and description of :meth:`indicator`'s table."""
        from evtms.luts import Interpolator

        status = self.ds["status"].transpose(*self.dims).values
        flagged = np.isin(status, codes)
        valid = np.isin(status, np.asarray(self.ds["status"].attrs["valid_flag_values"]))
        table = np.where(valid | flagged, flagged, np.nan)
        axes = [(d, self.axes[d]) for d in self.dims]
        return Interpolator.table_arrays(axes, {name: table}, "nan", False, self.fixed)

    def derived(self, name: str, recipe: dict, build) -> tuple[dict[str, np.ndarray], dict]:
        return build()


def values_made_at(attrs) -> dict[str, float | None]:
    """Inputs a LUT was computed at one value of: its fixed inputs, and for the air axes it does
    not have at all, the air boundary of its environment (``None`` where it records none)."""
    env = json.loads(attrs.get("environment", "{}"))
    return {"T_air_in": env.get("T"), "RH_air_in": env.get("RH")} | fixed_inputs(attrs)


def made_with(lut: CycleLut | DatasetLut) -> Parameters:
    """The parameters ``lut`` was made with (its ``parameters`` and ``environment``), checked; kept on ``lut``.

    The ``parameters`` attribute must hold ``fluid``, ``backend`` and the
    table of the LUT's own component only, each value known and in its range
    (:func:`evtms.benches.parameters.parameters_from_json`); the ``fluid``
    attribute must be a fluid name, the one the parameters name (if they do).

    Raises
    ------
    EvtmsInputError
        ``<file>: LUT attribute 'parameters': unknown table or key 'condenser';
        allowed: fluid, backend, [expansion_valve]`` and the like.
    """
    from evtms.benches.parameters import parameters_from_json
    from evtms.errors import EvtmsInputError
    from evtms.params import check_fluid_name

    if getattr(lut, "_made_with", None) is None:
        attrs = lut.attrs
        text = attrs.get("parameters", "{}")
        try:
            fluid = check_fluid_name(attrs.get("fluid", "R134a"))
            params = parameters_from_json(lut.component, text, attrs.get("environment"))
            named = json.loads(text).get("fluid", fluid)
            if named != fluid:
                raise EvtmsInputError(
                    f"LUT attribute 'fluid' is {fluid!r} but its 'parameters' name fluid {named!r}; allowed: one fluid"
                )
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"{lut.encoding['source']}: {exc}") from None
        lut._made_with = params
    return lut._made_with


def stored_variables(variables: list[str], component: str | None = None) -> list[str]:
    """The file's variables ``variables`` are read or derived from (of ``component``'s LUT)."""
    if component in NOT_CONDENSING and "p_out" in variables:
        variables = [*variables, "dp"]  # the drop that fills p_out (not_condensing_fill)
    if SCALED in variables:
        variables = list(dict.fromkeys([v for v in variables if v != SCALED] + ["capacity_ratio", "p_out"]))
    if APPROACH not in variables:
        return variables
    return list(dict.fromkeys([v for v in variables if v != APPROACH] + [OUTLET, "p_out"]))


def not_condensing_fill(ds, component: str, dims: tuple[str, ...], tables: dict[str, np.ndarray]) -> dict:
    """``tables`` of a condensing LUT with its closure variables filled where it condenses nothing.

    Where the secondary (the WCC's coolant) enters not below the refrigerant's inlet
    temperature, no heat leaves the refrigerant and the bench leaves the node NaN (its
    status :data:`NOT_CONDENSING`; in LUTs written before the bench solved the
    desuperheating-only states, every node whose coolant is not below the saturation).
    A cycle's roots may lie in cells that touch such nodes: left NaN, those cells would
    read as "no heat flow" (the closure's residual jumping to 1 across them) and put the
    discharge pressure on the next node above the root. There the nodes take the limits
    the bench's own outputs tend to as the coolant warms to the edge: ``capacity_ratio`` 0
    (no area condenses the refrigerant) and ``p_out`` the inlet pressure less the drop of
    the nearest valid node along the coolant-temperature axis (colder coolant; no drop
    where there is none, the drop being a few kPa). ``Q`` (from which a condensing chain's
    first component gives the second its outlet) is that node's too, 0 where there is
    none. Other variables stay NaN there.
    """
    if not set(_FILLED) & set(tables):
        return tables
    status = ds["status"].transpose(*dims).values
    codes = [c for c, m in status_flags(ds["status"].attrs).items() if m in NOT_CONDENSING[component]]
    off = np.isin(status, codes)
    if not off.any():
        return tables
    tables = dict(tables)
    if "capacity_ratio" in tables:
        tables["capacity_ratio"] = np.where(off, 0.0, tables["capacity_ratio"])
    axis = dims.index("T_coolant_in")
    if "p_out" in tables:
        dp = _carried(ds["dp"].transpose(*dims).values, axis)
        p_in = ds["p_in"].values.reshape([-1 if d == "p_in" else 1 for d in dims])
        tables["p_out"] = np.where(off, p_in - np.nan_to_num(dp, nan=0.0), tables["p_out"])
    if "Q" in tables:
        tables["Q"] = np.where(off, np.nan_to_num(_carried(tables["Q"], axis), nan=0.0), tables["Q"])
    return tables


def _carried(values: np.ndarray, axis: int, downward: bool = False, only: np.ndarray | None = None) -> np.ndarray:
    """``values`` with each NaN (of those where ``only``, if given) replaced by the nearest finite
    value below it along ``axis`` (above it, ``downward``); NaN where there is none."""
    filled = np.moveaxis(values, axis, -1).copy()
    fill = None if only is None else np.moveaxis(only, axis, -1)
    order = range(filled.shape[-1] - 2, -1, -1) if downward else range(1, filled.shape[-1])
    step = 1 if downward else -1
    for k in order:
        take = ~np.isfinite(filled[..., k]) if fill is None else fill[..., k]
        filled[..., k] = np.where(take, filled[..., k + step], filled[..., k])
    return np.moveaxis(filled, -1, axis)


def fluid_tables(luts: dict, kind: str, layout: list, build: Callable[[str, str], dict]) -> dict[str, np.ndarray]:
    """Property tables ``build(fluid, backend)`` makes for the LUTs' refrigerant.

    Cached (:mod:`evtms.luts.cache`) per fluid, backend, CoolProp version and
    ``layout`` (what else the tables depend on) when the LUTs are files: a
    cached table spares a LUT run the import of CoolProp (about 2 s). For
    in-memory datasets ``build`` is called.
    """
    component, any_lut = next(iter(luts.items()))
    name = any_lut.attrs.get("fluid", "R134a")
    backend = made_with(cycle_lut(any_lut, component)).backend
    if not any(isinstance(v, CycleLut) for v in luts.values()):
        return build(name, backend)
    from importlib.metadata import version

    recipe = {"fluid": name, "backend": backend, "coolprop": version("CoolProp"), "layout": layout}
    # One entry per recipe: the cache keeps one file per name and drops its older recipes.
    arrays, _ = cached_arrays(f"{kind}-{_short(recipe)}", [], recipe, lambda: (build(name, backend), {}))
    return arrays


def vapour_table(luts: dict) -> VapourTable:
    """The refrigerant's :class:`~evtms.fluid.VapourTable` for a LUT cycle (:func:`fluid_tables`;
    for in-memory datasets kept per process)."""
    from evtms.fluid import VapourTable

    layout = list(VapourTable.__init__.__defaults__)
    return VapourTable.from_tables(fluid_tables(luts, "vapour", layout, _vapour_tables))


@functools.lru_cache(maxsize=4)
def _vapour_tables(name: str, backend: str) -> dict[str, np.ndarray]:
    from evtms.fluid import Fluid, VapourTable

    return VapourTable(Fluid(name, backend)).tables()


def cycle_lut(lut, component: str) -> CycleLut | DatasetLut:
    """``lut`` as the cycle's view: a :class:`CycleLut` as it is, an xarray dataset wrapped."""
    return lut if isinstance(lut, CycleLut | DatasetLut) else DatasetLut(lut, component)
