"""Steady cycle maps: the refrigerant loop's outputs on a grid of its commands and boundaries (spec 2.5).

The time loop cannot afford the cycle solver per step (milliseconds a point),
so the steady cycle is solved once on a grid per circuit and read back by a
multilinear kernel. A map holds, at every node, the nine outputs
:data:`MAP_OUTPUTS`::

    p_suction, p_discharge [Pa], mdot [kg/s],
    Q_evaporator, Q_latent, Q_chiller, Q_condenser, W, W_fluid [W]

- ``Q_evaporator`` = -``Q_evap`` of the cycle (> 0 when cooling; total,
  latent included); ``Q_latent`` its latent part, clipped into
  [0, ``Q_evaporator``] (the LUTs give a few watts of the wrong sign near a
  dry coil); ``Q_chiller`` = -``Q_chiller`` of the cycle (> 0 from coolant to
  refrigerant); a branch a circuit lacks has 0 in its slots.
- ``W`` is the shaft power, ``W_fluid`` = mdot (h_B - h_A).
- ``Q_condenser`` is stored as ``Q_evaporator + Q_chiller + W_fluid``, the
  refrigerant's energy balance: it differs from the condenser's own heat
  flow ``mdot (h_B - h_C)`` only by the cycle's balance residual (the
  superheat closure tolerance, at most about 1e-5 of ``W_fluid`` on the
  'cycle' LUTs; attribute ``balance_relative_max``), and so every node closes
  to round-off. :func:`map_interp` uses the same weights for every output, so
  interpolated values close as well.

The maps (:data:`MAPS`): ``ac`` (cabin evaporator) over (speed, fan, blower,
T_amb, T_air_in, RH_air_in), ``chiller`` over (speed, fan, u_pump, T_amb,
T_coolant_in) and ``ac+chiller`` (both branches, one compressor) over
(speed, fan, blower, u_pump, T_amb, T_air_in, T_coolant_in) at RH_air_in 0.5.
``fan`` is the condenser's air flow as a fraction of the fan's full flow
(fan and ram air together, spec v2 5.4), the condenser LUT's air axis. The
inputs become cycle operating points as: RH_amb,
superheat and subcooling from :class:`MapSettings`, T_cabin = T_air_in,
RH_cabin = RH_air_in, mdot_coolant = u_pump ``coolant_flow_max``
``coolant_density``.

Invalid nodes (a cycle status outside
:data:`~evtms.cycle.solver.VALID_CYCLE_FLAGS`, or a non-finite output) are
filled at build time by copying the whole output vector of a donor node, so
a filled node closes too. The donor is searched axis by axis:

1. along speed (same other inputs): the nearest valid node at lower speed,
   else the nearest valid node at higher speed;
2. where a whole speed line is invalid: the nearest valid node along T_amb
   (nearest in kelvin, the lower one on a tie), taking the nodes filled in
   step 1 as valid;
3. then along each remaining axis in the map's order (fan, blower, u_pump,
   T_air_in, RH_air_in, T_coolant_in as the map has them), the same way.

A map without any valid node is an error. The filled nodes are counted
(``CycleMap.filled``, file attribute ``filled``) and marked (variable
``filled``).

A map is a LUT of a circuit: it is written and read by the LUT layer
(:func:`evtms.luts.io.write_map_lut`, :func:`evtms.luts.validate.read_map_lut`;
``docs/lut-format.md``) and kept by the LUT folder's
:class:`~evtms.luts.store.LutStore`, which caches it beside the LUTs and
rebuilds it when stale (see :func:`load_maps`). In Python a map interpolates
through the LUT layer's :class:`~evtms.luts.interp.Interpolator`
(:meth:`CycleMap.interp`); the time loop calls :data:`map_interp`, its
compiled twin (the same multilinear weights, summed corner by corner rather
than blended axis by axis: equal to rounding, checked by the tests).
"""

from __future__ import annotations

import datetime as dt
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms import __version__
from evtms._jit import jit, kernel_array
from evtms.errors import EvtmsInputError, EvtmsInterrupted

if TYPE_CHECKING:
    from evtms.luts.io import MapTable

#: The outputs of every map, in slot order.
MAP_OUTPUTS = (
    "p_suction",
    "p_discharge",
    "mdot",
    "Q_evaporator",
    "Q_latent",
    "Q_chiller",
    "Q_condenser",
    "W",
    "W_fluid",
)

#: Output -> (units, long_name).
OUTPUT_ATTRS = {
    "p_suction": ("Pa", "compressor suction pressure (state A)"),
    "p_discharge": ("Pa", "compressor discharge pressure (state B)"),
    "mdot": ("kg s-1", "refrigerant mass flow rate through the compressor"),
    "Q_evaporator": ("W", "heat taken from the cabin air by the evaporator, latent included (> 0 cooling)"),
    "Q_latent": ("W", "latent part of Q_evaporator (condensate), 0 <= Q_latent <= Q_evaporator"),
    "Q_chiller": ("W", "heat taken from the coolant by the chiller (> 0 cooling)"),
    "Q_condenser": ("W", "heat given to the ambient air by the condenser, Q_evaporator + Q_chiller + W_fluid"),
    "W": ("W", "compressor shaft power"),
    "W_fluid": ("W", "power given to the refrigerant, mdot (h_B - h_A)"),
}

#: Map axis -> (units, long_name).
AXIS_ATTRS = {
    "speed": ("1", "compressor speed, fraction of maximum"),
    "fan": ("1", "condenser air flow (fan and ram air), fraction of the fan's full flow"),
    "blower": ("1", "evaporator blower fraction"),
    "u_pump": ("1", "coolant pump command, fraction of coolant_flow_max"),
    "T_amb": ("K", "ambient air temperature at the condenser"),
    "T_air_in": ("K", "air temperature entering the evaporator"),
    "RH_air_in": ("1", "relative humidity of the air entering the evaporator"),
    "T_coolant_in": ("K", "coolant temperature entering the chiller"),
    "u_H": ("1", "heater-core loop pump command, fraction of heating_flow_max"),
    "T_H": ("K", "heater-core loop coolant entering the water-cooled condenser"),
    "u_E": ("1", "e-drive loop pump command, fraction of edrive_flow_max"),
    "T_E": ("K", "e-drive loop coolant entering the chiller"),
}

#: Map axis -> the cycle operating input it sets (u_pump sets mdot_coolant through the settings).
AXIS_INPUTS = {
    "speed": "speed",
    "fan": "fan",
    "blower": "blower",
    "u_pump": "mdot_coolant",
    "T_amb": "T_amb",
    "T_air_in": "T_cabin",
    "RH_air_in": "RH_cabin",
    "T_coolant_in": "T_coolant_in",
    "u_H": "mdot_coolant_h",
    "T_H": "T_coolant_h_in",
    "u_E": "mdot_coolant",
    "T_E": "T_coolant_in",
}
#: Pump-command axes -> (the flow setting at command 1, the density setting): mass flow = command x both.
PUMP_AXES = {
    "u_pump": ("coolant_flow_max", "coolant_density"),
    "u_H": ("heating_flow_max", "coolant_density"),
    "u_E": ("edrive_flow_max", "coolant_density"),
}

#: Bump when the build rule or the file layout changes: cached maps of another format are rebuilt.
#: 3: map LUTs written and read by the LUT layer (evtms.luts.io.write_map_lut, lut_kind "map").
#: 4: nodes solved by each map's closure (MapSpec.closure; the same values to round-off).
MAP_FORMAT = 4


@dataclass(frozen=True)
class MapSpec:
    """What a map is: its circuit, its axes and the inputs it holds fixed.

    Attributes
    ----------
    topology : str
        Circuit (:data:`evtms.cycle.topology.TOPOLOGIES`).
    axes : tuple of str
        Map axes in table order (names of :data:`AXIS_ATTRS`).
    fixed : tuple of (str, float)
        Map inputs held at one value [SI], e.g. ``(("RH_air_in", 0.5),)``.
    description : str
        One line for file attributes.
    closure : {"compiled", "python"}
        The closure its nodes are solved with (:class:`~evtms.cycle.solver.CycleSolver`), the
        faster for them; both agree to round-off, and a map is always solved with the same one.
    """

    topology: str
    axes: tuple[str, ...]
    fixed: tuple[tuple[str, float], ...] = ()
    description: str = ""
    closure: str = "compiled"


#: The maps the simulator reads.
MAPS: dict[str, MapSpec] = {
    "ac": MapSpec(
        "cabin", ("speed", "fan", "blower", "T_amb", "T_air_in", "RH_air_in"), (), "cabin evaporator alone (modes CC)"
    ),
    "chiller": MapSpec("chiller", ("speed", "fan", "u_pump", "T_amb", "T_coolant_in"), (), "chiller alone (mode BC)"),
    "ac+chiller": MapSpec(
        "cabin+chiller",
        ("speed", "fan", "blower", "u_pump", "T_amb", "T_air_in", "T_coolant_in"),
        (("RH_air_in", 0.5),),
        "cabin evaporator and chiller in parallel (mode CC+BC)",
    ),
    "hp": MapSpec(
        "hp",
        ("speed", "u_H", "T_H", "u_E", "T_E"),
        (),
        "heat pump: the water-cooled condenser heats the heater-core loop, the chiller draws on the e-drive loop",
        # An eighth of its nodes lie outside the models' envelope: the kernel hands each back to the
        # Python path, which solves it again to say why (139 us a node against 80 vectorised).
        closure="python",
    ),
}


def _celsius(start: float, stop: float, step: float) -> tuple[float, ...]:
    """Temperatures [K] from ``start`` to ``stop`` degC every ``step`` K (rounded to 10 decimals)."""
    n = int(round((stop - start) / step)) + 1
    return tuple(round(273.15 + start + i * step, 10) for i in range(n))


_FRACTIONS = (0.1, 0.2, 0.35, 0.5, 0.75, 1.0)

#: Default axes (spec 2.5) [SI]; None: the evaporator LUT's RH_air_in axis (read from its file). The fan
#: axis (spec v2 5.4) spans the staged fan's lowest flow with ram air (V_a 0.19 m3/s) to the fan's full flow
#: (0.88 m3/s, the end of the condenser LUT's air axis); ram air beyond that is not credited.
DEFAULT_AXES: dict[str, tuple[float, ...] | None] = {
    "speed": _FRACTIONS,
    "fan": (0.22, 0.6, 1.0),
    "blower": _FRACTIONS,
    "u_pump": (0.3, 0.5, 1.0),
    "T_amb": _celsius(-10.0, 50.0, 5.0),
    "T_air_in": _celsius(10.0, 50.0, 4.0),
    "RH_air_in": None,
    "T_coolant_in": _celsius(0.0, 50.0, 5.0),
    "u_H": (0.3, 0.6, 1.0),
    "T_H": _celsius(20.0, 70.0, 10.0),
    "u_E": (0.3, 0.6, 1.0),
    "T_E": _celsius(-25.0, 35.0, 5.0),
}

#: The ac+chiller map is coarser (spec 2.5): blower 4 nodes, T_air_in every 8 K, T_coolant_in every 10 K,
#: so 6 x 3 x 4 x 3 x 13 x 6 x 6 = 101,088 nodes, against 200,772 (ac, with the 'cycle' evaporator LUT's 13
#: humidity nodes) and 7,722 (chiller); speed, fan, u_pump and T_amb keep the full axes (speed is the
#: controlled input and the fill runs along it; the chiller duty is concave in the coolant flow, nearly
#: linear in T_coolant_in). Build times are on the benchmarks' performance page.
COARSE_AXES: dict[str, dict[str, tuple[float, ...]]] = {
    "ac+chiller": {
        "blower": (0.1, 0.35, 0.75, 1.0),
        "T_air_in": _celsius(10.0, 50.0, 8.0),
        "T_coolant_in": _celsius(0.0, 50.0, 10.0),
    }
}


def _check_axis(key: str, values: Sequence[float]) -> tuple[float, ...]:
    """An override's values as floats, finite, strictly increasing and inside its input's range."""
    from evtms.cycle.topology import INPUTS

    axis = key.split(".")[-1]
    try:
        out = tuple(float(v) for v in np.atleast_1d(np.asarray(values, float)))
    except (TypeError, ValueError):
        raise EvtmsInputError(f"map axis {key!r}: the values are not numbers") from None
    if not out or not all(math.isfinite(v) for v in out):
        raise EvtmsInputError(f"map axis {key!r}: give at least one finite value")
    if any(b <= a for a, b in zip(out, out[1:], strict=False)):
        raise EvtmsInputError(f"map axis {key!r}: the values must be strictly increasing")
    if axis in PUMP_AXES:
        if out[0] <= 0.0:
            raise EvtmsInputError(f"map axis {key!r}: {axis} must be > 0 (the exchanger needs a coolant flow)")
        return out
    spec = INPUTS[AXIS_INPUTS[axis]]
    for v in out:
        if not spec.lower <= v <= spec.upper or (spec.positive and v == spec.lower):
            raise EvtmsInputError(f"map axis {key!r}: {v:g} is not allowed; allowed: {spec.allowed()} (SI, K)")
    return out


@dataclass(frozen=True)
class MapSettings:
    """Everything besides the LUTs a map depends on (part of its cache key).

    Attributes
    ----------
    coolant_flow_max : float
        Coolant volume flow at u_pump 1 [m3/s].
    heating_flow_max, edrive_flow_max : float
        The heater-core loop's and the e-drive loop's volume flows at u_H and
        u_E 1 [m3/s] (the ``hp`` map's water-cooled condenser and chiller).
    coolant_density : float
        Coolant density [kg/m3]; mdot_coolant = u_pump coolant_flow_max coolant_density.
    superheat : float
        Superheat setpoint of every active branch's valve [K].
    subcooling : float
        Condenser-outlet subcooling [K] (0: receiver, saturated liquid).
    RH_amb : float
        Ambient relative humidity [1].
    axes : mapping of str to sequence of float
        Axis overrides [SI, K for temperatures]: ``{"T_amb": [...]}`` sets
        that axis in every map that has it, ``{"ac+chiller.T_amb": [...]}``
        in one map only (wins over the former). Other axes keep
        :data:`DEFAULT_AXES` (``ac+chiller``: :data:`COARSE_AXES`).
    """

    coolant_flow_max: float = 4.0e-4
    coolant_density: float = 1070.0
    heating_flow_max: float = 3.33e-4
    edrive_flow_max: float = 3.33e-4
    superheat: float = 10.0
    subcooling: float = 0.0
    RH_amb: float = 0.4
    axes: Mapping[str, Sequence[float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        checks = (
            ("coolant_flow_max", 0.0, math.inf, True),
            ("coolant_density", 0.0, math.inf, True),
            ("heating_flow_max", 0.0, math.inf, True),
            ("edrive_flow_max", 0.0, math.inf, True),
            ("superheat", 0.0, 50.0, False),
            ("subcooling", 0.0, 30.0, False),
            ("RH_amb", 0.0, 1.0, False),
        )
        for name, lo, hi, positive in checks:
            v = getattr(self, name)
            ok = isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi and not (positive and v == lo)
            if not ok:
                rng = f"{lo:g} < {name} <= {hi:g}" if positive else f"{lo:g} to {hi:g}"
                raise EvtmsInputError(f"map setting {name} = {v!r} is not allowed; allowed: {rng}")
        axes = {}
        for key, values in dict(self.axes).items():
            map_name, _, axis = key.rpartition(".")
            if axis not in AXIS_ATTRS or (map_name and (map_name not in MAPS or axis not in MAPS[map_name].axes)):
                raise EvtmsInputError(
                    f"map axis {key!r} is unknown; allowed: {', '.join(AXIS_ATTRS)}, or <map>.<axis> of a map's axes"
                )
            axes[key] = _check_axis(key, values)
        object.__setattr__(self, "axes", axes)

    def recipe(self, name: str) -> dict:
        """The settings map ``name`` depends on, JSON-serialisable (the coolant only with a chiller)."""
        spec = MAPS[name]
        out = {
            "superheat": self.superheat,
            "subcooling": self.subcooling,
            "RH_amb": self.RH_amb,
        }
        for axis in spec.axes:
            for setting in PUMP_AXES.get(axis, ()):
                out[setting] = getattr(self, setting)
        out["axes"] = {a: list(v) for a in spec.axes if (v := self.override(name, a)) is not None}
        return out

    def override(self, name: str, axis: str) -> tuple[float, ...] | None:
        """The override of ``axis`` in map ``name`` (None: its default)."""
        return self.axes.get(f"{name}.{axis}", self.axes.get(axis))


@dataclass(frozen=True, eq=False)
class CycleMap:
    """One steady cycle map: the outputs :data:`MAP_OUTPUTS` on a grid of inputs.

    Attributes
    ----------
    name : str
        Map name (:data:`MAPS`).
    axes : tuple of str
        Axis names in table order.
    nodes : tuple of numpy.ndarray
        Each axis' nodes [SI, K for temperatures], float64, strictly increasing.
    values : numpy.ndarray
        Outputs, shape ``(*node counts, 9)``, float64, C-contiguous, no NaN
        (units of :data:`OUTPUT_ATTRS`).
    filled : int
        Invalid nodes filled from a donor at build.
    filled_nodes : numpy.ndarray or None
        Boolean, shape ``(*node counts)``: which nodes were filled.
    attrs : dict
        Provenance (topology, LUT files, settings, evtms version, created, ...).
    """

    name: str
    axes: tuple[str, ...]
    nodes: tuple[np.ndarray, ...]
    values: np.ndarray
    filled: int
    filled_nodes: np.ndarray | None = None
    attrs: dict = field(default_factory=dict)
    _interpolator: object = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        nodes = tuple(np.ascontiguousarray(n, dtype=np.float64).reshape(-1) for n in self.nodes)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "values", np.ascontiguousarray(self.values, dtype=np.float64))
        shape = (*(n.size for n in nodes), len(MAP_OUTPUTS))
        if len(self.axes) != len(nodes) or self.values.shape != shape:
            raise ValueError(f"map {self.name}: values of shape {self.values.shape}, axes need {shape}")
        for a, n in zip(self.axes, nodes, strict=True):
            if n.size == 0 or np.any(np.diff(n) <= 0) or not np.all(np.isfinite(n)):
                raise ValueError(f"map {self.name}: the nodes of {a} are not strictly increasing")
        if not np.all(np.isfinite(self.values)):
            raise ValueError(f"map {self.name}: the values hold NaN or inf")

    @property
    def shape(self) -> tuple[int, ...]:
        """Node counts per axis."""
        return tuple(n.size for n in self.nodes)

    def output(self, name: str) -> np.ndarray:
        """The table of one output, shape ``(*node counts)`` (a view)."""
        return self.values[..., MAP_OUTPUTS.index(name)]

    def packed(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat arrays for :func:`map_interp`.

        Returns
        -------
        knots : numpy.ndarray
            float64, 1-D: every axis' nodes, concatenated in axis order.
        starts : numpy.ndarray
            int64, ``(ndim + 1,)``: axis ``d``'s nodes are ``knots[starts[d]:starts[d + 1]]``.
        table : numpy.ndarray
            float64, ``(n_nodes, 9)``, C order of the node grid (a view of ``values``).
        """
        starts = np.zeros(len(self.nodes) + 1, np.int64)
        starts[1:] = np.cumsum([n.size for n in self.nodes])
        table = self.values.reshape(-1, len(MAP_OUTPUTS))
        return kernel_array(np.concatenate(self.nodes)), kernel_array(starts, np.int64), kernel_array(table)

    def interp(self, x: Sequence[float]) -> tuple[np.ndarray, bool]:
        """The outputs at one point, by the LUT layer's interpolator (the loop calls :data:`map_interp`).

        Parameters
        ----------
        x : sequence of float
            One value per axis [SI, K for temperatures]. A coordinate outside
            its axis is clipped to the axis' end; NaN gives NaN outputs.

        Returns
        -------
        (numpy.ndarray, bool)
            The 9 outputs (:data:`MAP_OUTPUTS`) and whether a coordinate was clipped.
        """
        if self._interpolator is None:
            from evtms.luts.interp import Interpolator

            axes = list(zip(self.axes, self.nodes, strict=True))
            itp = Interpolator(axes, {k: self.output(k) for k in MAP_OUTPUTS}, out_of_range="nan")
            object.__setattr__(self, "_interpolator", itp)
        x = np.asarray(x, np.float64).reshape(-1)
        lo = np.array([n[0] for n in self.nodes])
        hi = np.array([n[-1] for n in self.nodes])
        inside = np.clip(x, lo, hi)  # NaN stays NaN: the 'nan' policy gives NaN outputs for it
        clipped = bool(np.any((x < lo) | (x > hi)))
        res = self._interpolator(inside[None, :])
        return np.array([res[k][0] for k in MAP_OUTPUTS]), clipped


def _map_interp(knots, starts, table, x, out):
    """Multilinear interpolation of every column of ``table`` at ``x``, the same weights for each.

    Plain scalar code (numba-compilable); :data:`map_interp` is its compiled
    form, the time loop's twin of :meth:`CycleMap.interp` (the LUT layer's
    interpolator), which it equals to rounding.

    Parameters
    ----------
    knots : numpy.ndarray
        float64, 1-D: the axes' nodes concatenated [SI].
    starts : numpy.ndarray
        int64, ``(ndim + 1,)``: offsets of each axis in ``knots``.
    table : numpy.ndarray
        float64, ``(n_nodes, n_out)``: node values, C order of the grid.
    x : numpy.ndarray
        float64, ``(ndim,)``: the point [SI]. A coordinate outside its axis
        is clipped to the axis' end; NaN gives NaN outputs.
    out : numpy.ndarray
        float64, ``(n_out,)``: receives the interpolated values.

    Returns
    -------
    int
        1 if any coordinate was clipped, else 0.
    """
    ndim = starts.shape[0] - 1
    nout = out.shape[0]
    base = np.empty(ndim, np.int64)
    frac = np.empty(ndim, np.float64)
    stride = np.empty(ndim, np.int64)
    clipped = 0
    s = 1
    for d in range(ndim - 1, -1, -1):
        stride[d] = s
        s *= starts[d + 1] - starts[d]
    for d in range(ndim):
        lo = starts[d]
        n = starts[d + 1] - lo
        xd = x[d]
        if n == 1:
            base[d] = 0
            frac[d] = 0.0
            if xd != knots[lo]:
                clipped = 1
        elif xd <= knots[lo]:
            base[d] = 0
            frac[d] = 0.0
            if xd < knots[lo]:
                clipped = 1
        elif xd >= knots[lo + n - 1]:
            base[d] = n - 2
            frac[d] = 1.0
            if xd > knots[lo + n - 1]:
                clipped = 1
        else:
            i = 0
            j = n - 1
            while j - i > 1:
                m = (i + j) // 2
                if knots[lo + m] <= xd:
                    i = m
                else:
                    j = m
            base[d] = i
            frac[d] = (xd - knots[lo + i]) / (knots[lo + i + 1] - knots[lo + i])
    for k in range(nout):
        out[k] = 0.0
    # Only the axes strictly between two nodes span corners (2^active of them); on a node, or on an axis of
    # one node, the lower node alone carries the weight (a node returns its own values exactly).
    active = np.empty(ndim, np.int64)
    n_active = 0
    row0 = 0
    for d in range(ndim):
        if frac[d] == 1.0:
            row0 += (base[d] + 1) * stride[d]
        else:
            row0 += base[d] * stride[d]
            if not frac[d] <= 0.0:  # NaN too: its weights make the outputs NaN
                active[n_active] = d
                n_active += 1
    for c in range(1 << n_active):
        w = 1.0
        row = row0
        for a in range(n_active):
            d = active[a]
            if (c >> a) & 1:
                w *= frac[d]
                row += stride[d]
            else:
                w *= 1.0 - frac[d]
        for k in range(nout):
            out[k] += w * table[row, k]
    return clipped


#: :func:`_map_interp` compiled by numba (``cache=True``), or itself under ``EVTMS_NO_NUMBA=1``;
#: callable from the simulator's own jitted loop.
map_interp = jit(_map_interp)


# ----------------------------------------------------------------------------------------------
# Building


#: Most operating points per solver call; a map of more is split into equal chunks of adjacent
#: nodes (:func:`_chunks`). A node's result does not depend on the chunking (checked). The
#: vectorised closure's Python steps cost per call, and a batch takes as many calls as its
#: slowest points need, so the time per node falls with the batch: all four maps in 88 s on two
#: workers in chunks of 4,000 nodes, 58 s in chunks of 16,000, 52 s in chunks of up to 32,000.
#: Adjacent nodes share LUT cells and iterate alike: chunks of every k-th node took 77 s. The
#: compiled closures hand their failed and valve-limited points to those Python steps, so large
#: chunks still pay: the three demo maps 37 s in chunks of 32,000, 43 s in chunks of 8,000.
CHUNK_POINTS = 32000
#: Builds of fewer points run in this process (a worker process costs about a second to start).
POOL_FROM_POINTS = 6000

Progress = Callable[[int, int, str], None]


def map_axes(name: str, luts_folder: str | Path, settings: MapSettings | None = None) -> dict[str, np.ndarray]:
    """The nodes of map ``name``'s axes: the overrides, else the defaults.

    Parameters
    ----------
    name : str
        Map name (:data:`MAPS`).
    luts_folder : path
        Folder of the cycle LUTs (the default RH_air_in axis is the evaporator LUT's).
    settings : MapSettings, optional
        Axis overrides (default: none).

    Returns
    -------
    dict of str to numpy.ndarray
        Nodes per axis [SI, K for temperatures], in the map's axis order.
    """
    from evtms.cycle.tables import CycleLut
    from evtms.luts.store import LutStore
    from evtms.paths import input_file

    if name not in MAPS:
        raise EvtmsInputError(f"cycle map {name!r} is unknown; allowed: {', '.join(MAPS)}")
    settings = settings or MapSettings()
    out = {}
    for axis in MAPS[name].axes:
        values = settings.override(name, axis)
        if values is None:
            values = COARSE_AXES.get(name, {}).get(axis, DEFAULT_AXES[axis])
        if values is None:  # the evaporator grid's humidity axis
            path = LutStore(luts_folder).lut("evaporator")
            if not path.exists():
                raise EvtmsInputError(f"{path}: no such file; write the cycle LUTs with 'evtms bench all --grid cycle'")
            values = CycleLut(input_file(path, "LUT file"), "evaporator").axes["RH_air_in"]
        out[axis] = np.asarray(values, np.float64)
    return out


def operating_inputs(name: str, axes: Mapping[str, np.ndarray], settings: MapSettings) -> dict[str, np.ndarray]:
    """Flat operating inputs (:class:`OperatingPoints` keywords) of every node, C order of the grid."""
    spec = MAPS[name]
    mesh = np.meshgrid(*[axes[a] for a in spec.axes], indexing="ij")
    values = {a: m.ravel() for a, m in zip(spec.axes, mesh, strict=True)}
    values.update({a: np.full(mesh[0].size, v) for a, v in spec.fixed})
    points = {
        "RH_amb": settings.RH_amb,
        "superheat": settings.superheat,
        "subcooling": settings.subcooling,
    }
    for a, v in values.items():
        if a in PUMP_AXES:
            flow, density = (getattr(settings, k) for k in PUMP_AXES[a])
            points[AXIS_INPUTS[a]] = v * flow * density
        else:
            points[AXIS_INPUTS[a]] = v
    return {k: np.broadcast_to(np.asarray(v, float), mesh[0].size).copy() for k, v in points.items()}


#: Cycle results a map is made of.
_RESULT_KEYS = ("p_A", "p_B", "mdot", "Q_evap", "Q_latent", "Q_chiller", "Q_cond", "W", "W_fluid", "status")
#: Per worker process: LUTs by (folder, topology), loaded once per process (a pool lives for one build).
_WORKER_LUTS: dict[tuple[str, str], dict] = {}


def solve_nodes(luts: dict, topology: str, inputs: Mapping[str, np.ndarray], params=None) -> dict[str, np.ndarray]:
    """The cycle at the map nodes ``inputs``: on ``luts``, or (``luts`` None) on the bench physics with ``params``."""
    from evtms.cycle.api import run_cycle
    from evtms.cycle.solver import OperatingPoints

    # One interpolation path and one closure path whatever the chunk's size: a map's bits do not
    # depend on how its nodes were split between chunks and worker processes.
    closure = next(m.closure for m in MAPS.values() if m.topology == topology)
    res = run_cycle(OperatingPoints(**inputs), luts, circuit=topology, params=params, compiled=True, closure=closure)
    return {k: np.asarray(res[k]) for k in _RESULT_KEYS}


def _worker_luts(folder: str, topology: str) -> dict:
    """The LUTs of ``topology`` in ``folder``, loaded once per worker process."""
    from evtms.cycle.api import load_cycle_luts

    key = (folder, topology)
    if key not in _WORKER_LUTS:
        _WORKER_LUTS[key] = load_cycle_luts(folder, topology)
    return _WORKER_LUTS[key]


def _solve_in_worker(folder: str, topology: str, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A worker process' chunk: the LUTs loaded once per process."""
    return solve_nodes(_worker_luts(folder, topology), topology, inputs)


def _tables_in_worker(folder: str, topology: str, component: str) -> None:
    """The derived tables (:mod:`evtms.luts.cache`) of one component of ``topology``, as its cycle
    reads them, built where the user cache lacks them: on new LUTs the workers build different
    components' tables side by side before their first chunk, where each chunk's solve would
    build them all in one worker while the other waited for its lock (16 s of a 68 s build)."""
    from evtms.cycle.models import LutModels

    models = LutModels(_worker_luts(folder, topology), (component,))
    for lut in models.luts.values():
        lut.no_heat_indicator()


def _solve_task(task: tuple) -> dict[str, np.ndarray]:
    """A :class:`~evtms.benches.chunked.PoolRunner` job: chunk ``(index, folder, topology, inputs)`` solved,
    or (``inputs`` a component's name) that component's tables built (no result)."""
    _, folder, topology, inputs = task
    if isinstance(inputs, str):
        _tables_in_worker(folder, topology, inputs)
        return {}
    return _solve_in_worker(folder, topology, inputs)


def _table_tasks(plans: Sequence[_Plan], folder: Path) -> list[tuple[str, str]]:
    """``(topology, component)`` for each component with tables the plans' circuits interpolate,
    once, the largest LUT file first (the evaporator's tables take as long as all the others')."""
    from evtms.cycle.topology import topology
    from evtms.luts.store import LutStore

    store, tasks = LutStore(folder), {}
    for p in plans:
        name = p.provenance["topology"]
        for c in topology(name).components:
            if c != "expansion_valve":  # no table of its own: the valve's flow area is derived on demand
                tasks.setdefault(c, (name, c))
    return sorted(tasks.values(), key=lambda t: -store.lut(t[1]).stat().st_size)


def map_values(res: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, float]:
    """Node values ``(n, 9)``, valid mask and the largest relative balance residual of the valid nodes."""
    from evtms.cycle.solver import VALID_CYCLE_FLAGS

    q_evap = 0.0 - np.asarray(res["Q_evap"], float)  # 0.0 - x: no -0.0 where a branch is absent
    q_chiller = 0.0 - np.asarray(res["Q_chiller"], float)
    w_fluid = np.asarray(res["W_fluid"], float)
    with np.errstate(invalid="ignore"):
        q_latent = np.minimum(np.maximum(0.0 - np.asarray(res["Q_latent"], float), 0.0), np.maximum(q_evap, 0.0))
    q_cond = q_evap + q_chiller + w_fluid
    columns = {
        "p_suction": res["p_A"],
        "p_discharge": res["p_B"],
        "mdot": res["mdot"],
        "Q_evaporator": q_evap,
        "Q_latent": q_latent,
        "Q_chiller": q_chiller,
        "Q_condenser": q_cond,
        "W": res["W"],
        "W_fluid": w_fluid,
    }
    values = np.stack([np.asarray(columns[k], float) for k in MAP_OUTPUTS], axis=-1)
    valid = np.isin(res["status"], VALID_CYCLE_FLAGS) & np.all(np.isfinite(values), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(np.asarray(res["Q_cond"], float) - q_cond) / w_fluid
    balance = float(np.max(rel[valid])) if valid.any() else float("nan")
    return values, valid, balance


def fill_order(axes: Sequence[str]) -> tuple[int, ...]:
    """The order in which the fill searches the axes: speed, T_amb, then the others in map order."""
    first = [a for a in ("speed", "T_amb") if a in axes]
    return tuple(axes.index(a) for a in (*first, *(a for a in axes if a not in first)))


def fill_invalid(
    values: np.ndarray, valid: np.ndarray, nodes: Sequence[np.ndarray], axes: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Invalid nodes filled with a donor's whole output vector (the module's fill rule).

    Parameters
    ----------
    values : numpy.ndarray
        ``(*node counts, n_out)``; invalid nodes may hold anything.
    valid : numpy.ndarray
        Boolean ``(*node counts)``.
    nodes : sequence of numpy.ndarray
        Each axis' nodes [SI] (distances for the nearest donor).
    axes : sequence of str
        Axis names (speed: lower speed first; the others: nearest, lower on a tie).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The filled values (a copy) and the boolean mask of filled nodes; nodes
        still invalid (only if no node is valid) keep their values.
    """
    values = np.array(values, dtype=np.float64, copy=True)
    ok = np.array(valid, dtype=bool, copy=True)
    for axis in fill_order(axes):
        if ok.all():
            break
        v = np.moveaxis(ok, axis, -1)  # views: writing into them writes into ok / values
        vals = np.moveaxis(values, axis, -2)
        n = v.shape[-1]
        idx = np.arange(n)
        lower = np.maximum.accumulate(np.where(v, idx, -1), axis=-1)
        upper = np.minimum.accumulate(np.where(v, idx, n)[..., ::-1], axis=-1)[..., ::-1]
        has_lower, has_upper = lower >= 0, upper < n
        if axes[axis] == "speed":
            use_lower = has_lower
        else:
            x = np.asarray(nodes[axis], float)
            d_lower = x[idx] - x[np.clip(lower, 0, n - 1)]
            d_upper = x[np.clip(upper, 0, n - 1)] - x[idx]
            use_lower = has_lower & (~has_upper | (d_lower <= d_upper))
        donor = np.clip(np.where(use_lower, lower, upper), 0, n - 1)
        take = ~v & (has_lower | has_upper)
        if take.any():
            gathered = np.take_along_axis(vals, donor[..., None], axis=-2)
            vals[take] = gathered[take]
            v[take] = True
    return values, ok & ~np.asarray(valid, bool)


@dataclass
class _Plan:
    """One map to build: its axes, operating inputs, cache key and provenance."""

    name: str
    axes: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray]
    key: str
    provenance: dict

    @property
    def size(self) -> int:
        return next(iter(self.inputs.values())).size


def _plan(name: str, folder: Path, settings: MapSettings) -> _Plan:
    from evtms.cycle.api import load_cycle_luts
    from evtms.cycle.topology import topology
    from evtms.luts.store import LutStore

    spec = MAPS[name]
    axes = map_axes(name, folder, settings)
    recipe = {
        "map_format": MAP_FORMAT,
        "evtms_version": __version__,
        "map_name": name,
        "topology": spec.topology,
        "fixed": dict(spec.fixed),
        "settings": settings.recipe(name),
        "axes": {a: [float(v) for v in axes[a]] for a in spec.axes},
    }
    try:
        key, provenance = LutStore(folder).map_key(recipe, topology(spec.topology).components)
    except OSError:
        load_cycle_luts(folder, spec.topology)  # its one-line error names the missing or bad file
        raise
    return _Plan(name, axes, operating_inputs(name, axes, settings), key, provenance)


def _chunks(plans: Sequence[_Plan]) -> list[tuple[_Plan, np.ndarray]]:
    """Each plan's nodes (flat indices) in equal chunks of adjacent nodes, at most :data:`CHUNK_POINTS`
    each; the chunks of two-branch circuits first (they cost several times as much a node: a
    pool that ends on them leaves its other workers idle)."""
    from evtms.cycle.topology import topology

    out = []
    for p in sorted(plans, key=lambda p: not topology(p.provenance["topology"]).parallel):
        out += [(p, c) for c in np.array_split(np.arange(p.size), math.ceil(p.size / CHUNK_POINTS))]
    return out


def _build(plans: Sequence[_Plan], folder: Path, progress: Progress | None, workers: int | None) -> dict[str, CycleMap]:
    """Solve every plan's nodes (in worker processes when large), fill, and make the maps."""
    report = progress or (lambda done, total, text: None)
    chunks = _chunks(plans)
    results: dict[str, dict[str, np.ndarray]] = {p.name: {} for p in plans}
    workers = min(workers or os.cpu_count() or 1, len(chunks))
    done = dict.fromkeys((p.name for p in plans), 0)
    t0 = time.perf_counter()
    for p in plans:  # maps built together progress together: each is announced at the start
        report(0, p.size, p.name)

    def take(plan: _Plan, nodes: np.ndarray, res: dict) -> None:
        into = results[plan.name]
        for k, v in res.items():
            if k not in into:
                into[k] = np.empty(plan.size, np.asarray(v).dtype)
            into[k][nodes] = v
        done[plan.name] += nodes.size
        report(done[plan.name], plan.size, plan.name)

    def piece(plan: _Plan, nodes: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v[nodes] for k, v in plan.inputs.items()}

    try:
        if workers > 1 and sum(p.size for p in plans) >= POOL_FROM_POINTS:
            import multiprocessing

            from evtms.benches.chunked import PoolRunner

            # fork where the platform has it (as evtms.workflows.demo's pool): a spawned worker re-runs the caller's
            # main script, which breaks scripts without an ``if __name__ == "__main__"`` guard
            method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
            # The sweeps' pool: workers ignore SIGINT; on Ctrl-C no other chunk starts.
            runner = PoolRunner(workers, start_method=method)
            finished = False
            try:
                topology = {p.name: p.provenance["topology"] for p in plans}
                tasks = [(-1, str(folder), t, c) for t, c in _table_tasks(plans, folder)]
                tasks += [(k, str(folder), topology[p.name], piece(p, nodes)) for k, (p, nodes) in enumerate(chunks)]
                for (k, *_), res in runner.run(_solve_task, tasks):
                    if k >= 0:
                        take(*chunks[k], res)
                finished = True
            finally:
                # Stopped (Ctrl-C, an error): a chunk saves nothing, so its workers end at once.
                runner.close(kill=not finished)
        else:
            from evtms.cycle.api import load_cycle_luts

            luts = {}
            for p, nodes in chunks:
                topo = p.provenance["topology"]
                if topo not in luts:
                    luts[topo] = load_cycle_luts(folder, topo)
                take(p, nodes, solve_nodes(luts[topo], topo, piece(p, nodes)))
    except KeyboardInterrupt:
        names = ", ".join(p.name for p in plans)
        raise EvtmsInterrupted(
            f"interrupted while building the cycle maps {names} of {str(folder)!r}; none was saved, "
            "the next run builds them again"
        ) from None
    seconds = time.perf_counter() - t0

    maps = {}
    for p in plans:
        res = results[p.name]
        spec = MAPS[p.name]
        shape = tuple(p.axes[a].size for a in spec.axes)
        flat, valid, balance = map_values(res)
        if not valid.any():
            raise EvtmsInputError(
                f"cycle map {p.name!r}: none of its {p.size:,} operating points solved on the LUTs in {folder} "
                "(check that the LUT grids cover the map's axes)"
            )
        nodes = tuple(p.axes[a] for a in spec.axes)
        values, filled = fill_invalid(flat.reshape(*shape, len(MAP_OUTPUTS)), valid.reshape(shape), nodes, spec.axes)
        created = dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")
        attrs = {
            **p.provenance,
            "map_key": p.key,
            "created": created,
            "filled": int(filled.sum()),
            "status": np.asarray(res["status"], np.int8).reshape(shape),
            "balance_relative_max": balance,
            "build_seconds": seconds,
        }
        maps[p.name] = CycleMap(p.name, spec.axes, nodes, values, int(filled.sum()), filled, attrs)
    return maps


def build_map(
    name: str,
    luts_folder: str | Path,
    settings: MapSettings | None = None,
    progress: Progress | None = None,
    *,
    workers: int | None = None,
) -> CycleMap:
    """Solve the cycle on every node of map ``name`` and fill the invalid nodes (nothing cached).

    Parameters
    ----------
    name : str
        Map name (:data:`MAPS`).
    luts_folder : path
        Folder holding the cycle LUTs (``evtms bench all --grid cycle``).
    settings : MapSettings, optional
        Settings and axis overrides (default :class:`MapSettings`).
    progress : callable, optional
        ``progress(done, total, text)``: ``done`` of the map's ``total``
        operating points solved; ``text`` is the map's name.
    workers : int, optional
        Worker processes for large maps (default: the CPU count); 1 solves in this process.

    Returns
    -------
    CycleMap

    Raises
    ------
    EvtmsInputError
        Unknown map, missing or bad LUT file, bad settings, or no node of the map solved.
    """
    folder = Path(luts_folder)
    return _build([_plan(name, folder, settings or MapSettings())], folder, progress, workers)[name]


# ----------------------------------------------------------------------------------------------
# Files


def map_table(cmap: CycleMap) -> MapTable:
    """A map as the LUT layer stores it (:class:`evtms.luts.io.MapTable`): outputs with units, provenance.

    Parameters
    ----------
    cmap : CycleMap
        The map.

    Returns
    -------
    MapTable
        Outputs (:data:`OUTPUT_ATTRS`), ``filled`` and ``status`` (int8) on the
        map's axes; global attributes: the provenance, fill rule and counts.
    """
    from evtms.cycle.solver import CYCLE_FLAGS, VALID_CYCLE_FLAGS
    from evtms.luts.io import MapTable

    axes = dict(zip(cmap.axes, cmap.nodes, strict=True))
    attributes = {a: {"units": AXIS_ATTRS[a][0], "long_name": AXIS_ATTRS[a][1]} for a in cmap.axes}
    variables = {k: cmap.output(k) for k in MAP_OUTPUTS}
    attributes |= {k: {"units": OUTPUT_ATTRS[k][0], "long_name": OUTPUT_ATTRS[k][1]} for k in MAP_OUTPUTS}
    variables["filled"] = np.zeros(cmap.shape, np.int8) if cmap.filled_nodes is None else cmap.filled_nodes
    attributes["filled"] = {
        "units": "1",
        "long_name": "1: node invalid on the LUTs, values copied from a donor node",
        "flag_values": np.array([0, 1], np.int8),
        "flag_meanings": "solved filled",
    }
    if "status" in cmap.attrs:
        codes = sorted(CYCLE_FLAGS)
        variables["status"] = np.asarray(cmap.attrs["status"], np.int8)
        attributes["status"] = {
            "units": "1",
            "long_name": "cycle status of the node as solved (before the fill)",
            "flag_values": np.array(codes, np.int8),
            "flag_meanings": " ".join(CYCLE_FLAGS[c] for c in codes),
            "valid_flag_values": np.array(VALID_CYCLE_FLAGS, np.int8),
        }
    attrs = {k: v for k, v in cmap.attrs.items() if k != "status"}
    created = attrs.get("created", "")
    attrs = {
        "title": f"evtms steady cycle map {cmap.name}",
        "description": MAPS[cmap.name].description if cmap.name in MAPS else "",
        "fill_rule": "invalid nodes copy the whole output vector of the nearest valid node at lower speed, "
        "else higher speed, else along T_amb, then the other axes in map order (evtms.system.maps)",
        "history": f"{created} built by the cycle solver on the LUTs (evtms.system.maps)".strip(),
        **attrs,
        "map_name": cmap.name,
        "filled": int(cmap.filled),
    }
    return MapTable(axes, variables, attributes, attrs)


def cycle_map(table: MapTable) -> CycleMap:
    """The cycle map a map table of :func:`map_table` holds.

    Raises
    ------
    KeyError, ValueError, TypeError
        Not a cycle map: an unknown name, other axes, a missing output or count.
    """
    name = table.name
    axes = tuple(MAPS[name].axes)
    if tuple(table.axes) != axes:
        raise ValueError(f"map {name}: axes {', '.join(table.axes)}; expected {', '.join(axes)}")
    values = np.stack([table.variables[k] for k in MAP_OUTPUTS], axis=-1)
    attrs = dict(table.attrs)
    if "status" in table.variables:
        attrs["status"] = table.variables["status"]
    filled = np.asarray(table.variables["filled"], bool)
    return CycleMap(name, axes, tuple(table.axes.values()), values, int(attrs["filled"]), filled, attrs)


def write_map(cmap: CycleMap, path: str | Path) -> Path:
    """Write a map as a map LUT (:func:`evtms.luts.io.write_map_lut`: the one LUT writer, atomically).

    Parameters
    ----------
    cmap : CycleMap
        The map.
    path : path
        The file to write (its folder must exist).

    Returns
    -------
    Path
        ``path``.
    """
    from evtms.luts.io import write_map_lut

    return write_map_lut(map_table(cmap), path)


def read_map(path: str | Path, key: str | None = None) -> CycleMap | None:
    """The map in a file of :func:`write_map` (:func:`evtms.luts.validate.read_map_lut`).

    Parameters
    ----------
    path : path
        The map file.
    key : str, optional
        The cache key the file must carry (:meth:`evtms.luts.store.LutStore.map_key`).

    Returns
    -------
    CycleMap or None
        None if the file is missing, unreadable, no valid map LUT, not a cycle map or (with ``key``) stale.
    """
    from evtms.luts.store import KEY_ATTR
    from evtms.luts.validate import read_map_lut

    try:
        return cycle_map(read_map_lut(path, None if key is None else {KEY_ATTR: key}))
    except (EvtmsInputError, OSError, ValueError, KeyError, TypeError):
        return None


def load_maps(
    luts_folder: str | Path,
    settings: MapSettings | None = None,
    names: Sequence[str] = ("ac", "chiller", "ac+chiller"),
    progress: Progress | None = None,
    *,
    workers: int | None = None,
) -> dict[str, CycleMap]:
    """The cycle maps ``names`` of the LUTs in ``luts_folder``, from the cache or built.

    The folder's :class:`~evtms.luts.store.LutStore` keeps them: a map is
    cached in ``<luts_folder>/maps/<name>.nc``, a map LUT (netCDF with units;
    attributes: the LUT files' signatures, the settings as JSON, the filled
    count, evtms's version, created), and rebuilt when one of the LUTs it is
    made from changed (file name, size or mtime_ns), when the settings, its
    axes, the evtms version or :data:`MAP_FORMAT` differ, or when the file is
    unreadable; maps to build are solved together (one pool of workers).
    Where the LUT folder cannot be written, the map goes to the user cache;
    where neither can, it is returned unsaved. A map file read once is kept
    in the user cache as its arrays (:func:`evtms.luts.cache.cached_arrays`,
    keyed by the file's identity) and read back memory-mapped.
    ``EVTMS_NO_CACHE=1`` neither reads nor writes any file.

    Parameters
    ----------
    luts_folder : path
        Folder holding the cycle LUTs.
    settings : MapSettings, optional
        Settings and axis overrides (default :class:`MapSettings`).
    names : sequence of str
        Maps wanted (:data:`MAPS`).
    progress : callable, optional
        ``progress(done, total, text)`` during builds: ``done`` of map
        ``text``'s ``total`` operating points solved (``text`` is the map's
        name, the same for all calls about one map; every map being built is
        announced with ``done`` 0 first). Not called for maps read from the cache.
    workers : int, optional
        Worker processes for builds (default: the CPU count).

    Returns
    -------
    dict of str to CycleMap
        In the order of ``names``.

    Raises
    ------
    EvtmsInputError
        Unknown map name, missing or bad LUT file or folder, bad settings, or a
        map without any solved node.
    """
    from evtms.luts.store import LutStore

    folder = Path(luts_folder)
    if folder.exists() and not folder.is_dir():
        raise EvtmsInputError(f"LUT folder {str(folder)!r} is a file; give the folder holding the cycle LUTs")
    if not folder.is_dir():
        raise EvtmsInputError(f"LUT folder {str(folder)!r} does not exist")
    unknown = [n for n in names if n not in MAPS]
    if unknown:
        raise EvtmsInputError(f"cycle map {unknown[0]!r} is unknown; allowed: {', '.join(MAPS)}")
    settings = settings or MapSettings()
    plans = {n: _plan(n, folder, settings) for n in dict.fromkeys(names)}

    def build(stale: Sequence[str]) -> dict[str, MapTable]:
        built = _build([plans[n] for n in stale], folder, progress, workers)
        return {n: map_table(cmap) for n, cmap in built.items()}

    maps = LutStore(folder).load_maps({n: p.key for n, p in plans.items()}, build, cycle_map, _read_map_file)
    return {n: maps[n] for n in names}


#: Bump when :func:`_map_arrays` changes: the user cache's copies of map files are made again.
_MAP_ARRAYS_VERSION = 1


def _read_map_file(path: Path, key: str) -> CycleMap:
    """The map in ``path`` (which must carry cache key ``key``), through the user cache
    (:func:`evtms.luts.cache.cached_arrays`): a map file read once is kept there as its arrays,
    keyed by the file's identity, and read back memory-mapped. A whole ``evtms simulate`` took
    0.1 s of its 0.85 s to read and check the three maps' netCDF files and stack their outputs.

    Raises
    ------
    EvtmsInputError, OSError, ValueError, KeyError, TypeError
        As :func:`evtms.luts.validate.read_map_lut` and :func:`cycle_map`: a stale or damaged file.
    """
    from evtms.luts.cache import cached_arrays
    from evtms.luts.store import KEY_ATTR
    from evtms.luts.validate import read_map_lut

    recipe = {"map_format": MAP_FORMAT, "map_key": key, "arrays": _MAP_ARRAYS_VERSION}
    arrays, info = cached_arrays(
        "map", [path], recipe, lambda: _map_arrays(cycle_map(read_map_lut(path, {KEY_ATTR: key})))
    )
    return _map_from_arrays(arrays, info)


def _map_arrays(cmap: CycleMap) -> tuple[dict[str, np.ndarray], dict]:
    """A map as named arrays and JSON-able info (:func:`_map_from_arrays` inverts it; its
    attributes' NumPy scalars come back as Python numbers)."""
    arrays = {f"nodes_{i}": n for i, n in enumerate(cmap.nodes)}
    arrays["values"] = cmap.values
    arrays["filled_nodes"] = np.zeros(cmap.shape, bool) if cmap.filled_nodes is None else cmap.filled_nodes
    attrs = dict(cmap.attrs)
    if "status" in attrs:
        arrays["status"] = np.asarray(attrs.pop("status"), np.int8)
    info = {"name": cmap.name, "axes": list(cmap.axes), "filled": int(cmap.filled), "attrs": _plain(attrs)}
    return arrays, info


def _map_from_arrays(arrays: Mapping[str, np.ndarray], info: Mapping) -> CycleMap:
    attrs = dict(info["attrs"])
    if "status" in arrays:
        attrs["status"] = arrays["status"]
    nodes = tuple(arrays[f"nodes_{i}"] for i in range(len(info["axes"])))
    return CycleMap(
        info["name"], tuple(info["axes"]), nodes, arrays["values"], info["filled"], arrays["filled_nodes"], attrs
    )


def _plain(value):
    """``value`` with NumPy scalars and arrays as Python numbers and lists (JSON-able)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    return value
