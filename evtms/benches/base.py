"""What a bench is: a vectorised function of its input arrays, plus metadata.

A :class:`Bench` names its axes (in the LUT format's order), the variables it
returns, its status codes and its grid presets. ``evaluate`` takes a dict of
equally long 1-D input arrays (one per axis) and returns a dict of output
arrays of the same length, with ``status`` as int8; invalid points hold NaN
in every float output.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from evtms.fluid import Fluid
from evtms.luts.schema import ALTERNATE_AXES, AxisSpec, ComponentSpec

if TYPE_CHECKING:
    from evtms.benches.parameters import Parameters

Evaluate = Callable[[dict[str, np.ndarray], "Parameters", Fluid], dict[str, np.ndarray]]

#: Status codes every bench shares; benches add their own above these.
STATUS_VALID = 0
STATUS_OUTSIDE_FLUID_RANGE = 1
STATUS_PROPERTY_FAILED = 2

#: The flag meanings of the shared codes; each bench adds its own.
COMMON_FLAGS = {
    STATUS_VALID: "valid",
    STATUS_OUTSIDE_FLUID_RANGE: "inlet_state_outside_fluid_range",
    STATUS_PROPERTY_FAILED: "property_evaluation_failed",
}


@dataclass(frozen=True)
class Bench:
    """A component test bench.

    Attributes
    ----------
    name : str
        Component name as in the LUT format (``condenser``, ...).
    title : str
        One-line description (the file's ``title``).
    axes : tuple of str
        Input axes in the LUT format's order.
    outputs : tuple of str
        Data variables it returns, ``status`` first.
    flags : dict of int to str
        Status code -> CF flag meaning (one word, underscores).
    evaluate : callable
        ``evaluate(inputs, params, fluid) -> outputs``.
    parameters : callable
        ``parameters()``: the component's default parameter table, a frozen
        dataclass of fields with units and ranges (:mod:`evtms.params`).
        :class:`~evtms.benches.parameters.Parameters` holds one such table
        per registered bench, named after it: the ``[name]`` table of a
        parameter file and the ``name`` table of a LUT's ``parameters``.
    presets : dict
        Grid preset name -> axis name -> values (SI).
    extra_axes : tuple of str
        Axes a grid may add after the standard ones.
    valid_flags : tuple of int
        Status codes whose points are valid (finite outputs).
    axis_specs : dict of str to AxisSpec
        This component's own axes (units, long name, allowed range, command-line
        units); axes shared by several components (``mdot``, ``p_in``, ...) are
        declared once in :mod:`evtms.benches.axes`.
    variables : dict of str to (str, str)
        Units and long name of this component's own outputs, or of a shared
        output whose meaning differs here (``Q`` of a chiller is not to air);
        shared outputs are declared in :mod:`evtms.benches.axes`.
    optional_outputs : tuple of str
        Outputs a LUT of this component may lack (evtms extensions the LUT
        format does not require, such as ``capacity_ratio``).
    surface_axes : tuple of (str, str)
        Axis pairs the bench report draws as response surfaces (the first
        pair the LUT has).
    main_output : (str, str)
        The output the bench report draws first, and the axis its line
        family runs along.
    """

    name: str
    title: str
    axes: tuple[str, ...]
    outputs: tuple[str, ...]
    flags: dict[int, str]
    evaluate: Evaluate
    parameters: Callable[[], Any]
    presets: dict[str, dict[str, tuple[float, ...]]] = field(default_factory=dict)
    extra_axes: tuple[str, ...] = ()
    valid_flags: tuple[int, ...] = (STATUS_VALID,)
    axis_specs: dict[str, AxisSpec] = field(default_factory=dict)
    variables: dict[str, tuple[str, str]] = field(default_factory=dict)
    optional_outputs: tuple[str, ...] = ()
    surface_axes: tuple[tuple[str, str], ...] = ()
    main_output: tuple[str, str] = ("Q", "mdot")

    def lut_spec(self) -> ComponentSpec:
        """What a LUT of this component holds, for the LUT layer (:mod:`evtms.luts.schema`)."""
        from evtms.benches.axes import AXES, VARIABLES

        names = [*self.axes, *(ALTERNATE_AXES[a] for a in self.axes if a in ALTERNATE_AXES), *self.extra_axes]
        axis_specs = {a: self.axis_specs[a] if a in self.axis_specs else AXES[a] for a in names}
        variables = {v: self.variables[v] if v in self.variables else VARIABLES[v] for v in self.outputs}
        required = tuple(v for v in self.outputs if v not in self.optional_outputs)
        return ComponentSpec(self.name, self.axes, self.extra_axes, axis_specs, variables, required)


def pressure_nodes(T_sat_celsius: np.ndarray) -> tuple[float, ...]:
    """Pressures [Pa] whose R134a saturation temperatures are about ``T_sat_celsius``.

    For placing grid nodes evenly in saturation temperature, where the coils'
    responses vary most evenly, without importing CoolProp: an Antoine fit
    ``ln p = 21.6652 - 2271.53 / (T - 23.0378 K)`` to CoolProp's R134a between
    235 K and 370 K (within 0.7 K), rounded to 1 Pa.
    """
    T = np.asarray(T_sat_celsius, float) + 273.15
    return tuple(float(v) for v in np.round(np.exp(21.665164 - 2271.5303 / (T - 23.037801))))


def in_flags(status: np.ndarray, flags: tuple[int, ...]) -> np.ndarray:
    """``np.isin(status, flags)`` for the few codes of a bench (a tenth of its cost on a cycle
    solver's one-point calls)."""
    out = np.zeros(np.shape(status), bool)
    for code in flags:
        out |= status == code
    return out


def finish_status(status: np.ndarray, outputs: dict[str, np.ndarray], valid_flags: tuple[int, ...]) -> None:
    """Flag points with a non-finite output as failed, and blank invalid points.

    Every float output of an invalid point becomes NaN, and a point that some
    model left non-finite without a reason gets ``STATUS_PROPERTY_FAILED``,
    so the LUT rule "valid points are finite" holds by construction.
    """
    valid = in_flags(status, valid_flags)
    finite = np.ones(status.shape, bool)
    for value in outputs.values():
        finite &= np.isfinite(value)
    status[valid & ~finite] = STATUS_PROPERTY_FAILED
    invalid = ~in_flags(status, valid_flags)
    for value in outputs.values():
        value[invalid] = np.nan


def first_code(conditions: list[tuple[np.ndarray, int]], n: int) -> np.ndarray:
    """int8 status array: the code of the first true condition per point, else 0."""
    status = np.zeros(n, np.int8)
    for mask, code in reversed(conditions):
        status[mask] = code
    return status
