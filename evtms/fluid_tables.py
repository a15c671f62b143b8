"""Refrigerant properties tabulated for compiled code: saturation, single phase, (p, h) -> T.

The coils' compiled marches (:mod:`evtms.hx._coil_kernels`) cannot call
CoolProp; they read these tables, built once per process from a
:class:`evtms.fluid.Fluid` on the full equation of state (HEOS, whatever the
caller's backend; about 0.4 s, some 21,000 CoolProp states) and kept in
memory (:func:`tables_for`).

Layout (all SI):

- saturation against ``u = ln p`` on :data:`N_PRESSURES` uniform nodes from
  :data:`P_MIN` to :data:`P_MAX_CRIT_FRACTION` of the critical pressure:
  the columns :data:`SAT_COLUMNS`;
- single phase on the same pressures and :data:`N_DEPTH` nodes of
  ``t = sqrt(s)`` in [0, 1], with ``s = (T - T_sat) / (T_top - T_sat)`` for
  vapour and ``s = (T_sat - T) / (T_sat - T_bottom)`` for liquid
  (:data:`T_TOP`, :data:`T_BOTTOM`): a rectangle in (ln p, t) whose first
  column is the saturated state, nodes packed towards saturation where the
  properties change fastest; the columns :data:`PHASE_COLUMNS`;
- interpolation by 4-point Lagrange polynomials in each coordinate (cubic,
  error of order ``step^4 f''''``), which passes through the nodes;
- ``(p, h) -> T``: the saturated enthalpies decide the phase; in a single
  phase the cubic in ``t`` along the interpolated column is inverted exactly
  (cell by bisection over the nodes, then safeguarded Newton), so
  ``h(p, T(p, h)) = h`` to round-off.
- ``(p, s) -> h`` (:func:`ps_enthalpy`, a compressor's isentropic
  discharge): the entropy column inverted the same way, its depth carried to
  the enthalpy column; inside the dome the mixture's enthalpy at the quality
  of ``s``.

Tolerance against CoolProp HEOS (``tests/test_fluid_tables.py`` asserts it on
random states, pressures 0.5-30 bar, liquid down to 220 K and vapour up to
150 K of superheat and 400 K): saturation temperature within 1e-4 K;
enthalpy within 0.2 J/kg; density, heat capacity, viscosity and conductivity
within 1e-4 relative (typically 1e-6; the worst is the heat capacity of
vapour within a kelvin of saturation near 30 bar); ``T(p, h)`` within 1e-3 K;
entropy within 1e-3 J/(kg K) (typically 1e-4) and ``h(p, s)`` within 0.2 J/kg.
A state outside the tables (pressure outside ``P_MIN``-``P_MAX``,
temperature outside ``T_BOTTOM``-``T_TOP``) gives NaN: the compiled coils then
hand the point to the CoolProp path.

References
----------
Bell, I. H. et al. (2014). Pure and pseudo-pure fluid thermophysical property
evaluation and the open-source thermophysical property library CoolProp.
Ind. Eng. Chem. Res. 53(6), 2498-2508 (the properties tabulated).
Abramowitz, M., Stegun, I. A. (1964). Handbook of Mathematical Functions,
25.2.13 (Lagrange interpolation on equally spaced points).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from evtms._jit import jit
from evtms.fluid import Fluid

#: Saturation columns, in the order of :attr:`PropertyTables.sat`.
SAT_COLUMNS = ("T", "h_l", "h_v", "rho_l", "rho_v", "cp_l", "cp_v", "mu_l", "mu_v", "k_l", "k_v")
#: Single-phase columns, in the order of the last axis of :attr:`PropertyTables.vapour` and ``liquid``.
PHASE_COLUMNS = ("h", "rho", "cp", "mu", "k", "s")
#: The CoolProp outputs of :data:`PHASE_COLUMNS`.
_PHASE_KEYS = ("H", "D", "CP", "MU", "K", "S")
_N_PHASE = len(PHASE_COLUMNS)
#: Lowest tabulated pressure [Pa] (below the coils' 0.5 bar; the cycle solver searches from 0.25 bar).
P_MIN = 2e4
#: Highest tabulated pressure as a fraction of the critical pressure [1] (36.5 bar for R134a):
#: closer to the critical point the liquid's heat capacity steepens beyond what the cubic holds.
P_MAX_CRIT_FRACTION = 0.9
#: Temperature [K] the vapour table reaches and the liquid table starts from.
T_TOP = 450.0
T_BOTTOM = 200.0
#: Pressure nodes and nodes of ``t = sqrt(s)`` (0.5 s to build; 1 MB).
N_PRESSURES = 160
N_DEPTH = 64

# Columns of the scalar metadata array the kernels read.
_U0, _DU, _NU, _NT, _TTOP, _TBOT = range(6)
_SAT_T, _SAT_HL, _SAT_HV = 0, 1, 2
# Single-phase columns the inversions read.
_COL_H, _COL_S = 0, PHASE_COLUMNS.index("s")


@dataclass(frozen=True)
class PropertyTables:
    """The arrays the compiled kernels read (see the module notes).

    Attributes
    ----------
    meta : numpy.ndarray
        ``ln p`` of the first node, its step, the numbers of pressure and depth nodes,
        :data:`T_TOP` and :data:`T_BOTTOM`.
    sat : numpy.ndarray
        ``(N_PRESSURES, len(SAT_COLUMNS))`` saturation properties.
    vapour, liquid : numpy.ndarray
        ``(N_PRESSURES, N_DEPTH, len(PHASE_COLUMNS))`` single-phase properties.
    p_min, p_max : float
        Tabulated pressure range [Pa].
    """

    meta: np.ndarray
    sat: np.ndarray
    vapour: np.ndarray
    liquid: np.ndarray
    p_min: float
    p_max: float

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(meta, sat, vapour, liquid)``, the kernels' arguments."""
        return self.meta, self.sat, self.vapour, self.liquid


def build_tables(fluid: Fluid, n_pressures: int = N_PRESSURES, n_depth: int = N_DEPTH) -> PropertyTables:
    """Tabulate ``fluid`` through CoolProp (see the module notes for the layout)."""
    p_max = P_MAX_CRIT_FRACTION * fluid.p_crit
    u = np.linspace(math.log(P_MIN), math.log(p_max), n_pressures)
    p = np.exp(u)
    sat = fluid.saturation(p)
    sat_arr = np.stack([sat[c] for c in SAT_COLUMNS], axis=1)
    s = np.linspace(0.0, 1.0, n_depth)[1:] ** 2
    T_sat = sat["T"][:, None]
    pp = np.broadcast_to(p[:, None], (n_pressures, n_depth - 1))
    phases = []
    for T_end, suffix in ((T_TOP, "v"), (T_BOTTOM, "l")):
        # The first column is the saturated state: (p, T_sat) alone is ambiguous in CoolProp.
        T = T_sat + s[None, :] * (T_end - T_sat)
        rest = fluid.state("PT", pp, T, _PHASE_KEYS)
        first = [sat[f"{name}_{suffix}"] for name in PHASE_COLUMNS]
        phases.append(np.stack([np.c_[f, rest[k]] for f, k in zip(first, _PHASE_KEYS, strict=True)], axis=2))
    if not all(np.isfinite(a).all() for a in (sat_arr, *phases)):
        raise ValueError(f"CoolProp left states of {fluid!r} undefined inside the tables' range")
    meta = np.array([u[0], u[1] - u[0], n_pressures, n_depth, T_TOP, T_BOTTOM])
    return PropertyTables(meta, np.ascontiguousarray(sat_arr), *phases, p_min=P_MIN, p_max=float(p[-1]))


_TABLES: dict[str, PropertyTables] = {}


def tables_for(fluid: Fluid) -> PropertyTables:
    """The :class:`PropertyTables` of ``fluid``'s name, built on first use in a process.

    Tabulated from the full equation of state (HEOS) whatever ``fluid``'s backend: a tabular
    backend (``BICUBIC&HEOS``) is itself an interpolation, off by up to 0.1 K in the (p, h)
    temperature of a liquid near saturation, which the cubic here would only carry on.
    """
    key = fluid.name
    if key not in _TABLES:
        source = fluid if fluid.backend == "HEOS" else Fluid(fluid.name, "HEOS")
        _TABLES[key] = build_tables(source)
    return _TABLES[key]


# --- scalar kernels (numba) ------------------------------------------------------------------


@jit(counted=False)
def _stencil(x: float, n: int) -> tuple[int, float, float, float, float]:
    """First node and the four Lagrange weights at ``x`` (in node units, 0..n-1) on equal steps."""
    i = int(math.floor(x)) - 1
    i = min(max(i, 0), n - 4)
    r = x - i
    w0 = -(r - 1.0) * (r - 2.0) * (r - 3.0) / 6.0
    w1 = r * (r - 2.0) * (r - 3.0) / 2.0
    w2 = -r * (r - 1.0) * (r - 3.0) / 2.0
    w3 = r * (r - 1.0) * (r - 2.0) / 6.0
    return i, w0, w1, w2, w3


@jit(counted=False)
def pressure_stencil(meta: np.ndarray, p: float) -> tuple[int, float, float, float, float]:
    """:func:`_stencil` of pressure ``p`` [Pa]; first node -1 outside the table (also NaN)."""
    x = (math.log(p) - meta[_U0]) / meta[_DU] if p > 0.0 else -1.0
    n = int(meta[_NU])
    if not (0.0 <= x <= n - 1.0):
        return -1, 0.0, 0.0, 0.0, 0.0
    return _stencil(x, n)


@jit(counted=False)
def sat_column(sat: np.ndarray, st: tuple[int, float, float, float, float], c: int) -> float:
    """Saturation column ``c`` (:data:`SAT_COLUMNS`) at a :func:`pressure_stencil` (NaN outside)."""
    i, w0, w1, w2, w3 = st
    if i < 0:
        return math.nan
    return w0 * sat[i, c] + w1 * sat[i + 1, c] + w2 * sat[i + 2, c] + w3 * sat[i + 3, c]


@jit(counted=False)
def saturation(meta: np.ndarray, sat: np.ndarray, p: float, out: np.ndarray) -> bool:
    """All :data:`SAT_COLUMNS` at ``p`` [Pa] into ``out``; False (``out`` NaN) outside the table."""
    st = pressure_stencil(meta, p)
    for c in range(out.size):
        out[c] = sat_column(sat, st, c)
    return st[0] >= 0


@jit(counted=False)
def _column_at(tab: np.ndarray, st: tuple[int, float, float, float, float], j: int, c: int) -> float:
    i, w0, w1, w2, w3 = st
    return w0 * tab[i, j, c] + w1 * tab[i + 1, j, c] + w2 * tab[i + 2, j, c] + w3 * tab[i + 3, j, c]


@jit(counted=False)
def _phase_at(meta: np.ndarray, tab: np.ndarray, st, t: float, out: np.ndarray) -> None:
    """Single-phase columns at depth ``t`` (see the module notes) into ``out``."""
    n = int(meta[_NT])
    j, v0, v1, v2, v3 = _stencil(t * (n - 1), n)
    for c in range(out.size):
        out[c] = (
            v0 * _column_at(tab, st, j, c)
            + v1 * _column_at(tab, st, j + 1, c)
            + v2 * _column_at(tab, st, j + 2, c)
            + v3 * _column_at(tab, st, j + 3, c)
        )


@jit(counted=False)
def pt_state(meta, sat, vapour, liquid, p: float, T: float, out: np.ndarray) -> bool:
    """``h, rho, cp, mu, k`` (:data:`PHASE_COLUMNS`) at ``(p, T)`` into ``out``: vapour at or above
    the saturation temperature, liquid below. False (``out`` NaN) outside the tables."""
    st = pressure_stencil(meta, p)
    T_sat = sat_column(sat, st, _SAT_T)
    ok = st[0] >= 0 and meta[_TBOT] <= T <= meta[_TTOP]
    if not ok:
        for c in range(out.size):
            out[c] = math.nan
        return False
    if T >= T_sat:
        _phase_at(meta, vapour, st, math.sqrt((T - T_sat) / (meta[_TTOP] - T_sat)), out)
    else:
        _phase_at(meta, liquid, st, math.sqrt((T_sat - T) / (T_sat - meta[_TBOT])), out)
    return True


@jit
def pt_enthalpy(meta, sat, vapour, liquid, p: float, T: float) -> float:
    """Enthalpy [J/kg] at ``(p, T)`` (:func:`pt_state`'s first column)."""
    out = np.empty(_N_PHASE)
    pt_state(meta, sat, vapour, liquid, p, T, out)
    return out[0]


@jit(counted=False)
def _invert_depth(meta, tab, st, h: float) -> float:
    """The depth ``t`` in [0, 1] where the column's interpolated enthalpy is ``h``; NaN beyond the
    table. The enthalpy is monotonic in ``t`` (rising for vapour, falling for liquid)."""
    return _invert_column(meta, tab, st, h, _COL_H)


@jit(counted=False)
def _invert_column(meta, tab, st, h: float, c: int) -> float:
    """The depth ``t`` in [0, 1] where single-phase column ``c`` interpolates to ``h``; NaN beyond
    the table. Column ``c`` must be monotonic in ``t`` (enthalpy and entropy are: both rise with
    temperature at constant pressure)."""
    n = int(meta[_NT])
    h0 = _column_at(tab, st, 0, c)
    h1 = _column_at(tab, st, n - 1, c)
    sign = 1.0 if h1 > h0 else -1.0
    if not (sign * h0 <= sign * h <= sign * h1):
        return math.nan
    lo, hi = 0, n - 1  # node values bracket h: sign * H[lo] <= sign * h <= sign * H[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if sign * _column_at(tab, st, mid, c) <= sign * h:
            lo = mid
        else:
            hi = mid
    i = min(max(lo - 1, 0), n - 4)
    y0 = _column_at(tab, st, i, c)
    y1 = _column_at(tab, st, i + 1, c)
    y2 = _column_at(tab, st, i + 2, c)
    y3 = _column_at(tab, st, i + 3, c)
    a, b = lo - i, lo - i + 1.0  # the cell in the stencil's coordinate r
    ya, yb = _column_at(tab, st, lo, c), _column_at(tab, st, lo + 1, c)
    r = a + (h - ya) / (yb - ya) if yb != ya else a
    for _ in range(30):  # Newton on the cubic, kept in the cell (bisection where it leaves)
        w0 = -(r - 1.0) * (r - 2.0) * (r - 3.0) / 6.0
        w1 = r * (r - 2.0) * (r - 3.0) / 2.0
        w2 = -r * (r - 1.0) * (r - 3.0) / 2.0
        w3 = r * (r - 1.0) * (r - 2.0) / 6.0
        g = w0 * y0 + w1 * y1 + w2 * y2 + w3 * y3 - h
        d0 = -(3.0 * r * r - 12.0 * r + 11.0) / 6.0
        d1 = (3.0 * r * r - 10.0 * r + 6.0) / 2.0
        d2 = -(3.0 * r * r - 8.0 * r + 3.0) / 2.0
        d3 = (3.0 * r * r - 6.0 * r + 2.0) / 6.0
        dg = d0 * y0 + d1 * y1 + d2 * y2 + d3 * y3
        if sign * g > 0.0:
            b = r
        else:
            a = r
        step = g / dg if dg != 0.0 else math.inf
        r_new = r - step
        if not (a <= r_new <= b):
            r_new = 0.5 * (a + b)
        if abs(r_new - r) < 1e-13:
            r = r_new
            break
        r = r_new
    return (i + r) / (n - 1)


@jit(counted=False)
def ph_temperature(meta, sat, vapour, liquid, p: float, h: float) -> float:
    """Temperature [K] at ``(p, h)``: the saturation temperature inside the dome, else the exact
    inverse of :func:`pt_state`'s enthalpy; NaN outside the tables."""
    st = pressure_stencil(meta, p)
    if st[0] < 0 or h != h:
        return math.nan
    T_sat = sat_column(sat, st, _SAT_T)
    h_l = sat_column(sat, st, _SAT_HL)
    h_v = sat_column(sat, st, _SAT_HV)
    if h_l <= h <= h_v:
        return T_sat
    if h > h_v:
        t = _invert_depth(meta, vapour, st, h)
        return T_sat + t * t * (meta[_TTOP] - T_sat)
    t = _invert_depth(meta, liquid, st, h)
    return T_sat - t * t * (T_sat - meta[_TBOT])


@jit(counted=False)
def _depth_column(meta, tab, st, t: float, c: int) -> float:
    """Single-phase column ``c`` at depth ``t`` (one column of :func:`_phase_at`)."""
    n = int(meta[_NT])
    j, v0, v1, v2, v3 = _stencil(t * (n - 1), n)
    return (
        v0 * _column_at(tab, st, j, c)
        + v1 * _column_at(tab, st, j + 1, c)
        + v2 * _column_at(tab, st, j + 2, c)
        + v3 * _column_at(tab, st, j + 3, c)
    )


@jit(counted=False)
def ps_enthalpy(meta, sat, vapour, liquid, p: float, s: float) -> float:
    """Enthalpy [J/kg] at ``(p [Pa], s [J/(kg K)])``: in a single phase the exact inverse of
    :func:`pt_state`'s entropy carried to its enthalpy; inside the dome the mixture's,
    ``h = h_l + x (h_v - h_l)`` at ``x = (s - s_l) / (s_v - s_l)`` (the saturated entropies are
    the single-phase tables' first columns). NaN outside the tables."""
    st = pressure_stencil(meta, p)
    if st[0] < 0 or s != s:
        return math.nan
    s_l = _column_at(liquid, st, 0, _COL_S)
    s_v = _column_at(vapour, st, 0, _COL_S)
    if s_l <= s <= s_v:
        h_l = sat_column(sat, st, _SAT_HL)
        return h_l + (s - s_l) / (s_v - s_l) * (sat_column(sat, st, _SAT_HV) - h_l)
    tab = vapour if s > s_v else liquid
    t = _invert_column(meta, tab, st, s, _COL_S)
    if t != t:
        return math.nan
    return _depth_column(meta, tab, st, t, _COL_H)


@jit(counted=False)
def _ps_many(meta, sat, vapour, liquid, p, s, out):
    for n in range(p.size):
        out[n] = ps_enthalpy(meta, sat, vapour, liquid, p[n], s[n])


@jit
def _pt_many(meta, sat, vapour, liquid, p, T, out):
    row = np.empty(out.shape[1])
    for n in range(p.size):
        pt_state(meta, sat, vapour, liquid, p[n], T[n], row)
        out[n, :] = row


@jit(counted=False)
def _ph_many(meta, sat, vapour, liquid, p, h, out):
    for n in range(p.size):
        out[n] = ph_temperature(meta, sat, vapour, liquid, p[n], h[n])


@jit
def _sat_many(meta, sat, p, out):
    row = np.empty(out.shape[1])
    for n in range(p.size):
        saturation(meta, sat, p[n], row)
        out[n, :] = row


# --- the tables behind Fluid's interface -------------------------------------------------------


class TabulatedCurve:
    """:class:`evtms.fluid.SaturationCurve`'s interface on :class:`PropertyTables` (cubic, not linear)."""

    def __init__(self, fluid: TabulatedFluid) -> None:
        self._fluid = fluid

    def _col(self, name: str, p: np.ndarray) -> np.ndarray:
        return self._fluid.saturation(p)[name]

    def temperature(self, p: np.ndarray) -> np.ndarray:
        """Saturation temperature [K] at ``p`` [Pa]."""
        return self._col("T", p)

    def liquid_enthalpy(self, p: np.ndarray) -> np.ndarray:
        """Saturated-liquid enthalpy [J/kg] at ``p`` [Pa]."""
        return self._col("h_l", p)

    def vapour_enthalpy(self, p: np.ndarray) -> np.ndarray:
        """Saturated-vapour enthalpy [J/kg] at ``p`` [Pa]."""
        return self._col("h_v", p)


class TabulatedFluid:
    """A :class:`evtms.fluid.Fluid` look-alike answering from :class:`PropertyTables`.

    It answers what the coils ask (``state`` for the pairs ``"PT"`` and
    ``"PH"``, ``saturation``, ``saturation_curve``) with the compiled kernels'
    arithmetic, so that the NumPy coil path fed with it is the compiled
    march's reference to round-off; states outside the tables are NaN.

    Parameters
    ----------
    fluid : Fluid
        The CoolProp fluid the tables are built from (its constants are copied).
    """

    def __init__(self, fluid: Fluid) -> None:
        self.tables = tables_for(fluid)
        for name in ("name", "backend", "p_crit", "T_crit", "T_triple", "T_max", "p_max", "molar_mass", "p_triple"):
            setattr(self, name, getattr(fluid, name))

    def __repr__(self) -> str:
        return f"TabulatedFluid({self.name!r}, backend={self.backend!r})"

    def state(
        self, pair: str, a: np.ndarray | float, b: np.ndarray | float, outputs: tuple[str, ...] = ("T", "H", "D")
    ) -> dict[str, np.ndarray]:
        """:meth:`evtms.fluid.Fluid.state` for ``"PT"`` (outputs of :data:`_PHASE_KEYS` and ``T``),
        ``"PH"`` (outputs ``T`` and those of ``"PT"`` at that temperature) and ``"PS"`` (``H``
        from :func:`ps_enthalpy`, then as ``"PH"``; inside the dome only ``H`` and ``T`` are
        the mixture's)."""
        if pair not in ("PT", "PH", "PS"):
            raise ValueError(f"input pair {pair!r} is not one of ('PT', 'PH', 'PS') for tabulated properties")
        p, x = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
        shape = p.shape
        # Writable copies where the inputs are read-only: numba compiles once per argument type.
        p, x = (np.require(v.reshape(-1), requirements=("C", "W")) for v in (p, x))
        meta, sat, vap, liq = self.tables.arrays
        if pair == "PS":  # to the enthalpy, then as "PH"
            h = np.empty(p.size)
            _ps_many(meta, sat, vap, liq, p, x, h)
            if outputs == ("H",):
                return {"H": h.reshape(shape)}
            pair, x = "PH", h
        if pair == "PH":
            T = np.empty(p.size)
            _ph_many(meta, sat, vap, liq, p, x, T)
        else:
            T = x
        cols = np.empty((p.size, len(PHASE_COLUMNS)))
        if any(o != "T" for o in outputs):
            _pt_many(meta, sat, vap, liq, p, T, cols)
        out = {}
        for o in outputs:
            out[o] = (T.copy() if o == "T" else cols[:, _PHASE_KEYS.index(o)].copy()).reshape(shape)
        return out

    def saturation(self, p: np.ndarray | float) -> dict[str, np.ndarray]:
        """Saturated liquid and vapour properties at ``p`` [Pa], keys :data:`SAT_COLUMNS`."""
        p = np.asarray(p, float)
        flat = np.ascontiguousarray(p.reshape(-1))
        out = np.empty((flat.size, len(SAT_COLUMNS)))
        _sat_many(self.tables.meta, self.tables.sat, flat, out)
        return {c: out[:, k].reshape(p.shape) for k, c in enumerate(SAT_COLUMNS)}

    @functools.cached_property
    def _curve(self) -> TabulatedCurve:
        return TabulatedCurve(self)

    def saturation_curve(self) -> TabulatedCurve:
        """The saturation curve of the tables."""
        return self._curve
