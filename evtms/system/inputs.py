"""External inputs of a simulation: the thesis's Table 12 experiment inputs as numbers or traces.

Each input is a constant or a :class:`Trace` (values on the run's time,
linear between samples, held at the ends). The time loop reads them per step
as one array (:func:`per_step`, columns in :data:`INPUT_NAMES` order, NaN
where an input is not given, so the controller's own law applies):

- ``Q_battery_ext`` [W]: heat into the battery from outside (Table 12
  ``Qloss``), ``C_b dT_b/dt`` gains it; an external source in the system
  ledger;
- ``hvac_inlet_T`` [K], ``hvac_inlet_rh`` [1]: a fixed HVAC inlet air state
  (Table 12 ``Tin``) instead of the fresh/recirculated mix;
- ``SP_evap`` [K]: the evaporator outlet air setpoint (Table 12, thesis
  section 4.4);
- ``SP_CoHX`` [K]: the coolant temperature at the heater core's inlet
  (thesis ``SP_T_C_CoHX_in``, section 4.5);
- ``blower`` [1]: a fixed blower command in place of the blower law.

References
----------
Thesis Table 12 (inputs of the mode experiments); the project's system spec
v2, section 4.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

#: Inputs in the loop's column order.
INPUT_NAMES = ("Q_battery_ext", "hvac_inlet_T", "hvac_inlet_rh", "SP_evap", "SP_CoHX", "blower")
#: Allowed range per input (both ends included) and its units.
INPUT_RANGES: dict[str, tuple[float, float, str]] = {
    "Q_battery_ext": (-50e3, 50e3, "W"),
    "hvac_inlet_T": (233.15, 333.15, "K"),
    "hvac_inlet_rh": (0.0, 1.0, "1"),
    "SP_evap": (273.15, 298.15, "K"),
    "SP_CoHX": (288.15, 363.15, "K"),
    "blower": (0.0, 1.0, "1"),
}


@dataclass(frozen=True)
class Trace:
    """An input given over time.

    Attributes
    ----------
    time : numpy.ndarray
        Sample times [s] on the run's clock, strictly increasing.
    values : numpy.ndarray
        The input's values at the samples [its units].
    source : str
        Where it came from (``FILE.csv:column``).
    """

    time: np.ndarray
    values: np.ndarray
    source: str = ""

    def step_means(self, edges: np.ndarray) -> np.ndarray:
        """Mean over each step ``[edges[k], edges[k+1]]`` of the piecewise-linear trace, held at its ends."""
        t = np.concatenate(([min(edges[0], self.time[0]) - 1.0], self.time, [max(edges[-1], self.time[-1]) + 1.0]))
        v = np.concatenate((self.values[:1], self.values, self.values[-1:]))
        area = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
        # The integral is piecewise quadratic between samples; integrate exactly at the edges.
        k = np.clip(np.searchsorted(t, edges, side="right") - 1, 0, t.size - 2)
        tau = edges - t[k]
        slope = (v[k + 1] - v[k]) / (t[k + 1] - t[k])
        at = area[k] + v[k] * tau + 0.5 * slope * tau**2
        return np.diff(at) / np.diff(edges)


InputValue = float | Trace


def per_step(inputs: Mapping[str, InputValue] | None, edges: np.ndarray) -> np.ndarray:
    """The inputs as the loop reads them: (steps, len(INPUT_NAMES)), NaN where not given.

    Parameters
    ----------
    inputs : mapping of str to float or Trace, optional
        Inputs by name (:data:`INPUT_NAMES`); values in SI units.
    edges : numpy.ndarray
        Step boundaries [s] on the run's clock (preconditioning included).

    Returns
    -------
    numpy.ndarray
        Per step the mean of each given input over the step.
    """
    out = np.full((edges.size - 1, len(INPUT_NAMES)), np.nan)
    for name, value in (inputs or {}).items():
        col = INPUT_NAMES.index(name)
        out[:, col] = value.step_means(edges) if isinstance(value, Trace) else float(value)
    return out
