"""The cycle's compiled component call gives the step-by-step path's numbers and reasons, bit for bit.

:meth:`evtms.cycle.models._LutComponent.__call__` evaluates a LUT in one
compiled call (:mod:`evtms.cycle._component_kernel`: axis checks,
interpolation, the outlet's approach transform); the reference is the same
method with that call switched off (the interpolator, then the transform,
with Python between them). Queries reach beyond every axis, carry NaN and
inputs off a LUT's fixed value, so that every kind of reason is compared.
"""

from __future__ import annotations

import numpy as np
import pytest

from evtms.cycle.models import LutModels, _LutComponent
from evtms.luts.interp import compiled_kernel

pytestmark = pytest.mark.skipif(compiled_kernel() is None, reason="numba is not importable (or EVTMS_NO_NUMBA is set)")

#: The model call of each component and the LUT axis (or fixed input) behind each of its arguments.
CALLS = {
    "compressor": ("compressor", ("speed", "T_in", "p_in", "pr")),
    "condenser": ("condenser", ("mdot", "fan", "p_in", "h_in", "T_air_in", "RH_air_in")),
    "evaporator": ("evaporator", ("mdot", "blower", "p_in", "h_in", "T_air_in", "RH_air_in")),
    "chiller": ("chiller", ("mdot", "p_in", "h_in", "mdot_coolant", "T_coolant_in")),
}


@pytest.fixture(scope="module")
def models(cycle_luts_dir):
    from evtms.cycle import load_cycle_luts

    luts = load_cycle_luts(cycle_luts_dir, "cabin+chiller")
    return LutModels(luts, ("condenser", "evaporator", "expansion_valve", "compressor", "chiller"))


def _arguments(component: _LutComponent, names, rng, n: int) -> list[np.ndarray]:
    """Random values over each axis and 5 % beyond it, a few NaN; a fixed input mostly at its value."""
    args = []
    for name in names:
        if name in component.ranges:
            lo, hi = component.ranges[name]
            x = rng.uniform(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo), n)
        else:
            fixed = component.fixed[name]
            x = np.where(rng.random(n) < 0.9, fixed, fixed * 1.1)
        x[rng.random(n) < 0.02] = np.nan
        args.append(x)
    return args


@pytest.mark.parametrize("component", list(CALLS))
@pytest.mark.parametrize("detailed", [False, True])
def test_compiled_call_equals_the_step_by_step_path(models, component, detailed, monkeypatch):
    method, names = CALLS[component]
    lut = models.luts[component]
    args = _arguments(lut, names, np.random.default_rng(len(component)), 600)
    models.detailed(detailed)
    try:
        fast = getattr(models, method)(*args)
        with monkeypatch.context() as m:
            m.setattr(_LutComponent, "_kernel_for", lambda self, itp: None)
            reference = getattr(models, method)(*args)
    finally:
        models.detailed(False)
    assert fast.keys() == reference.keys()
    for key, value in reference.items():
        if value.dtype == object:
            assert list(fast[key]) == list(value), key
        else:
            np.testing.assert_array_equal(fast[key], value, err_msg=key)
    reasons = reference["reason"]
    # The comparison covers points beyond an axis and, where the LUT holds one fixed, off its value.
    assert any("outside" in r for r in reasons)
    if set(lut._fixed_axes) & set(names):
        assert any("fixed at" in r for r in reasons)
    # And points inside every axis with finite outputs: the usual call.
    assert np.isfinite(reference["p_out" if component != "compressor" else "mdot"]).sum() > 100


def test_the_compiled_call_is_taken(models, monkeypatch):
    """The comparison above compares two paths: the compiled one runs where its interpolator is compiled."""
    calls = []
    original = _LutComponent._call_kernel
    monkeypatch.setattr(_LutComponent, "_call_kernel", lambda self, *a: calls.append(1) or original(self, *a))
    lut = models.luts["evaporator"]
    models.evaporator(*[np.array([0.5 * sum(lut.ranges[d])]) for d in CALLS["evaporator"][1]])
    assert calls == [1]
