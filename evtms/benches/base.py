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

import numpy as np

from evtms.fluid import Fluid
from evtms.params import Parameters

Evaluate = Callable[[dict[str, np.ndarray], Parameters, Fluid], dict[str, np.ndarray]]

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
    presets : dict
        Grid preset name -> axis name -> values (SI).
    extra_axes : tuple of str
        Axes a grid may add after the standard ones.
    valid_flags : tuple of int
        Status codes whose points are valid (finite outputs).
    """

    name: str
    title: str
    axes: tuple[str, ...]
    outputs: tuple[str, ...]
    flags: dict[int, str]
    evaluate: Evaluate
    presets: dict[str, dict[str, tuple[float, ...]]] = field(default_factory=dict)
    extra_axes: tuple[str, ...] = ()
    valid_flags: tuple[int, ...] = (STATUS_VALID,)


def pressure_nodes(T_sat_celsius: np.ndarray) -> tuple[float, ...]:
    """Pressures [Pa] whose R134a saturation temperatures are about ``T_sat_celsius``.

    For placing grid nodes evenly in saturation temperature, where the coils'
    responses vary most evenly, without importing CoolProp: an Antoine fit
    ``ln p = 21.6652 - 2271.53 / (T - 23.0378 K)`` to CoolProp's R134a between
    235 K and 370 K (within 0.7 K), rounded to 1 Pa.
    """
    T = np.asarray(T_sat_celsius, float) + 273.15
    return tuple(float(v) for v in np.round(np.exp(21.665164 - 2271.5303 / (T - 23.037801))))


def finish_status(status: np.ndarray, outputs: dict[str, np.ndarray], valid_flags: tuple[int, ...]) -> None:
    """Flag points with a non-finite output as failed, and blank invalid points.

    Every float output of an invalid point becomes NaN, and a point that some
    model left non-finite without a reason gets ``STATUS_PROPERTY_FAILED``,
    so the LUT rule "valid points are finite" holds by construction.
    """
    valid = np.isin(status, valid_flags)
    finite = np.ones(status.shape, bool)
    for value in outputs.values():
        finite &= np.isfinite(value)
    status[valid & ~finite] = STATUS_PROPERTY_FAILED
    invalid = ~np.isin(status, valid_flags)
    for value in outputs.values():
        value[invalid] = np.nan


def first_code(conditions: list[tuple[np.ndarray, int]], n: int) -> np.ndarray:
    """int8 status array: the code of the first true condition per point, else 0."""
    status = np.zeros(n, np.int8)
    for mask, code in reversed(conditions):
        status[mask] = code
    return status
