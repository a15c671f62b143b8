"""Refrigerant and humid-air properties: the one module that talks to CoolProp.

Everything here is vectorised over NumPy arrays. CoolProp's Python wrapper has
no array version of the low-level ``AbstractState.update``, so the loop over
points runs here, once per *unique* input pair (bench grids repeat the same
pressures and temperatures many times), at about 5 us a state with HEOS and
0.5 us with the BICUBIC&HEOS tables. HEOS's (p, h) flash costs 35-50 us, and
the coils' outlets are all distinct states: clearly single-phase ones are
solved by Newton's method on (p, T) updates with the phase imposed instead
(two or three of them, to well below 1e-6 K). A state CoolProp cannot
evaluate becomes NaN; callers turn NaN into a ``status`` code instead of
crashing a sweep.

References
----------
Bell, I. H., Wronski, J., Quoilin, S., Lemort, V. (2014). Pure and pseudo-pure
fluid thermophysical property evaluation and the open-source thermophysical
property library CoolProp. Ind. Eng. Chem. Res. 53(6), 2498-2508.
Tillner-Roth, R., Baehr, H. D. (1994). An international standard formulation
for the thermodynamic properties of 1,1,1,2-tetrafluoroethane (HFC-134a).
J. Phys. Chem. Ref. Data 23, 657-729 (the R134a equation of state in HEOS).
Herrmann, S., Kretzschmar, H.-J., Gatley, D. P. (2009). Thermodynamic
properties of real moist air, dry air, steam, water, and ice (ASHRAE RP-1485),
HVAC&R Research 15(5), 961-986 (CoolProp's ``HAPropsSI``).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from evtms._jit import kernel_array
from evtms.errors import EvtmsInputError

#: Enthalpy margin [J/kg] from the tabulated saturation curve (within 30 J/kg of CoolProp)
#: inside which a state is left to CoolProp's own (p, h) flash.
FAST_PH_MARGIN = 200.0
#: Newton stops after a temperature step below this [K]; the error left is far smaller.
FAST_PH_TOLERANCE = 1e-4
#: Newton steps before a state is handed back to the flash.
FAST_PH_ITERATIONS = 8

#: Input pairs accepted by :meth:`Fluid.state`, as (first, second) argument.
INPUT_PAIRS = ("PT", "PH", "PS", "PQ", "TQ")
#: Outputs accepted by :meth:`Fluid.state` and their AbstractState methods.
OUTPUTS = {
    "T": "T",
    "P": "p",
    "H": "hmass",
    "S": "smass",
    "D": "rhomass",
    "CP": "cpmass",
    "CV": "cvmass",
    "MU": "viscosity",
    "K": "conductivity",
    "Q": "Q",
    "SIGMA": "surface_tension",
}


@functools.cache
def _cp() -> Any:
    """Import CoolProp on first use (the import alone costs about 2 s)."""
    import CoolProp.CoolProp as CP

    return CP


def coolprop_version() -> str:
    """Version string of the CoolProp library in use."""
    return str(_cp().get_global_param_string("version"))


def _unique_rows(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique (a, b) pairs and the inverse index that rebuilds the inputs.

    The pairs are packed into complex numbers, which NumPy sorts natively
    (real part, then imaginary); ``np.unique(axis=0)`` on a 2-column array
    is several times slower.
    """
    packed = np.asarray(a, np.float64) + 1j * np.asarray(b, np.float64)
    uniq, inverse = np.unique(packed, return_inverse=True)
    return np.stack([uniq.real, uniq.imag], axis=1), inverse.reshape(-1)


class Fluid:
    """Vectorised thermodynamic and transport properties of a pure fluid.

    Parameters
    ----------
    name : str
        CoolProp fluid name, ``"R134a"`` by default.
    backend : str
        CoolProp backend: ``"HEOS"`` (full equation of state, default) or a
        tabular one such as ``"BICUBIC&HEOS"`` (about 10x faster; its tables
        are built and cached on first use; bench outputs stay within 0.5 % of
        HEOS, checked in the tests).

    Raises
    ------
    EvtmsInputError
        CoolProp cannot load ``name`` with ``backend`` (an unknown fluid, a
        mixture without its fractions); one line naming both.
    """

    def __init__(self, name: str = "R134a", backend: str = "HEOS") -> None:
        CP = _cp()
        try:
            self._state = st = CP.AbstractState(backend, name)
            # A mixture without fractions (``R134a&R32``) loads and fails on its first property.
            self.p_crit = float(st.p_critical())
            self.T_crit = float(st.T_critical())
            self.T_triple = float(st.Ttriple())
            self.T_max = float(st.Tmax())
            self.p_max = float(st.pmax())
            self.molar_mass = float(st.molar_mass())
        except (ValueError, RuntimeError) as exc:  # unknown fluid or backend
            reason = " ".join(str(exc).split())
            raise EvtmsInputError(
                f"fluid {name!r} with backend {backend!r} cannot be loaded by CoolProp ({reason}); "
                'allowed: a pure fluid CoolProp knows, such as "R134a"'
            ) from None
        self.name = name
        self.backend = backend
        self._pairs = {
            "PT": (CP.PT_INPUTS, False),
            "PH": (CP.HmassP_INPUTS, True),
            "PS": (CP.PSmass_INPUTS, False),
            "PQ": (CP.PQ_INPUTS, False),
            "TQ": (CP.QT_INPUTS, True),
        }
        # CoolProp does not report p_triple for every backend; take it from a
        # saturated state at the triple-point temperature.
        self.p_triple = float(self.state("TQ", self.T_triple, 0.0, ("P",))["P"])

    def __repr__(self) -> str:
        return f"Fluid({self.name!r}, backend={self.backend!r})"

    def state(
        self,
        pair: str,
        a: np.ndarray | float,
        b: np.ndarray | float,
        outputs: tuple[str, ...] = ("T", "H", "D"),
    ) -> dict[str, np.ndarray]:
        """Evaluate states given by an input pair, element-wise over arrays.

        Parameters
        ----------
        pair : str
            One of ``"PT"`` (p [Pa], T [K]), ``"PH"`` (p [Pa], h [J/kg]),
            ``"PS"`` (p [Pa], s [J/(kg K)]), ``"PQ"`` (p [Pa], quality [1]),
            ``"TQ"`` (T [K], quality [1]).
        a, b : array_like
            The two inputs in the order the pair names them; broadcast together.
        outputs : tuple of str
            Keys of :data:`OUTPUTS`.

        Returns
        -------
        dict of str to numpy.ndarray
            One array per output, shaped like the broadcast inputs; NaN where
            CoolProp could not evaluate the state (outside its range, or a
            transport property in the two-phase dome).
        """
        if pair not in INPUT_PAIRS:
            raise ValueError(f"input pair {pair!r} is not one of {INPUT_PAIRS}")
        key, swap = self._pairs[pair]
        a_arr, b_arr = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
        shape = a_arr.shape
        a_flat, b_flat = a_arr.reshape(-1), b_arr.reshape(-1)
        uniq, inverse = _unique_rows(a_flat, b_flat)
        # HEOS extrapolates beyond its validity range without complaint; hold
        # every state to the equation of state's published limits instead.
        T_in = {"PT": uniq[:, 1], "TQ": uniq[:, 0]}.get(pair)
        p_in = uniq[:, 0] if pair[0] == "P" else None
        bad = np.zeros(len(uniq), dtype=bool)
        if T_in is not None:
            bad |= (T_in < self.T_triple) | (T_in > self.T_max)
        if p_in is not None:
            bad |= (p_in <= 0.0) | (p_in > self.p_max)
        uniq[bad] = np.nan
        getters = [getattr(self._state, OUTPUTS[o]) for o in outputs]
        values = np.full((len(outputs), len(uniq)), np.nan)
        todo = np.isfinite(uniq).all(axis=1)
        if pair == "PH" and self.backend == "HEOS":
            todo &= ~self._single_phase_ph(uniq, outputs, getters, values)
        update = self._state.update
        for i in np.nonzero(todo)[0]:
            x, y = uniq[i]
            try:
                if swap:
                    update(key, y, x)
                else:
                    update(key, x, y)
                for j, get in enumerate(getters):
                    values[j, i] = get()
            except ValueError:
                # Outside CoolProp's range, or a property undefined in the dome:
                # the remaining outputs of this state stay NaN. A flash that fails near the
                # critical point can leave a phase imposed on the state: clear it, or the
                # next states of any pair would be solved in that phase.
                self._state.unspecify_phase()
                continue
        if "T" in outputs:  # e.g. a (p, h) state hotter than the EOS allows
            t = values[outputs.index("T")]
            values[:, (t < self.T_triple) | (t > self.T_max)] = np.nan
        return {o: values[j][inverse].reshape(shape) for j, o in enumerate(outputs)}

    def saturation(self, p: np.ndarray | float) -> dict[str, np.ndarray]:
        """Saturated liquid and vapour properties at pressure ``p`` [Pa].

        Returns
        -------
        dict of str to numpy.ndarray
            ``T`` [K]; for liquid (suffix ``_l``) and vapour (``_v``):
            ``h`` [J/kg], ``s`` [J/(kg K)], ``rho`` [kg/m3], ``cp`` [J/(kg K)],
            ``mu`` [Pa s], ``k`` [W/(m K)]; and ``sigma`` [N/m]. NaN at or
            above the critical pressure and below the triple point.
        """
        p = np.asarray(p, dtype=float)
        p_ok = np.where((p > self.p_triple) & (p < self.p_crit), p, np.nan)
        keys = ("T", "H", "S", "D", "CP", "MU", "K", "SIGMA")
        liq = self.state("PQ", p_ok, 0.0, keys)
        vap = self.state("PQ", p_ok, 1.0, keys[1:-1])
        names = {"H": "h", "S": "s", "D": "rho", "CP": "cp", "MU": "mu", "K": "k"}
        out = {"T": liq["T"], "sigma": liq["SIGMA"]}
        for key, short in names.items():
            out[f"{short}_l"] = liq[key]
            out[f"{short}_v"] = vap[key]
        return out

    def _single_phase_ph(
        self, uniq: np.ndarray, outputs: tuple[str, ...], getters: list, values: np.ndarray
    ) -> np.ndarray:
        """Solve clearly single-phase (p, h) states by Newton's method on temperature.

        CoolProp's (p, h) flash costs 35-50 us a state with HEOS, a (p, T)
        update with the phase imposed about 6 us. From a tabulated guess
        (:class:`VapourTable` for vapour, the saturated-liquid curve for
        liquid) ``T <- T - (h(p, T) - h) / cp(p, T)`` converges quadratically;
        it stops once a step is below :data:`FAST_PH_TOLERANCE`, where the
        remaining error is of order ``cp'/(2 cp) dT^2``, under 1e-9 K. Which
        states take this path, and their guess, depend on the state alone. Fills
        ``values`` (outputs by row) at the solved states and returns their
        mask; states near saturation (within :data:`FAST_PH_MARGIN` of the
        tabulated curve), above 90 % of the critical pressure, or not
        converged are left to the flash.
        """
        CP = _cp()
        p, h = uniq[:, 0], uniq[:, 1]
        n = len(uniq)
        solved = np.zeros(n, dtype=bool)
        curve = self.saturation_curve()
        with np.errstate(invalid="ignore"):
            h_l, h_v = curve.liquid_enthalpy(p), curve.vapour_enthalpy(p)
            usable = np.isfinite(h_l + h_v) & (p < 0.9 * self.p_crit)
            vapour = usable & (h > h_v + FAST_PH_MARGIN)
            liquid = usable & (h < h_l - FAST_PH_MARGIN)
        guess = np.full(n, np.nan)
        if liquid.any():  # the saturated liquid of the same enthalpy: off by the pressure's effect
            guess[liquid] = np.interp(h[liquid], curve.h_l, curve.T)
        if vapour.any():
            table = self._guess_table()
            T_sat, h_v_table = table.saturation(p[vapour])
            guess[vapour] = T_sat + table.superheat_of(p[vapour], h[vapour] - h_v_table)
        st = self._state
        only_T = outputs == ("T",)
        for phase, mask in ((CP.iphase_gas, vapour), (CP.iphase_liquid, liquid)):
            idx = np.nonzero(mask & np.isfinite(guess))[0]
            if idx.size == 0:
                continue
            st.specify_phase(phase)
            try:
                for i in idx:
                    solved[i] = _newton_temperature(
                        st, CP.PT_INPUTS, p[i], h[i], guess[i], (self.T_triple, self.T_max), only_T, getters, values, i
                    )
            finally:
                st.unspecify_phase()
        return solved

    def _guess_table(self) -> VapourTable:
        """A coarse :class:`VapourTable` (within about 0.1 K), the vapour states' first guess.

        Built on first use from about 5,000 states (some 30 ms). The guess is a
        function of the state alone, so a state's result does not depend on the
        call it came in (a sweep gives the same numbers in one process or many).
        Kept per fluid name and backend for the process: a cycle solver builds a
        new :class:`Fluid` per call."""
        key = ("guess", self.name, self.backend)
        if key not in _TABLES:
            _TABLES[key] = VapourTable(self, n=120, superheat_max=120.0, step=3.0)
        return _TABLES[key]

    def saturation_curve(self) -> SaturationCurve:
        """The fluid's tabulated :class:`SaturationCurve`, built on first use in a process (per
        fluid name and backend: some 0.1 s, which a direct cycle point paid on every call)."""
        key = ("curve", self.name, self.backend)
        if key not in _TABLES:
            _TABLES[key] = SaturationCurve(self)
        return _TABLES[key]

    def saturation_pressure(self, T: np.ndarray | float) -> np.ndarray:
        """Saturation pressure [Pa] at temperature ``T`` [K]; NaN outside the dome."""
        T = np.asarray(T, dtype=float)
        T_ok = np.where((T >= self.T_triple) & (T < self.T_crit), T, np.nan)
        return self.state("TQ", T_ok, 0.0, ("P",))["P"]


#: The tables :meth:`Fluid.saturation_curve` and :meth:`Fluid._guess_table` built, by kind,
#: fluid name and backend (functions of those alone).
_TABLES: dict[tuple[str, str, str], Any] = {}


def _newton_temperature(
    st, key, p: float, h: float, T: float, bounds: tuple[float, float], only_T: bool, getters, values, i: int
) -> bool:
    """Newton on T for one (p, h) state from ``T`` [K] (see ``Fluid._single_phase_ph``); the outputs
    go to column ``i`` of ``values``. False, with the column left NaN, if it did not converge, the
    solution lies outside the equation of state's temperatures ``bounds`` [K] (the flash decides
    those, as before), or CoolProp refused a state."""
    try:
        for _ in range(FAST_PH_ITERATIONS):
            st.update(key, p, T)
            step = (st.hmass() - h) / st.cpmass()
            T -= step
            if abs(step) < FAST_PH_TOLERANCE:
                break
        else:
            return False
        if not (bounds[0] <= T <= bounds[1]):
            return False
        if only_T:
            values[0, i] = T
            return True
        st.update(key, p, T)
        for j, get in enumerate(getters):
            values[j, i] = get()
        return True
    except ValueError:
        values[:, i] = np.nan  # a getter that failed part-way
        return False


def quality(h: np.ndarray, h_l: np.ndarray, h_v: np.ndarray) -> np.ndarray:
    """Thermodynamic quality ``(h - h_l) / (h_v - h_l)`` [1].

    Negative for subcooled liquid, above 1 for superheated vapour, as the LUT
    format defines ``x_out``.
    """
    return (np.asarray(h) - h_l) / (h_v - h_l)


# --------------------------------------------------------------------------
# Humid air (air side of the coils)
# --------------------------------------------------------------------------


def _haprops(output: str, *args: Any) -> np.ndarray:
    """``HAPropsSI`` over arrays; NaN where CoolProp fails."""
    CP = _cp()
    # Scalars as floats: CoolProp before 8 takes a number or a sized array, not a 0-d array.
    args = tuple(float(a) if isinstance(a, np.ndarray) and a.ndim == 0 else a for a in args)
    try:
        return np.asarray(CP.HAPropsSI(output, *args), dtype=float)
    except ValueError:
        pass
    # Fall back to element-wise so that one bad point does not spoil the rest.
    names, vals = args[0::2], np.broadcast_arrays(*[np.asarray(v, dtype=float) for v in args[1::2]])
    out = np.full(vals[0].shape, np.nan)
    for idx in np.ndindex(out.shape):
        call = [x for pair in zip(names, [v[idx] for v in vals], strict=True) for x in pair]
        try:
            out[idx] = CP.HAPropsSI(output, *call)
        except ValueError:
            continue
    return out


def humid_air_inlet(T: float, p: float, RH: float) -> dict[str, float]:
    """Properties of moist air entering a coil.

    Parameters
    ----------
    T : float
        Dry-bulb temperature [K].
    p : float
        Total pressure [Pa].
    RH : float
        Relative humidity [1].

    Returns
    -------
    dict of str to float
        ``w`` humidity ratio [kg/kg dry air], ``h`` enthalpy [J/kg dry air],
        ``cp`` heat capacity [J/(kg dry air K)], ``rho`` density of the
        mixture [kg/m3], ``mu`` viscosity [Pa s], ``k`` conductivity
        [W/(m K)], ``T_dew`` dew point [K], ``Pr`` Prandtl number [1].
    """
    return dict(_humid_air_inlet(float(T), float(p), float(RH)))


@functools.lru_cache(maxsize=4096)
def _humid_air_inlet(T: float, p: float, RH: float) -> tuple[tuple[str, float], ...]:
    """:func:`humid_air_inlet`, remembered: every chunk of a sweep meets the same few hundred
    entering-air states (eight ``HAPropsSI`` calls, some 0.2 ms each), 10 % of an evaporator chunk."""
    args = ("T", T, "P", p, "R", RH)
    w = float(_haprops("W", *args))
    cp = float(_haprops("C", *args))
    mu = float(_haprops("mu", *args))
    k = float(_haprops("k", *args))
    v_ha = float(_haprops("Vha", *args))  # m3 per kg of humid air
    cp_ha = float(_haprops("cp_ha", *args))  # J/(kg humid air K)
    return (
        ("w", w),
        ("h", float(_haprops("H", *args))),
        ("cp", cp),
        ("rho", 1.0 / v_ha),
        ("mu", mu),
        ("k", k),
        ("T_dew", float(_haprops("Tdp", *args))),
        ("Pr", cp_ha * mu / k),
    )


def humid_air_enthalpy(T: np.ndarray, w: np.ndarray, p: float) -> np.ndarray:
    """Moist-air enthalpy [J/kg dry air] at temperature ``T`` [K], humidity ratio ``w``."""
    return _haprops("H", "T", np.asarray(T, float), "W", np.asarray(w, float), "P", p)


def humid_air_temperature(
    h: np.ndarray, w: np.ndarray, p: float, w_common: np.ndarray | float | None = None
) -> np.ndarray:
    """Dry-bulb temperature [K] of moist air with enthalpy ``h`` [J/kg dry air], ratio ``w``.

    Points whose humidity ratio equals ``w_common`` (their inlet value: air
    heated or cooled without condensing, the usual case) are inverted on a
    cached line of ``HAPropsSI`` enthalpies at that humidity ratio, every
    0.05 K (within 1e-4 J/kg of ``HAPropsSI``). The others (air that lost
    moisture) are inverted on a cached ``HAPropsSI`` table every 0.25 K and
    every 0.001 kg/kg, interpolated linearly in both (within 0.02 J/kg; a
    direct ``HAPropsSI`` inversion costs 75 us a point).
    """
    h, w = np.broadcast_arrays(np.asarray(h, float), np.asarray(w, float))
    out = np.full(h.shape, np.nan)
    ok = np.isfinite(h) & np.isfinite(w)
    tabulated = np.zeros(h.shape, bool)
    if w_common is not None:
        w_common = np.broadcast_to(np.asarray(w_common, float), h.shape)
        tabulated = ok & (w == w_common)
        common = w_common[tabulated]
        one = common.size and (common == common[0]).all()  # a cycle solver's call: one air state
        for wc in common[:1] if one else np.unique(common):
            sel = tabulated & (w_common == wc)
            out[sel] = _constant_humidity_line(float(p), float(wc)).temperature(h[sel])
    rest = ok & ~tabulated
    if rest.any():
        out[rest] = _invert_humid_air_table(h[rest], w[rest], float(p))
    return out


_TABLE_T = np.arange(200.0, 400.0 + 0.125, 0.25)
_TABLE_DW = 0.001


@functools.lru_cache(maxsize=8)
def _humid_air_table(p: float, n_w: int) -> np.ndarray:
    """Moist-air enthalpy [J/kg dry air] on (w, T): w = 0, 0.001, ... (n_w lines), T in _TABLE_T."""
    w = np.arange(n_w) * _TABLE_DW
    TT, WW = np.meshgrid(_TABLE_T, w)
    return _haprops("H", "T", TT.ravel(), "W", WW.ravel(), "P", p).reshape(n_w, _TABLE_T.size)


def _invert_humid_air_table(h: np.ndarray, w: np.ndarray, p: float) -> np.ndarray:
    """Temperature [K] at enthalpy ``h`` and humidity ratio ``w`` from the cached table."""
    out = np.full(h.shape, np.nan)
    ok = (w >= 0) & (w < 0.2)
    if not ok.any():
        return out
    n_w = int(np.ceil(w[ok].max() / 0.01) * 10) + 3  # table lines up to the next 0.01, and spares
    table = _humid_air_table(p, n_w)
    compiled = _compiled_inversion()
    if compiled is not None:  # the same arithmetic per point: the NumPy loop's overhead dominates a few points
        res = np.empty(int(ok.sum()))
        compiled(np.ascontiguousarray(h[ok]), np.ascontiguousarray(w[ok]), table, _TABLE_T, _TABLE_DW, res)
        out[ok] = res
        return out
    # Quadratic (3-line Lagrange) interpolation in w: h(T, w) is slightly curved in w.
    j = np.clip(np.rint(w[ok] / _TABLE_DW).astype(np.intp), 1, n_w - 2)
    s = w[ok] / _TABLE_DW - j
    c_m, c_0, c_p = 0.5 * s * (s - 1.0), 1.0 - s * s, 0.5 * s * (s + 1.0)

    def line(k: np.ndarray) -> np.ndarray:
        return c_m * table[j - 1, k] + c_0 * table[j, k] + c_p * table[j + 1, k]

    target = h[ok]
    lo = np.zeros(target.size, np.intp)
    hi = np.full(target.size, _TABLE_T.size - 1, np.intp)
    while np.any(hi - lo > 1):  # bisection on the (monotonic) enthalpy line
        mid = (lo + hi) // 2
        below = line(mid) <= target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    h_lo, h_hi = line(lo), line(hi)
    with np.errstate(divide="ignore", invalid="ignore"):  # targets beyond the table: NaN just below
        T = _TABLE_T[lo] + (target - h_lo) / (h_hi - h_lo) * (_TABLE_T[hi] - _TABLE_T[lo])
    inside = (target >= line(np.zeros_like(lo))) & (target <= line(np.full_like(lo, _TABLE_T.size - 1)))
    out[ok] = np.where(inside, T, np.nan)
    return out


def _invert_points(
    h: np.ndarray, w: np.ndarray, table: np.ndarray, T_grid: np.ndarray, dw: float, out: np.ndarray
) -> None:
    """:func:`_invert_humid_air_table`'s interpolation and bisection point by point (compiled by
    :func:`_compiled_inversion`), operation for operation: ``w`` within 0-0.2."""
    n_w, n_T = table.shape
    for n in range(h.size):
        j = min(max(int(np.rint(w[n] / dw)), 1), n_w - 2)
        s = w[n] / dw - j
        c_m, c_0, c_p = 0.5 * s * (s - 1.0), 1.0 - s * s, 0.5 * s * (s + 1.0)
        target = h[n]
        first = c_m * table[j - 1, 0] + c_0 * table[j, 0] + c_p * table[j + 1, 0]
        last = c_m * table[j - 1, n_T - 1] + c_0 * table[j, n_T - 1] + c_p * table[j + 1, n_T - 1]
        if not (first <= target <= last):
            out[n] = np.nan
            continue
        lo, hi = 0, n_T - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if c_m * table[j - 1, mid] + c_0 * table[j, mid] + c_p * table[j + 1, mid] <= target:
                lo = mid
            else:
                hi = mid
        h_lo = c_m * table[j - 1, lo] + c_0 * table[j, lo] + c_p * table[j + 1, lo]
        h_hi = c_m * table[j - 1, hi] + c_0 * table[j, hi] + c_p * table[j + 1, hi]
        out[n] = T_grid[lo] + (target - h_lo) / (h_hi - h_lo) * (T_grid[hi] - T_grid[lo])


@functools.cache
def _compiled_inversion():
    """:func:`_invert_points` compiled, or None without numba (the NumPy loop then serves).
    Compiled on first use, so importing this module does not import numba."""
    from evtms._jit import jit, numba_enabled

    return jit(_invert_points) if numba_enabled() else None


#: Nodes [K] of the constant-humidity lines, and the nodes a line computes at a time.
_LINE_T = np.arange(200.0, 460.0 + 0.025, 0.05)
_LINE_BLOCK = 100


class _HumidityLine:
    """``HAPropsSI`` enthalpies of moist air at fixed humidity ratio ``w`` on :data:`_LINE_T`,
    computed a block of nodes at a time where queries land.

    The whole line is 5,201 ``HAPropsSI`` states (some 0.2 s), of which a coil's leaving air
    needs a few hundred; a cycle solver meets a new line with every entering-air state.
    :meth:`temperature` interpolates within the computed nodes only where the query lies
    between two of them, so it gives what ``np.interp`` on the whole line gives.
    """

    def __init__(self, p: float, w: float) -> None:
        self.p, self.w = p, w
        self.h = np.full(_LINE_T.size, np.nan)
        self.done = np.zeros(-(-_LINE_T.size // _LINE_BLOCK), bool)

    def _fill(self, first: int, last: int) -> None:
        for b in range(first, last + 1):
            if not self.done[b]:
                nodes = slice(b * _LINE_BLOCK, min((b + 1) * _LINE_BLOCK, _LINE_T.size))
                self.h[nodes] = _haprops("H", "T", _LINE_T[nodes], "W", self.w, "P", self.p)
                self.done[b] = True

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] at enthalpy ``h`` [J/kg dry air] (NaN outside the line, 200-460 K)."""
        h = np.asarray(h, float)
        ok = np.isfinite(h)
        if not ok.any():
            return np.full(h.shape, np.nan)
        # First guess of the blocks from ASHRAE's h = 1006 t + w (2.501e6 + 1860 t) (t in degC).
        t = (h[ok] - 2.501e6 * self.w) / (1006.0 + 1860.0 * self.w) + 273.15
        last_block = self.done.size - 1
        lo, hi = (int(np.clip((x - _LINE_T[0]) / 0.05 // _LINE_BLOCK, 0, last_block)) for x in (t.min(), t.max()))
        while True:
            self._fill(lo, hi)
            start, stop = lo * _LINE_BLOCK, min((hi + 1) * _LINE_BLOCK, _LINE_T.size)
            seg = self.h[start:stop]
            below = lo > 0 and h[ok].min() < seg[0]
            above = hi < last_block and h[ok].max() > seg[-1]
            if not (below or above):
                return np.interp(h, seg, _LINE_T[start:stop], left=np.nan, right=np.nan)
            lo, hi = lo - below, hi + above


@functools.lru_cache(maxsize=256)
def _constant_humidity_line(p: float, w: float) -> _HumidityLine:
    """The :class:`_HumidityLine` of moist air at humidity ratio ``w`` and pressure ``p``, kept."""
    return _HumidityLine(p, w)


class SaturatedAir:
    """Enthalpy and humidity ratio of saturated moist air as functions of T.

    The wet-coil method needs ``h_sat(T)`` and its inverse at many surface
    temperatures; the curve is tabulated once per pressure from ``HAPropsSI``
    every 0.05 K between -60 degC and 60 degC (over ice below 0 degC) and
    interpolated linearly, which keeps it within 1e-3 J/kg of ``HAPropsSI``.
    """

    def __init__(self, p: float, T_lo: float = 213.15, T_hi: float = 333.15, step: float = 0.05) -> None:
        self.p = p
        self.T = np.arange(T_lo, T_hi + step / 2, step)
        self.h = _haprops("H", "T", self.T, "P", p, "R", 1.0)
        self.w = _haprops("W", "T", self.T, "P", p, "R", 1.0)

    def enthalpy(self, T: np.ndarray) -> np.ndarray:
        """Saturated-air enthalpy [J/kg dry air] at ``T`` [K] (NaN outside the table)."""
        return np.interp(T, self.T, self.h, left=np.nan, right=np.nan)

    def humidity_ratio(self, T: np.ndarray) -> np.ndarray:
        """Saturation humidity ratio [kg/kg dry air] at ``T`` [K]."""
        return np.interp(T, self.T, self.w, left=np.nan, right=np.nan)

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] of saturated air with enthalpy ``h`` [J/kg dry air]."""
        return np.interp(h, self.h, self.T, left=np.nan, right=np.nan)

    def dew_point(self, w: np.ndarray) -> np.ndarray:
        """Dew point [K] of air with humidity ratio ``w`` [kg/kg dry air]: where saturation holds ``w``.

        Air drier than the table's coldest saturated state (about 6.7e-6 kg/kg at
        -60 degC and 1 atm) gets ``-inf``: its dew point is below any surface a
        refrigerant coil reaches, which is all a coil model needs. NaN above the
        table's warmest state.
        """
        return np.interp(w, self.w, self.T, left=-np.inf, right=np.nan)


@functools.lru_cache(maxsize=8)
def saturated_air(p: float) -> SaturatedAir:
    """The cached :class:`SaturatedAir` curve at total pressure ``p`` [Pa]."""
    return SaturatedAir(p)


def water_liquid_enthalpy(T: np.ndarray) -> np.ndarray:
    """Enthalpy [J/kg] of liquid condensate at ``T`` [K], on the IAPWS-95 reference.

    ``HAPropsSI`` takes its water properties on the IAPWS-95 reference (zero
    internal energy and entropy of the liquid at the triple point, 273.16 K),
    so this enthalpy closes the moist-air energy balance. A constant
    cp = 4186 J/(kg K) is within 0.4 kJ/kg of IAPWS-95 over 0-40 degC, under
    0.02 % of a coil's air-side enthalpy change. Below 0 degC the condensate
    is still taken as (supercooled) liquid; such points carry a frost flag.
    """
    return 4186.0 * (np.asarray(T, float) - 273.16)


def _tables_digest(tables: dict[str, np.ndarray]) -> str:
    """A short hash of named tables, in their order."""
    import hashlib

    digest = hashlib.sha256()
    for table in tables.values():
        digest.update(np.ascontiguousarray(table).tobytes())
    return digest.hexdigest()[:16]


class SaturationCurve:
    """Saturation properties tabulated against pressure, for solvers' inner loops.

    CoolProp costs about 10 us per saturation state; a cycle solver asks for
    T_sat(p) thousands of times per operating point. The curve is tabulated
    once (2,000 log-spaced pressures between ``p_min`` and 99.5 % of the
    critical pressure) and interpolated linearly in log p, within 2 mK and
    30 J/kg of CoolProp over the whole range (checked in the tests).

    Parameters
    ----------
    fluid : Fluid
        The refrigerant.
    p_min : float
        Lowest pressure of the table [Pa].
    """

    #: The tabulated columns (:meth:`tables`, :meth:`from_tables`).
    COLUMNS = ("p", "T", "h_l", "h_v", "cp_l", "rho_l")

    def __init__(self, fluid: Fluid, p_min: float = 2e4, n: int = 2000) -> None:
        p = np.geomspace(p_min, 0.995 * fluid.p_crit, n)
        sat = fluid.saturation(p)
        self._set(
            {"p": p, "T": sat["T"], "h_l": sat["h_l"], "h_v": sat["h_v"], "cp_l": sat["cp_l"], "rho_l": sat["rho_l"]}
        )

    def _set(self, tables: dict[str, np.ndarray]) -> None:
        # Read-only whatever they came as (a cache file's are): compiled kernels read them.
        self.p, self.T = kernel_array(tables["p"]), kernel_array(tables["T"])
        self.h_l, self.h_v = kernel_array(tables["h_l"]), kernel_array(tables["h_v"])
        self.cp_l, self.rho_l = kernel_array(tables["cp_l"]), kernel_array(tables["rho_l"])
        self._log_p = kernel_array(np.log(self.p))

    def tables(self) -> dict[str, np.ndarray]:
        """The tabulated columns by name (pressures [Pa] and their saturation properties, SI)."""
        return {name: getattr(self, name) for name in self.COLUMNS}

    def digest(self) -> str:
        """A short hash of the tables (what a table derived with them depends on)."""
        return _tables_digest(self.tables())

    @classmethod
    def from_tables(cls, tables: dict[str, np.ndarray]) -> SaturationCurve:
        """A curve from :meth:`tables` (e.g. cached): no CoolProp needed."""
        curve = cls.__new__(cls)
        curve._set({name: np.asarray(tables[name], float) for name in cls.COLUMNS})
        return curve

    def _at(self, table: np.ndarray, p: np.ndarray) -> np.ndarray:
        return np.interp(np.log(np.asarray(p, float)), self._log_p, table, left=np.nan, right=np.nan)

    def temperature(self, p: np.ndarray) -> np.ndarray:
        """Saturation temperature [K] at pressure ``p`` [Pa]."""
        return self._at(self.T, p)

    def pressure(self, T: np.ndarray) -> np.ndarray:
        """Saturation pressure [Pa] at temperature ``T`` [K]."""
        return np.exp(np.interp(np.asarray(T, float), self.T, self._log_p, left=np.nan, right=np.nan))

    def liquid_enthalpy(self, p: np.ndarray) -> np.ndarray:
        """Saturated-liquid enthalpy [J/kg] at ``p`` [Pa]."""
        return self._at(self.h_l, p)

    def vapour_enthalpy(self, p: np.ndarray) -> np.ndarray:
        """Saturated-vapour enthalpy [J/kg] at ``p`` [Pa]."""
        return self._at(self.h_v, p)

    def liquid_density(self, p: np.ndarray) -> np.ndarray:
        """Saturated-liquid density [kg/m3] at ``p`` [Pa]."""
        return self._at(self.rho_l, p)

    def liquid_cp(self, p: np.ndarray) -> np.ndarray:
        """Saturated-liquid heat capacity [J/(kg K)] at ``p`` [Pa]."""
        return self._at(self.cp_l, p)


class VapourTable:
    """Superheated-vapour enthalpy above saturation, tabulated in (ln p, superheat).

    ``dh(p, dT) = h(p, T_sat(p) + dT) - h_v(p)`` [J/kg] on ``n`` log-spaced
    pressures from ``p_min`` to 95 % of the critical pressure and superheats
    from 0 to ``superheat_max`` every ``step`` K, with ``T_sat`` and ``h_v``
    on the same pressures; interpolated bilinearly (in ln p and superheat),
    within about 5 J/kg of CoolProp over the table (checked in the tests), and
    continued linearly beyond ``superheat_max``.
    The LUT cycle measures an evaporator outlet against the secondary inlet
    with it (:mod:`evtms.cycle.approach`) without importing CoolProp.

    Parameters
    ----------
    fluid : Fluid
        The refrigerant.
    p_min : float
        Lowest pressure of the table [Pa].
    n : int
        Number of pressures.
    superheat_max, step : float
        Highest superheat and superheat step [K].
    """

    #: The tabulated columns (:meth:`tables`, :meth:`from_tables`); ``dh`` is 2-D (pressure, superheat).
    COLUMNS = ("p", "T", "h_v", "superheat", "dh")

    def __init__(
        self, fluid: Fluid, p_min: float = 1e4, n: int = 400, superheat_max: float = 100.0, step: float = 0.5
    ) -> None:
        p = np.geomspace(p_min, 0.95 * fluid.p_crit, n)
        sat = fluid.state("PQ", p, 1.0, ("T", "H"))
        superheat = np.arange(0.0, superheat_max + step / 2, step)
        # PT exactly at saturation is ambiguous in CoolProp: the first column is the saturated vapour.
        T = sat["T"][:, None] + superheat[None, 1:]
        h = fluid.state("PT", np.broadcast_to(p[:, None], T.shape), T, ("H",))["H"]
        dh = np.concatenate([np.zeros((n, 1)), h - sat["H"][:, None]], axis=1)
        self._set({"p": p, "T": sat["T"], "h_v": sat["H"], "superheat": superheat, "dh": dh})

    def _set(self, tables: dict[str, np.ndarray]) -> None:
        # Read-only whatever they came as (a cache file's are): compiled kernels read them.
        self.p, self.T, self.h_v = (kernel_array(tables[k]) for k in ("p", "T", "h_v"))
        self.superheat, self.dh = kernel_array(tables["superheat"]), kernel_array(tables["dh"])
        # The grids are uniform in ln p and in superheat: a cell is found by arithmetic.
        self.log_p0 = float(np.log(self.p[0]))
        self.dlog_p = float(np.log(self.p[-1] / self.p[0]) / (self.p.size - 1))
        self.step = float(self.superheat[1] - self.superheat[0])

    def tables(self) -> dict[str, np.ndarray]:
        """The tabulated columns by name (SI)."""
        return {name: getattr(self, name) for name in self.COLUMNS}

    def digest(self) -> str:
        """A short hash of the tables (what a table derived with them depends on)."""
        return _tables_digest(self.tables())

    @classmethod
    def from_tables(cls, tables: dict[str, np.ndarray]) -> VapourTable:
        """A table from :meth:`tables` (e.g. cached): no CoolProp needed."""
        table = cls.__new__(cls)
        table._set({name: np.asarray(tables[name], float) for name in cls.COLUMNS})
        return table

    def _pressure_cell(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # The cell index and the position in it; NaN outside the table.
        u = (np.log(np.asarray(p, float)) - self.log_p0) / self.dlog_p
        u = np.where((u >= 0) & (u <= self.p.size - 1), u, np.nan)
        i = np.minimum(np.nan_to_num(u).astype(np.intp), self.p.size - 2)
        return i, u - i

    @staticmethod
    def _along(table: np.ndarray, i: np.ndarray, w: np.ndarray) -> np.ndarray:
        return table[i] + w * (table[i + 1] - table[i])

    def _rise(self, i: np.ndarray, w: np.ndarray, superheat: np.ndarray) -> np.ndarray:
        v = np.maximum(np.asarray(superheat, float) / self.step, 0.0)
        j = np.minimum(np.nan_to_num(v).astype(np.intp), self.superheat.size - 2)
        t = v - j
        low = self.dh[i, j] + t * (self.dh[i, j + 1] - self.dh[i, j])
        high = self.dh[i + 1, j] + t * (self.dh[i + 1, j + 1] - self.dh[i + 1, j])
        return low + w * (high - low)

    def saturation(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Saturation temperature [K] and saturated-vapour enthalpy [J/kg] at ``p`` [Pa]; NaN outside."""
        i, w = self._pressure_cell(p)
        return self._along(self.T, i, w), self._along(self.h_v, i, w)

    def superheat_of(self, p: np.ndarray, rise: np.ndarray) -> np.ndarray:
        """Superheat [K] whose enthalpy above saturation at ``p`` [Pa] is ``rise`` [J/kg].

        The inverse of :meth:`enthalpy_above_saturation` (a bisection over the
        superheat steps, then linear in the cell); NaN outside the table's pressures."""
        i, w = self._pressure_cell(p)
        rise = np.asarray(rise, float)
        last = self.superheat.size - 2
        lo = np.zeros(np.shape(i), np.intp)
        hi = np.full(np.shape(i), last, np.intp)
        for _ in range(int(np.ceil(np.log2(last + 1))) + 1):  # the last cell whose start lies below
            mid = (lo + hi + 1) // 2
            start = self.dh[i, mid] + w * (self.dh[i + 1, mid] - self.dh[i, mid])
            below = start <= rise
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid - 1)
        a = self.dh[i, lo] + w * (self.dh[i + 1, lo] - self.dh[i, lo])
        b = self.dh[i, lo + 1] + w * (self.dh[i + 1, lo + 1] - self.dh[i, lo + 1])
        return (lo + (rise - a) / (b - a)) * self.step + 0.0 * w

    def enthalpy_above_saturation(self, p: np.ndarray, superheat: np.ndarray) -> np.ndarray:
        """``h(p, T_sat + superheat) - h_v(p)`` [J/kg]; NaN outside the table's pressures.

        A negative superheat counts as 0; beyond ``superheat_max`` the last step's slope
        continues linearly (the function keeps rising, so it stays invertible)."""
        return self._rise(*self._pressure_cell(p), superheat)

    def rise_to(self, p: np.ndarray, T: np.ndarray, superheat_min: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``h_v(p)`` and ``h(p, T') - h_v(p)`` [J/kg] with ``T' = max(T, T_sat(p) + superheat_min)`` [K].

        :meth:`saturation` and :meth:`enthalpy_above_saturation` from one search of the pressure cell."""
        i, w = self._pressure_cell(p)
        return self._along(self.h_v, i, w), self._rise(i, w, np.maximum(T - self._along(self.T, i, w), superheat_min))


#: Incompressible-fluid name and mass fraction of the default coolant: 50 % monoethylene glycol in water.
COOLANT_NAME = "MEG"
COOLANT_MASS_FRACTION = 0.5
#: How far below its freezing point the coolant tables are continued [K].
COOLANT_SUPERCOOLING = 30.0


class Coolant:
    """A water-glycol coolant (CoolProp incompressible, ``INCOMP::MEG`` by default), tabulated in temperature.

    CoolProp's incompressibles are polynomial fits in temperature (Skovrup
    2004, in Bell et al. 2014) valid from the mixture's freezing point up to
    ``Tmax``; the installed CoolProp takes the concentration through
    ``AbstractState("INCOMP", "MEG")`` and ``set_mass_fractions`` (the
    ``"MEG-50%"`` and ``"MEG[0.5]"`` name forms are not in its library).
    Enthalpy, heat capacity, density, viscosity and conductivity are
    tabulated at the fixed pressure ``p`` every ``step`` K from the freezing
    point to ``Tmax`` and interpolated linearly; :data:`COOLANT_SUPERCOOLING`
    K below freezing the enthalpy is continued with the heat capacity at
    freezing and the other properties held (CoolProp refuses those states),
    so that a stream cooled below freezing stays finite for the caller to
    flag against :attr:`T_freeze`. The table *is* the enthalpy function:
    :meth:`enthalpy` and :meth:`temperature` are exact inverses (to round-off),
    so a heat balance written in coolant enthalpies closes to round-off; the
    table lies within about 1e-3 J/kg of CoolProp at the default step.

    Parameters
    ----------
    name : str
        CoolProp incompressible mixture name, ``"MEG"`` by default.
    mass_fraction : float
        Glycol mass fraction [1], 0.5 by default.
    p : float
        Coolant pressure [Pa] of the tables (incompressible: weak effect).
    step : float
        Temperature step of the tables [K].

    Attributes
    ----------
    T_freeze : float
        Freezing point of the mixture [K] (237.2 K for MEG 50 %).
    T_min, T_max : float
        Table range [K]: ``T_freeze - COOLANT_SUPERCOOLING`` to CoolProp's ``Tmax`` (373.15 K for MEG).
    """

    def __init__(
        self, name: str = COOLANT_NAME, mass_fraction: float = COOLANT_MASS_FRACTION, p: float = 2e5, step: float = 0.02
    ) -> None:
        CP = _cp()
        try:
            st = CP.AbstractState("INCOMP", name)
            st.set_mass_fractions([mass_fraction])
        except ValueError as exc:
            raise ValueError(f"CoolProp cannot load coolant {name!r} at mass fraction {mass_fraction}: {exc}") from exc
        self.name, self.mass_fraction, self.p = name, mass_fraction, p
        self.T_freeze = float(CP.PropsSI("T_freeze", "T", 300.0, "P", p, f"INCOMP::{name}-{100 * mass_fraction:g}%"))
        self.T_max = float(st.Tmax())
        n = int(np.ceil((self.T_max - self.T_freeze) / step)) + 1
        T = np.linspace(self.T_freeze, self.T_max, n)
        rows = np.empty((n, 5))
        for i, t in enumerate(T):
            st.update(CP.PT_INPUTS, p, float(t))
            rows[i] = (st.hmass(), st.cpmass(), st.rhomass(), st.viscosity(), st.conductivity())
        below = T[0] - np.arange(int(round(COOLANT_SUPERCOOLING / step)), 0, -1) * (T[1] - T[0])
        ext = np.repeat(rows[:1], below.size, axis=0)
        ext[:, 0] = rows[0, 0] + rows[0, 1] * (below - T[0])
        self.T = np.concatenate([below, T])
        self.T_min = float(self.T[0])
        self.h, self._cp_tab, self._rho, self._mu, self._k = np.concatenate([ext, rows]).T

    def __repr__(self) -> str:
        return f"Coolant({self.name!r}, mass_fraction={self.mass_fraction})"

    def enthalpy(self, T: np.ndarray | float) -> np.ndarray:
        """Specific enthalpy [J/kg] at ``T`` [K] (NaN outside ``T_min..T_max``)."""
        return np.interp(T, self.T, self.h, left=np.nan, right=np.nan)

    def temperature(self, h: np.ndarray | float) -> np.ndarray:
        """Temperature [K] at specific enthalpy ``h`` [J/kg], the inverse of :meth:`enthalpy`."""
        return np.interp(h, self.h, self.T, left=np.nan, right=np.nan)

    def tables(self) -> dict[str, np.ndarray]:
        """The tabulated columns by name, what :meth:`enthalpy`, :meth:`temperature` and
        :meth:`properties` interpolate: ``T`` [K], ``h`` [J/kg], ``CP``, ``D``, ``MU``, ``K`` (SI)."""
        return {"T": self.T, "h": self.h, "CP": self._cp_tab, "D": self._rho, "MU": self._mu, "K": self._k}

    def properties(self, T: np.ndarray | float) -> dict[str, np.ndarray]:
        """``CP`` [J/(kg K)], ``D`` [kg/m3], ``MU`` [Pa s] and ``K`` [W/(m K)] at ``T`` [K] (NaN outside)."""
        return {
            key: np.interp(T, self.T, table, left=np.nan, right=np.nan)
            for key, table in (("CP", self._cp_tab), ("D", self._rho), ("MU", self._mu), ("K", self._k))
        }


@functools.lru_cache(maxsize=4)
def coolant(name: str = COOLANT_NAME, mass_fraction: float = COOLANT_MASS_FRACTION) -> Coolant:
    """The cached :class:`Coolant` of ``name`` at ``mass_fraction``."""
    return Coolant(name, mass_fraction)
