"""Component models for the cycle solver: from LUTs, or the bench physics directly.

Both classes answer the same calls (the compressor, the condensing component
(air-cooled condenser or WCC) and the evaporating branches on arrays of
operating points, the valve's parameters) and return NaN plus a
reason string where they cannot: :class:`LutModels`
interpolates LUT files (the fast path for control work) and names the LUT
axis a query leaves; :class:`DirectModels` calls the bench functions (the
accuracy reference) and names the bench's status.
"""

from __future__ import annotations

import json
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from evtms._jit import numba_enabled
from evtms.benches.base import in_codes
from evtms.benches.condenser import SUPERHEATED_INLETS
from evtms.benches.evaporator import FREEZING_POINT
from evtms.benches.expansion_valve import ExpansionValveParams, nominal_opening
from evtms.benches.parameters import Parameters
from evtms.cycle.approach import APPROACH, OUTLET, SECONDARY_INLET, SUPERHEAT_MIN, outlet_enthalpy
from evtms.cycle.dome import SCALED, dome_capacity_ratio
from evtms.cycle.tables import cycle_lut, made_with, values_made_at, vapour_table, window_start, wrong_side_flags
from evtms.errors import EvtmsInputError
from evtms.fluid import Fluid, SaturationCurve
from evtms.hx.crossflow import per_point_searches

if TYPE_CHECKING:
    import xarray as xr

    from evtms.fluid import VapourTable

Result = dict[str, np.ndarray]


def frost_risk_flags(flags: dict[int, str]) -> tuple[int, ...]:
    """A bench's status codes of valid points whose coldest surface is below 0 degC (the evaporator's
    ``valid_frost_risk_surface_below_0C``, and the same with its air correlation out of range)."""
    return tuple(c for c, meaning in flags.items() if meaning.startswith("valid_frost_risk"))


#: Variables the solver needs while it iterates (the fewer, the faster the LUT gathers).
#: The coils' outlet enthalpy is ``h_out_continued``: equal to ``h_out`` where the cycle
#: closes (a superheated evaporator outlet, a subcooled condenser outlet) and smooth
#: across the phase boundary, where ``h_out`` has a kink that interpolation smears
#: over a whole cell.
ITERATION_OUTPUTS = {
    "compressor": ("mdot", "h_in", "h_out"),
    # With a saturated-liquid outlet the condenser closes on capacity_ratio alone;
    # a subcooled target needs the outlet enthalpy as well.
    "condenser": ("capacity_ratio", "p_out"),
    "condenser_subcooled": ("capacity_ratio", "p_out", "h_out_continued"),
    "evaporator": ("h_out_continued", "p_out"),
    "chiller": ("h_out_continued", "p_out"),
    # The WCC closes the same way as the condenser (its capacity ratio is the same construct).
    "wcc": ("capacity_ratio", "p_out"),
}

#: Each component model's arguments, in the order its method takes them, as the LUT axes they are.
MODEL_AXES = {
    "compressor": ("speed", "T_in", "p_in", "pr"),
    "condenser": ("mdot", "fan", "p_in", "h_in", "T_air_in", "RH_air_in"),
    "wcc": ("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in"),
    "evaporator": ("mdot", "blower", "p_in", "h_in", "T_air_in", "RH_air_in"),
    "chiller": ("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in"),
}

#: The condensing components (:class:`~evtms.cycle.topology.Condensing`): the same closure variables.
CONDENSING = ("condenser", "wcc")

#: What the first of a condensing chain interpolates besides its closure variables: its heat rate,
#: from which its outlet (the second's inlet) follows. Its outlet enthalpy itself goes as the inverse
#: of the refrigerant flow (the heat over the flow) and was up to 2 kJ/kg off between the flow nodes,
#: which the condenser behind it, left with a small share of the heat, turned into 5 % of discharge
#: pressure. The heat rate gets the curvature correction (:data:`CURVED`): it bends where the coolant
#: passes the saturation (below it the WCC condenses too); corrected, its worst error in the chain on
#: 100 random points fell from 6.0 to 1.7 % of itself (1.2 to 0.7 % of the condensing heat).
CHAIN_FIRST_OUTPUTS = ("Q",)

#: Where the condenser's tables start for a circuit without a condensing chain, by axis: every
#: compressor discharge is superheated vapour, so the cycle grid's two-phase inlets
#: (:data:`evtms.benches.condenser.TWO_PHASE_INLETS`) would only cost memory there, and their
#: node below the first superheated one would change the curvature correction of the cells above.
DISCHARGE_WINDOW = {"h_in": SUPERHEATED_INLETS[0]}

#: Variables whose interpolation gets the quadratic (curvature) correction: the coils'
#: closure and outlet variables, which curve strongly between nodes.
CURVED = {
    "compressor": ("mdot", "h_out", "T_out", "W"),
    "condenser": ("capacity_ratio", "h_out_continued", SCALED),
    "evaporator": ("h_out_continued", "Q_latent"),
    "chiller": ("h_out_continued", "p_out"),
    "wcc": ("capacity_ratio", "h_out_continued", "Q"),
}

#: The operating inputs each component's model takes as they are, by the component's axis name:
#: a LUT whose axis does not cover one cannot give that point at any refrigerant state.
OPERATING_AXES = {
    "compressor": {"speed": "speed"},
    "condenser": {"fan": "fan", "T_air_in": "T_amb", "RH_air_in": "RH_amb"},
    "evaporator": {"blower": "blower", "T_air_in": "T_cabin", "RH_air_in": "RH_cabin"},
    "chiller": {"mdot_coolant": "mdot_coolant", "T_coolant_in": "T_coolant_in"},
    # The WCC's coolant is the heating loop's, the chiller's the battery or e-drive loop's.
    "wcc": {"mdot_coolant": "mdot_coolant_h", "T_coolant_in": "T_coolant_h_in"},
}

#: Variables each component model returns for the final states.
COMPONENT_OUTPUTS = {
    "compressor": ("mdot", "h_in", "h_out", "T_out", "W"),
    "condenser": ("p_out", "capacity_ratio", "h_out_continued"),
    "evaporator": ("Q_latent", "h_out_continued", "p_out"),
    "chiller": ("h_out_continued", "p_out"),
    "wcc": ("p_out", "capacity_ratio", "h_out_continued", "h_out"),
}


#: Empty stand-ins for the kernel's unused table arguments.
_NONE = np.empty(0)
_NONE2 = np.empty((2, 2))


def _reasons(n: int) -> np.ndarray:
    return np.full(n, "", dtype=object)


def _column(value, n: int) -> np.ndarray:
    """``value`` as a fresh float array of ``n`` points (a copy: the benches may write into it)."""
    if type(value) is np.ndarray and value.shape == (n,) and value.dtype == np.float64:
        return value.copy()
    return np.broadcast_to(np.asarray(value, float), (n,)).copy()


#: Valve flow areas at the nominal opening [m2] by valve parameters, fluid name and backend.
_VALVE_AREAS: dict[tuple[ExpansionValveParams, str, str], float] = {}


#: The inputs of each exchanger's secondary stream in its bench call, as its compiled twin takes them.
_TWIN_INPUTS = {
    "condenser": ("fan", "T_air_in", "RH_air_in"),
    "evaporator": ("blower", "T_air_in", "RH_air_in"),
    "chiller": ("mdot_coolant", "T_coolant_in"),
    "wcc": ("mdot_coolant", "T_coolant_in"),
}
#: One-point air sides a :class:`DirectModels` keeps (a solve meets one air state per coil).
_AIR_KEPT = 64


def _twin_outputs(component: str) -> tuple[str, ...]:
    """The outputs the compiled twins give a closure's iterations: :data:`COMPONENT_OUTPUTS` but
    the evaporator's ``Q_latent`` (the bench's alone)."""
    return tuple(k for k in COMPONENT_OUTPUTS[component] if k != "Q_latent")


def _twin_constants(component: str, params: Parameters, fluid: Fluid) -> tuple | np.ndarray:
    """:meth:`DirectModels.twin_constants`, computed."""
    from evtms.benches import chiller, compressor, wcc
    from evtms.benches.coil import march_inputs

    if component == "compressor":
        return compressor.kernel_constants(params.compressor, fluid)
    if component == "chiller":
        geo, cool, T_freeze, T_max, p_triple, p_min, _, gauss = chiller.kernel_constants(fluid, params.chiller)
        return geo, cool, T_freeze, T_max, p_triple, p_min, gauss, fluid.p_crit
    if component == "wcc":
        *head, _, gauss = wcc.kernel_constants(fluid, params.wcc)
        return (*head, gauss)
    env = params.environment  # the tube array and the saturated-air curve do not depend on the air state
    _, tube, curve = march_inputs(fluid, getattr(params, component), env, 1.0, env.T, env.RH, component)
    return (tube, component == "condenser", component == "evaporator", *curve)


class DirectModels:
    """The bench physics, called directly (no LUTs).

    Parameters
    ----------
    params : Parameters
        Component parameters (the ``environment`` gives the air pressure).
    fluid : Fluid, optional
        Refrigerant properties; built from ``params`` if not given.
    """

    name = "direct"

    def __init__(self, params: Parameters, fluid: Fluid | None = None) -> None:
        from evtms.benches import BENCHES

        self.params = params
        self.fluid = fluid or Fluid(params.fluid, params.backend)
        self._benches = BENCHES
        self._flag_codes: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = {}
        self._iterating = False
        self._constants: dict[str, tuple] = {}
        self._air: dict[tuple, np.ndarray] = {}

    def _run(self, component: str, inputs: dict[str, np.ndarray]) -> Result:
        n = len(next(iter(inputs.values())))
        inputs = {k: _column(v, n) for k, v in inputs.items()}
        if self._iterating and numba_enabled():
            return self._run_twins(component, inputs, n)
        return self._run_bench(component, inputs, n)

    def _run_bench(self, component: str, inputs: dict[str, np.ndarray], n: int) -> Result:
        """The bench function itself: every variable."""
        bench = self._benches[component]
        with per_point_searches():  # a cycle solver's calls hold a few points each
            out = bench.evaluate(inputs, self.params, self.fluid)
        status = out["status"]
        bad = ~in_codes(status, bench.valid_flags)
        reasons = _reasons(n)
        if bad.any():  # the solver's calls are mostly valid: no reasons to look up
            for code, meaning in bench.flags.items():
                reasons[bad & (status == code)] = f"{component}: {meaning}"
        result = {k: out[k] for k in COMPONENT_OUTPUTS[component]}
        wrong_side, frost = self._codes(component)
        result["no_heat_flow"] = in_codes(status, wrong_side)
        if component == "evaporator":
            result["frost_risk"] = in_codes(status, frost).astype(float)
        result["reason"] = reasons
        return result

    def _run_twins(self, component: str, inputs: dict[str, np.ndarray], n: int) -> Result:
        """The closure's iterations: the benches' compiled twins as the direct-physics kernel reads
        them (:mod:`evtms.cycle._direct_kernel`: the same values and statuses as the bench
        functions, every variable of :data:`COMPONENT_OUTPUTS` but the evaporator's ``Q_latent``,
        whose correction for fog at the outlet the twins leave to the bench). Points the twins
        leave to the bench (states beyond the property tables, a coil at a flow or pressure that
        is not finite) go through it."""
        from evtms.cycle import _direct_kernel as kernel
        from evtms.fluid_tables import tables_for

        tables = tables_for(self.fluid).arrays
        if component == "compressor":
            args = (inputs[k] for k in ("speed", "T_in", "p_in", "pr"))
            rows, codes = kernel.compressor_rows(*args, self.twin_constants(component), tables)
        else:
            secondary = (inputs[k] for k in _TWIN_INPUTS[component])
            per_point = self.twin_inputs(component, *secondary, n=n)
            args = (inputs[k] for k in ("mdot", "p_in", "h_in"))
            rows, codes = kernel.exchanger_rows(*args, per_point, self.twin_constants(component), tables)
        columns = kernel.twin_columns(component)
        valid = codes == 0
        result = {k: np.where(valid, rows[:, columns.index(k)], np.nan) for k in _twin_outputs(component)}
        result["no_heat_flow"] = (codes == kernel.WRONG_SIDE) if component != "compressor" else np.zeros(n, bool)
        if component == "evaporator":
            result["frost_risk"] = (valid & (rows[:, columns.index("T_surface_min")] < FREEZING_POINT)).astype(float)
        flags = self._benches[component].flags
        result["reason"] = np.array([f"{component}: {flags[c]}" if c > 0 else "" for c in codes.tolist()], object)
        rest = np.nonzero(codes < 0)[0]
        if rest.size:  # the bench decides these (CoolProp beyond the tables)
            sub = self._run_bench(component, {k: v[rest] for k, v in inputs.items()}, rest.size)
            for key, value in result.items():
                value[rest] = sub[key]
        return result

    def twin_constants(self, component: str) -> tuple | np.ndarray:
        """What the compiled twin of ``component`` takes besides its points
        (:mod:`evtms.cycle._direct_kernel`): the compressor's constants, a coil's tube array, mode and
        saturated-air curve, the plate chiller's or the WCC's constants (without the refrigerant
        tables); kept per component."""
        if component not in self._constants:
            self._constants[component] = _twin_constants(component, self.params, self.fluid)
        return self._constants[component]

    def twin_inputs(self, component: str, *secondary, n: int) -> np.ndarray:
        """The compiled twin's per-point inputs of ``component`` at its secondary stream
        ``secondary`` (a coil's air fraction [1], temperature [K] and relative humidity [1]: its air
        side per point, :func:`evtms.benches.coil.march_inputs`, kept for one-point calls; a
        plate's coolant flow [kg/s] and inlet temperature [K]) for ``n`` points."""
        columns = [np.broadcast_to(np.asarray(v, float), (n,)) for v in secondary]
        if component not in ("condenser", "evaporator"):
            return np.ascontiguousarray(np.stack(columns, axis=1))
        from evtms.benches.coil import march_inputs

        key = (component, *(float(c[0]) for c in columns)) if n == 1 else None
        if key is not None and key in self._air:
            return self._air[key]
        air, _, _ = march_inputs(
            self.fluid, getattr(self.params, component), self.params.environment, *columns, component
        )
        air = np.ascontiguousarray(np.broadcast_to(air, (n, air.shape[1])))
        if key is not None:
            if len(self._air) >= _AIR_KEPT:
                self._air.clear()
            self._air[key] = air
        return air

    def _codes(self, component: str) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The bench's :func:`wrong_side_flags` and :func:`frost_risk_flags` (found once per component)."""
        if component not in self._flag_codes:
            flags = self._benches[component].flags
            self._flag_codes[component] = (wrong_side_flags(flags), frost_risk_flags(flags))
        return self._flag_codes[component]

    def compressor(self, speed, T_in, p_in, pr) -> Result:
        return self._run("compressor", {"speed": speed, "T_in": T_in, "p_in": p_in, "pr": pr})

    def condenser(self, mdot, fan, p_in, h_in, T_air, RH_air) -> Result:
        return self._run(
            "condenser",
            {
                "mdot": mdot,
                "fan": fan,
                "p_in": p_in,
                "h_in": h_in,
                "T_res": T_air,
                "T_air_in": T_air,
                "RH_air_in": RH_air,
            },
        )

    def wcc(self, mdot, p_in, h_in, mdot_coolant, T_coolant_in) -> Result:
        return self._run(
            "wcc",
            {"mdot": mdot, "p_in": p_in, "h_in": h_in, "mdot_coolant": mdot_coolant, "T_coolant_in": T_coolant_in},
        )

    def evaporator(self, mdot, blower, p_in, h_in, T_air, RH_air) -> Result:
        return self._run(
            "evaporator",
            {
                "mdot": mdot,
                "blower": blower,
                "p_in": p_in,
                "h_in": h_in,
                "T_res": T_air,
                "T_air_in": T_air,
                "RH_air_in": RH_air,
            },
        )

    def chiller(self, mdot, p_in, h_in, mdot_coolant, T_coolant_in) -> Result:
        return self._run(
            "chiller",
            {"mdot": mdot, "p_in": p_in, "h_in": h_in, "mdot_coolant": mdot_coolant, "T_coolant_in": T_coolant_in},
        )

    def flow_range(self, component: str) -> tuple[float, float]:
        """Refrigerant flows [kg/s] a branch's flow split may give it: from 0.1 g/s (a valve
        nearly closed; the cycle LUTs start at 1-3 g/s)."""
        return 1e-4, np.inf

    def outside_axes(self, component: str, ops: dict[str, np.ndarray]) -> np.ndarray:
        """No LUT axes: every operating input is the bench's to judge (empty reasons)."""
        return _reasons(len(next(iter(ops.values()))))

    def detailed(self, on: bool) -> None:
        """Every variable, from the bench functions (the final states), or the closure's
        iterations on the benches' compiled twins (:meth:`_run_twins`)."""
        self._iterating = not on

    def subcooled_targets(self, on: bool) -> None:
        """The bench functions always return every variable."""

    def valve(self) -> tuple[ExpansionValveParams, float]:
        """The valve's parameters and its flow area at the nominal opening [m2] (CoolProp's
        nominal states, some 2 ms: kept per parameters and fluid for the process, as the
        solver asks several times a point)."""
        valve = self.params.expansion_valve
        key = (valve, self.fluid.name, self.fluid.backend)
        if key not in _VALVE_AREAS:
            _VALVE_AREAS[key] = nominal_opening(valve, self.fluid)
        return valve, _VALVE_AREAS[key]

    def limits(self, exclude: tuple[str, ...] = ()) -> dict[str, tuple[float, float]]:
        """Ranges the solver may search: the fluid's saturation range, and pressure
        ratios up to where the compressor's volumetric efficiency falls to 5 %
        (the same whichever components are ``exclude``-d)."""
        from evtms.benches.compressor import clearance_volumetric_efficiency

        comp = self.params.compressor
        ratios = np.geomspace(1.0, 100.0, 2000)
        pr_max = float(ratios[clearance_volumetric_efficiency(ratios, comp) > 0.05][-1])
        return {
            "p_suction": (2.5e4, 0.9 * self.fluid.p_crit),
            "p_discharge": (1e5, 0.98 * self.fluid.p_crit),
            "pr": (1.0, pr_max),
            # Physical limits, not a LUT's: the solver reports no root there.
            "axes": {"p_suction": (None, None), "p_discharge": (None, None), "pr": (None, None)},
        }


def _outside_axis(component: str, axis: str, value: float, lo: float, hi: float) -> str:
    """Why a query lies outside a component LUT's axis."""
    return f"{component} LUT axis {axis} = {value:.6g} outside [{lo:.6g}, {hi:.6g}]"


class _LutComponent:
    """One component's LUT: interpolators, axes, and the fixed values of absent axes."""

    def __init__(
        self,
        component: str,
        lut,
        curvature: tuple[str, ...],
        compiled: bool = True,
        vapour: VapourTable | None = None,
        saturation: SaturationCurve | None = None,
        window: dict[str, float] | None = None,
        added: tuple[str, ...] = (),
    ) -> None:
        lut = cycle_lut(lut, component)
        self.component = component
        self.source = lut.encoding["source"]
        self.dims = list(lut.dims)
        # An evaporating branch's outlet is interpolated as the log of its approach to the
        # secondary inlet (evtms.cycle.approach), which sets the valve-controlled flow
        # several times more accurately where the outlet nears that temperature.
        self.secondary = SECONDARY_INLET.get(component) if vapour is not None else None
        self.vapour = vapour
        self.compiled = compiled

        def table(variables: tuple[str, ...]):
            if saturation is not None and "capacity_ratio" in variables:
                variables = (*variables, SCALED)  # a two-phase inlet's scaled ratio beside it (evtms.cycle.dome)
            if self.secondary is None:
                return lut.interpolator(list(variables), curvature, compiled, None, saturation, window)
            swap = {OUTLET: APPROACH}
            return lut.interpolator(
                [swap.get(v, v) for v in variables], tuple(swap.get(v, v) for v in curvature), compiled, vapour
            )

        # The coils' responses curve strongly between nodes (they saturate towards
        # the air temperature); the quadratic correction cuts that error several-fold.
        self.fast = table((*ITERATION_OUTPUTS[component], *added))
        self.subcooled = (
            table((*ITERATION_OUTPUTS["condenser_subcooled"], *added)) if component in CONDENSING else self.fast
        )
        self.needs_subcooled = False
        # The final states need a few more variables: a table of those alone, added to
        # the widest iteration table's (the tables hold each variable with its curvature
        # columns, so a table of every variable would repeat the largest ones).
        have = set(self.subcooled.variables) | ({OUTLET} if self.secondary else set())
        extra = tuple(v for v in COMPONENT_OUTPUTS[component] if v not in have)
        self.extra = table(extra) if extra else None
        # Status codes as the file defines them (a LUT carries its own flag_values and meanings).
        flags = lut.status_flags()
        # The evaporator's frost risk (its bench status ``valid_frost_risk_surface_below_0C``):
        # the LUTs hold no surface temperature, so the final states interpolate the
        # indicator of that status (1 at frost-risk nodes, 0 at other valid nodes).
        self.frost_codes = frost_risk_flags(flags)
        self.frost = (
            lut.indicator("frost_risk", self.frost_codes, compiled)
            if component == "evaporator" and self.frost_codes
            else None
        )
        # A cell touching nodes where the refrigerant enters on the wrong side of the secondary
        # stream (no heat flows; the bench leaves them NaN) interpolates to NaN. Near that edge
        # the physics takes next to no heat (a chiller whose coolant is barely warmer than the
        # evaporation cannot superheat, so its valve closes): such a point is "no heat flow",
        # as the bench says at the nodes, and not the end of the model's envelope. The share of
        # the cell's weight on those nodes is interpolated, NaN where other invalid nodes weigh;
        # its table is built (and cached) the first time a NaN cell is met.
        self.no_heat_codes = wrong_side_flags(flags)
        self._no_heat_table = (
            partial(lut.indicator, "no_heat_flow", self.no_heat_codes, compiled) if self.no_heat_codes else None
        )
        self._no_heat = None
        self._kernel = None
        self.detailed = False
        start = window_start(lut.axes, window)
        self.ranges = {d: (float(lut.axes[d][start.get(d, 0)]), float(lut.axes[d][-1])) for d in self.dims}
        self.fixed = values_made_at(lut.attrs)
        # Inputs a query may give that the LUT holds fixed (checked against their value).
        self._fixed_axes = tuple(a for a, v in self.fixed.items() if a not in self.dims and v is not None)

    def __call__(self, query: dict[str, np.ndarray]) -> Result:
        # The solver calls this some ninety times per operating point and iteration, mostly
        # with every value inside the axes: the reasons are worked out only where one is not.
        itp = self.subcooled if (self.needs_subcooled or self.detailed) else self.fast
        if not self.detailed and self._kernel_for(itp) is not None:
            return self._call_kernel(query, itp)
        n = len(next(iter(query.values())))
        cols = {}
        outside = []  # (mask, message per point) in the order of the axes: the first one wins
        for d in self.dims:
            lo, hi = self.ranges[d]
            if d == "T_res" and d not in query:
                cols[d] = np.full(n, lo)  # no effect in steady state; any grid value will do
                continue
            x = query[d]
            if not (type(x) is np.ndarray and x.ndim == 1 and x.size == n and x.dtype == np.float64):
                x = np.broadcast_to(np.asarray(x, float), (n,))
            off = ~((x >= lo) & (x <= hi))
            if off.any():
                outside.append((off, lambda i, d=d, x=x, lo=lo, hi=hi: _outside_axis(self.component, d, x[i], lo, hi)))
            cols[d] = x
        outside += self._fixed_off(query, n)
        out = itp(cols)
        if self.secondary is not None:
            T_sec = np.broadcast_to(np.asarray(query[self.secondary], float), (n,))
            out[OUTLET] = outlet_enthalpy(out.pop(APPROACH), out["p_out"], T_sec, self.vapour, self.compiled)
        if self.detailed and self.extra is not None:
            out.update(self.extra(cols))
        if self.detailed and self.frost is not None:
            out.update(self.frost(cols))
        reasons = _reasons(n)
        bad = _blank_outside(out, reasons, outside)
        return self._flag_nan(out, reasons, bad, itp, lambda k: {d: c[k] for d, c in cols.items()})

    def _fixed_off(self, query: dict[str, np.ndarray], n: int) -> list:
        """(mask, message per point) of the inputs the query gives that the LUT holds fixed and that are off."""
        outside = []
        for axis in self._fixed_axes:
            if axis in query:
                fixed = self.fixed[axis]
                x = np.broadcast_to(np.asarray(query[axis], float), (n,))
                off = ~(np.abs(x - fixed) <= 1e-9 * max(abs(fixed), 1.0))
                if off.any():
                    outside.append(
                        (
                            off,
                            lambda i, axis=axis, x=x, fixed=fixed: (
                                f"{self.component} LUT has no {axis} axis (fixed at {fixed:g}); asked {x[i]:.6g}"
                            ),
                        )
                    )
        return outside

    def _flag_nan(self, out: Result, reasons: np.ndarray, bad: np.ndarray, itp, columns) -> Result:
        """``out`` with ``no_heat_flow`` and ``reason``: a NaN cell's reason, or no heat where its NaN
        nodes are the refrigerant on the wrong side of the secondary (``columns(k)``: the query of points k)."""
        n = reasons.size
        nan = ~bad & ~np.isfinite(out[OUTLET if self.secondary else itp.variables[0]])
        if self._no_heat_table is not None:
            # Always present (as from DirectModels): the solver gathers results of several calls.
            none = np.zeros(n, bool)
            if nan.any():
                k = np.nonzero(nan)[0]
                share = self.no_heat_indicator()(columns(k))["no_heat_flow"]
                none[k[share > 0]] = True  # NaN shares (other invalid nodes) compare False
                nan &= ~none
            out["no_heat_flow"] = none
        if nan.any():
            reasons[nan] = f"{self.component} LUT: invalid (NaN) point in the interpolation cell"
        out["reason"] = reasons
        return out

    def no_heat_indicator(self):
        """The interpolator of the share of a cell's weight on nodes where no heat flows (the
        refrigerant on the wrong side of its secondary stream), built (and cached) on first use;
        None where the LUT has no such status."""
        if self._no_heat is None and self._no_heat_table is not None:
            self._no_heat = self._no_heat_table()
        return self._no_heat

    def _kernel_for(self, itp):
        """The compiled evaluation (:mod:`evtms.cycle._component_kernel`) where ``itp`` is compiled
        with the 'nan' policy, else None (the path above)."""
        if not (itp.compiled and itp.out_of_range == "nan"):
            return None
        if self._kernel is None:
            from evtms.cycle import _component_kernel

            self._kernel = _component_kernel
            self._lo = np.array([self.ranges[d][0] for d in self.dims])
            self._hi = np.array([self.ranges[d][1] for d in self.dims])
            v = self.vapour
            self._vapour_args = (
                ((v.log_p0, v.dlog_p, v.T, v.h_v, v.step), v.dh)
                if v is not None
                else ((0.0, 1.0, _NONE, _NONE, 1.0), _NONE2)
            )
        return self._kernel

    def _call_kernel(self, query: dict[str, np.ndarray], itp) -> Result:
        """:meth:`__call__` in one compiled call (the same numbers, the same reasons)."""
        n = len(next(iter(query.values())))
        dims = self.dims
        pts = np.empty((len(dims), n))
        for j, d in enumerate(dims):
            # T_res: no effect in steady state; any grid value will do.
            pts[j] = self._lo[j] if (d == "T_res" and d not in query) else query[d]
        out = np.empty((len(itp.variables), n))
        first = np.empty(n, np.int64)
        rows, t_sec, check = (-1, -1), _NONE, 0
        if self.secondary is not None:
            rows = (itp.variables.index(APPROACH), itp.variables.index("p_out"))
            check = rows[0]
            t_sec = (
                pts[dims.index(self.secondary)]
                if self.secondary in dims
                else np.broadcast_to(np.asarray(query[self.secondary], float), (n,)).copy()
            )
        vapour, dh = self._vapour_args
        args = (self._lo, self._hi, itp._floats, itp._ints, itp._kernel_values, out, first, check, *rows)
        flags = self._kernel.evaluate(pts, *args, t_sec, vapour, dh, SUPERHEAT_MIN)
        res = {v: out[k] for k, v in enumerate(itp.variables)}
        if self.secondary is not None:
            res[OUTLET] = res.pop(APPROACH)
        fixed = self._fixed_off(query, n)
        if not flags and not fixed:  # the usual call: every point inside the axes, every cell valid
            if self._no_heat_table is not None:
                res["no_heat_flow"] = np.zeros(n, bool)
            res["reason"] = _reasons(n)
            return res
        reasons = _reasons(n)
        if flags & 1:
            for i in np.nonzero(first >= 0)[0]:
                d = dims[first[i]]
                reasons[i] = _outside_axis(self.component, d, pts[first[i], i], *self.ranges[d])
        bad = _blank_outside(res, reasons, fixed)
        return self._flag_nan(res, reasons, bad, itp, lambda k: {d: pts[j][k] for j, d in enumerate(dims)})


def _blank_outside(out: Result, reasons: np.ndarray, outside: list) -> np.ndarray:
    """Each point's first reason of ``outside`` ((mask, message per point), in order) into
    ``reasons`` where it has none; where any is given, the points with a reason get NaN in
    ``out`` (in place). Returns the points with a reason."""
    for off, message in outside:
        for i in np.nonzero(off & (reasons == ""))[0]:
            reasons[i] = message(i)
    bad = reasons != ""
    if outside:
        for v in out.values():
            v[bad] = np.nan
    return bad


class LutModels:
    """Component models interpolated from LUT datasets.

    A coil's point whose interpolation cell holds nodes where the refrigerant
    enters on the wrong side of the secondary stream (the bench's
    ``refrigerant_inlet_not_*`` status: no heat flows, NaN in the LUT), and no
    other invalid node, returns ``no_heat_flow`` True with an empty reason, as
    :class:`DirectModels` does at those states; any other NaN cell returns NaN
    with a reason.

    Parameters
    ----------
    luts : mapping of str to CycleLut or xarray.Dataset
        ``condenser``, ``evaporator``, ``expansion_valve`` and ``compressor``
        LUTs (``chiller`` and ``wcc`` in their place, as ``components`` needs).
        The coils must have ``h_in`` inlet axes (a two-phase inlet has
        no (p, T)) and the compressor a ``p_in`` axis, as the ``cycle`` grid
        preset writes them. Of the valve's LUT the cycle uses its parameters
        (see :meth:`valve`).
    components : tuple of str, optional
        The components the circuit needs (``Topology.components``); default
        the cabin loop's.
    compiled : bool
        Interpolate through the compiled kernel (numba); False keeps to the
        NumPy path, which a job of a few points finishes before numba loads.
    approach : bool
        Interpolate the evaporating branches' outlet as the log of its approach
        to the secondary inlet (:mod:`evtms.cycle.approach`; default); False
        interpolates ``h_out_continued`` itself (for comparison).
    saturation : SaturationCurve, optional
        The refrigerant's saturation curve, for a condensing chain's condenser
        (its two-phase inlets, :mod:`evtms.cycle.dome`); default: CoolProp's for
        the LUTs' fluid, where a chain needs it.

    Notes
    -----
    A circuit without a condensing chain reads the condenser's tables from
    :data:`DISCHARGE_WINDOW` up; a chain's condenser reads them whole, its
    capacity ratio blended with the scaled one at two-phase inlets.
    """

    name = "lut"

    def __init__(
        self,
        luts: dict[str, xr.Dataset],
        components: tuple[str, ...] | None = None,
        compiled: bool = True,
        approach: bool = True,
        saturation: SaturationCurve | None = None,
    ) -> None:
        # Axes the solver searches along (an input it only sets may be a fixed input of the LUT).
        searched = {
            "condenser": ("p_in", "h_in"),
            "wcc": ("p_in", "h_in"),
            "evaporator": ("p_in", "h_in", "mdot"),
            "chiller": ("p_in", "h_in", "mdot"),
            "expansion_valve": (),
            "compressor": ("p_in", "pr"),
        }
        components = components or ("condenser", "evaporator", "expansion_valve", "compressor")
        # The condensing components in the refrigerant's order: the discharge enters the first.
        self.chain = tuple(c for c in components if c in CONDENSING)
        if len(self.chain) > 1 and saturation is None and "condenser" in luts:  # else the missing LUT is named below
            saturation = SaturationCurve(Fluid(cycle_lut(luts["condenser"], "condenser").attrs.get("fluid", "R134a")))
        self.saturation = saturation if len(self.chain) > 1 else None
        need = {c: searched[c] for c in components}
        self.luts = {}
        evaporating = [c for c in components if c in SECONDARY_INLET and c in luts]
        vapour = vapour_table({c: cycle_lut(luts[c], c) for c in evaporating}) if approach and evaporating else None
        for component, axes in need.items():
            if component not in luts:
                raise EvtmsInputError(f"the cycle needs a {component} LUT; none was given")
            lut = cycle_lut(luts[component], component)
            if not axes:
                continue
            extra = self._chain_tables(component)
            dims = list(lut.dims)
            for axis in axes:
                if axis not in dims:
                    raise EvtmsInputError(
                        f"the {component} LUT has axes {', '.join(dims)}; cycle work needs {axis!r} as an axis "
                        f"(write it with 'evtms bench {component} --grid cycle')"
                    )
            self.luts[component] = _LutComponent(component, lut, CURVED.get(component, ()), compiled, vapour, **extra)
        # None for a partial set (a branch's LUTs alone): no discharge closure to serve.
        self.condensing = self.chain[0] if self.chain else None
        self.valve_lut = cycle_lut(luts["expansion_valve"], "expansion_valve")
        self.valve_attrs = dict(self.valve_lut.attrs)
        self._valve: tuple[ExpansionValveParams, float] | None = None

    def detailed(self, on: bool) -> None:
        """Return every variable (final states) or only those the iterations need."""
        for lut in self.luts.values():
            lut.detailed = on

    def _chain_tables(self, component: str) -> dict:
        """What ``component``'s tables hold beyond its own iteration variables (:class:`_LutComponent`'s
        ``saturation``, ``window`` and ``added``): a chain's first gives its outlet to the second, a
        chain's condenser its scaled capacity ratio, a lone condenser reads its discharges' nodes."""
        if component == "condenser":
            return {"saturation": self.saturation} if self.saturation is not None else {"window": DISCHARGE_WINDOW}
        if len(self.chain) > 1 and component == self.chain[0]:
            return {"added": CHAIN_FIRST_OUTPUTS}
        return {}

    def subcooled_targets(self, on: bool) -> None:
        """Whether any point asks for a subcooled condenser outlet (more variables per iteration):
        the last of the condensing chain's, whose outlet is the circuit's."""
        if self.chain:
            self.luts[self.chain[-1]].needs_subcooled = on

    def compressor(self, speed, T_in, p_in, pr) -> Result:
        return self._ask("compressor", (speed, T_in, p_in, pr))

    def condenser(self, mdot, fan, p_in, h_in, T_air, RH_air) -> Result:
        out = self._ask("condenser", (mdot, fan, p_in, h_in, T_air, RH_air))
        if SCALED in out:  # a chain's condenser: two-phase inlets (evtms.cycle.dome)
            out["capacity_ratio"] = dome_capacity_ratio(
                out["capacity_ratio"], out.pop(SCALED), p_in, h_in, T_air, out["p_out"], self.saturation
            )
        return out

    def wcc(self, mdot, p_in, h_in, mdot_coolant, T_coolant_in) -> Result:
        out = self._ask("wcc", (mdot, p_in, h_in, mdot_coolant, T_coolant_in))
        if "Q" in out:  # the first of a chain: its outlet from its heat rate (CHAIN_FIRST_OUTPUTS)
            out["h_out"] = h_in - out.pop("Q") / mdot
        return out

    def evaporator(self, mdot, blower, p_in, h_in, T_air, RH_air) -> Result:
        return self._ask("evaporator", (mdot, blower, p_in, h_in, T_air, RH_air))

    def chiller(self, mdot, p_in, h_in, mdot_coolant, T_coolant_in) -> Result:
        return self._ask("chiller", (mdot, p_in, h_in, mdot_coolant, T_coolant_in))

    def _ask(self, component: str, args: tuple) -> Result:
        return self.luts[component](dict(zip(MODEL_AXES[component], args, strict=True)))

    def outside_axes(self, component: str, ops: dict[str, np.ndarray]) -> np.ndarray:
        """Per point, why its operating inputs lie outside ``component``'s LUT axes
        (:data:`OPERATING_AXES`; the first such axis in the LUT's order), else ''."""
        lut = self.luts[component]
        n = len(next(iter(ops.values())))
        reasons = _reasons(n)
        for axis, name in OPERATING_AXES[component].items():
            if axis not in lut.ranges or name not in ops:
                continue
            lo, hi = lut.ranges[axis]
            x = np.broadcast_to(np.asarray(ops[name], float), (n,))
            for i in np.nonzero(~((x >= lo) & (x <= hi)) & (reasons == ""))[0]:
                reasons[i] = _outside_axis(component, axis, x[i], lo, hi)
        return reasons

    def flow_range(self, component: str) -> tuple[float, float]:
        """Refrigerant flows [kg/s] a branch's LUT covers (its ``mdot`` axis)."""
        return self.luts[component].ranges["mdot"]

    def valve(self) -> tuple[ExpansionValveParams, float]:
        """The valve's parameters, as its LUT was made with, and its flow area at the nominal opening [m2].

        The cycle sets the valve's pressure drop; what it asks of the valve is
        the opening that passes the cycle's flow at that drop. Its LUT's dp at
        a saturated-liquid inlet would be interpolated across the kink the
        inlet density has there (4-50 % off); the valve's own orifice law with
        the area of its parameters is exact.
        """
        if self._valve is None:
            attrs = self.valve_attrs
            checked = made_with(self.valve_lut)
            valve = checked.expansion_valve

            def area():  # CoolProp's densities at the nominal conditions; cached
                fluid = Fluid(attrs.get("fluid", "R134a"), checked.backend)
                return {"area": np.array([nominal_opening(valve, fluid)])}, {}

            recipe = {"parameters": json.loads(attrs["parameters"]), "fluid": attrs.get("fluid", "R134a")}
            arrays, _ = self.valve_lut.derived("area", recipe, area)
            self._valve = (valve, float(arrays["area"][0]))
        return self._valve

    def limits(self, exclude: tuple[str, ...] = ()) -> dict[str, tuple[float, float]]:
        """Pressure ranges the solver may search: where the LUTs have data (the components in
        ``exclude``, a closed branch's, do not bound the suction)."""
        # Suction: every evaporating branch's inlet-pressure axis and the compressor's.
        suction = [
            (c, self.luts[c].ranges["p_in"])
            for c in ("evaporator", "chiller", "compressor")
            if c in self.luts and c not in exclude
        ]
        low = max(suction, key=lambda item: item[1][0])
        high = min(suction, key=lambda item: item[1][1])
        cond = self.luts[self.condensing].ranges["p_in"]
        return {
            "p_suction": (low[1][0], high[1][1]),
            "p_discharge": cond,
            "pr": self.luts["compressor"].ranges["pr"],
            # Which LUT axis each limit is, for the reason of a point beyond it.
            "axes": {
                "p_suction": (f"{low[0]} LUT axis p_in", f"{high[0]} LUT axis p_in"),
                "p_discharge": (f"{self.condensing} LUT axis p_in",) * 2,
                "pr": ("compressor LUT axis pr", "compressor LUT axis pr"),
            },
        }
