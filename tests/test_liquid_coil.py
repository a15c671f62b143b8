"""Radiator and heater-core benches: the coolant-to-air core's balances, second law, trends and flags."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.benches import BENCHES
from evtms.benches.coil import air_stream
from evtms.benches.liquid_coil import (
    STATUS_BELOW_DEW_POINT,
    STATUS_CORRELATION_OUTSIDE_RANGE,
    STATUS_FLOW_NOT_POSITIVE,
    STATUS_FROST_RISK,
    STATUS_OUTSIDE_FLUID_RANGE,
    VALID_FLAGS,
)
from evtms.benches.parameters import Parameters
from evtms.fluid import coolant
from evtms.hx.effectiveness import crossflow_one_mixed_effectiveness
from evtms.hx.tube import hausen_nusselt, shah_london_nu_t

PARAMS = Parameters()
LIQUID_COILS = ("radiator", "heater_core")


def _random_inputs(n: int, seed: int = 3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "mdot_coolant": rng.uniform(0.02, 0.4, n),
        "T_coolant_in": rng.uniform(250.0, 370.0, n),
        "V_air": rng.uniform(0.01, 1.4, n),
        "T_air_in": rng.uniform(243.15, 323.15, n),
        "RH_air_in": rng.uniform(0.0, 1.0, n),
    }


def _run(component: str, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return BENCHES[component].evaluate(inputs, PARAMS, None)


@pytest.mark.parametrize("component", LIQUID_COILS)
def test_energy_closes_to_round_off_on_both_streams(component):
    inputs = _random_inputs(400)
    out = _run(component, inputs)
    valid = np.isin(out["status"], VALID_FLAGS)
    assert valid.mean() > 0.95
    cool = coolant()
    q_coolant = inputs["mdot_coolant"] * (cool.enthalpy(inputs["T_coolant_in"]) - cool.enthalpy(out["T_coolant_out"]))
    core = getattr(PARAMS, component)
    _, _, C_air, _, _ = air_stream(core, PARAMS.environment, inputs["V_air"], inputs["T_air_in"], inputs["RH_air_in"])
    q_air = C_air * (out["T_air_out"] - inputs["T_air_in"])
    scale = np.abs(out["Q"][valid]) + 1.0
    assert np.max(np.abs(q_coolant - out["Q"])[valid] / scale) < 1e-9
    assert np.max(np.abs(q_air - out["Q"])[valid] / scale) < 1e-9


@pytest.mark.parametrize("component", LIQUID_COILS)
def test_no_stream_leaves_beyond_the_other_inlet(component):
    inputs = _random_inputs(400, seed=5)
    out = _run(component, inputs)
    valid = np.isin(out["status"], VALID_FLAGS)
    T_c, T_a = inputs["T_coolant_in"][valid], inputs["T_air_in"][valid]
    lo, hi = np.minimum(T_c, T_a) - 1e-9, np.maximum(T_c, T_a) + 1e-9
    for key in ("T_coolant_out", "T_air_out"):
        assert np.all((out[key][valid] >= lo) & (out[key][valid] <= hi)), key
    assert np.all((out["effectiveness"][valid] > 0) & (out["effectiveness"][valid] <= 1))
    # Heat flows from the warmer stream to the colder one.
    assert np.all(np.sign(out["Q"][valid]) == np.sign(T_c - T_a))


def test_heat_rises_with_air_flow_coolant_flow_and_temperature_difference():
    base = {"mdot_coolant": 0.2, "T_coolant_in": 343.15, "V_air": 0.5, "T_air_in": 303.15, "RH_air_in": 0.4}

    def q_along(axis: str, values: np.ndarray) -> np.ndarray:
        inputs = {k: np.full(values.size, v) for k, v in base.items()}
        inputs[axis] = values
        return _run("radiator", inputs)["Q"]

    assert np.all(np.diff(q_along("V_air", np.linspace(0.1, 1.4, 8))) > 0)
    assert np.all(np.diff(q_along("mdot_coolant", np.linspace(0.05, 0.36, 8))) > 0)
    assert np.all(np.diff(q_along("T_coolant_in", np.linspace(310.0, 370.0, 8))) > 0)


def test_radiator_conductance_at_50_kmh_on_ram_air():
    # The system spec's estimate: 100-160 W/K at 50 km/h on ram air (0.40 m3/s through the front end)
    # with the pump at full flow; the louvred-fin air side gives a little more.
    out = _run(
        "radiator",
        {
            "mdot_coolant": np.array([0.356]),
            "T_coolant_in": np.array([313.15]),
            "V_air": np.array([0.40]),
            "T_air_in": np.array([283.15]),
            "RH_air_in": np.array([0.5]),
        },
    )
    assert 100.0 < out["UA"][0] < 200.0


def test_effectiveness_matches_the_closed_forms_and_is_continuous_where_the_rates_cross():
    NTU = np.linspace(0.0, 5.0, 51)
    zero = crossflow_one_mixed_effectiveness(NTU, np.zeros_like(NTU), np.zeros_like(NTU, bool))
    assert np.max(np.abs(zero - (1.0 - np.exp(-NTU)))) < 1e-12
    one_max = crossflow_one_mixed_effectiveness(NTU, np.ones_like(NTU), np.zeros_like(NTU, bool))
    one_min = crossflow_one_mixed_effectiveness(NTU, np.ones_like(NTU), np.ones_like(NTU, bool))
    closed = 1.0 - np.exp(-(1.0 - np.exp(-NTU)))
    assert np.max(np.abs(one_max - closed)) < 1e-12 and np.max(np.abs(one_min - closed)) < 1e-12
    # Infinite area: (1 - exp(-Cr)) / Cr with the larger stream mixed, 1 - exp(-1/Cr) with the smaller.
    big = np.array([200.0])
    Cr = 0.5
    limit_max = crossflow_one_mixed_effectiveness(big, np.array([Cr]), np.array([False]))[0]
    limit_min = crossflow_one_mixed_effectiveness(big, np.array([Cr]), np.array([True]))[0]
    assert limit_max == pytest.approx(-np.expm1(-Cr) / Cr, rel=1e-12)
    assert limit_min == pytest.approx(-np.expm1(-1.0 / Cr), rel=1e-12)


def test_laminar_coolant_side_limits():
    assert shah_london_nu_t(1.0) == pytest.approx(2.976, rel=1e-3)  # Shah and London's square duct
    assert shah_london_nu_t(1e-9) == pytest.approx(7.541, rel=1e-6)  # parallel plates
    long_tube = hausen_nusselt(np.array([500.0]), np.array([10.0]), 2e-3, 1e4, 3.66)
    assert long_tube[0] == pytest.approx(3.66, rel=1e-3)
    short = hausen_nusselt(np.array([500.0, 1000.0]), np.array([10.0, 10.0]), 2e-3, 0.5, 3.66)
    assert short[1] > short[0] > 3.66


def test_cold_humid_air_on_a_colder_core_is_flagged_frost_and_condensate():
    inputs = {
        "mdot_coolant": np.array([0.2, 0.2, 0.2]),
        "T_coolant_in": np.array([258.15, 280.15, 330.15]),
        "V_air": np.array([0.4, 0.4, 0.4]),
        "T_air_in": np.array([268.15, 293.15, 293.15]),
        "RH_air_in": np.array([0.9, 0.9, 0.9]),
    }
    status = _run("radiator", inputs)["status"]
    assert status[0] == STATUS_FROST_RISK
    assert status[1] == STATUS_BELOW_DEW_POINT
    assert status[2] in (0, STATUS_CORRELATION_OUTSIDE_RANGE)


def test_states_the_core_cannot_take_are_nan_with_their_reason():
    inputs = {
        "mdot_coolant": np.array([0.2, 0.0, 0.2]),
        "T_coolant_in": np.array([200.0, 330.0, 330.0]),
        "V_air": np.array([0.4, 0.4, 0.0]),
        "T_air_in": np.array([293.15, 293.15, 293.15]),
        "RH_air_in": np.array([0.5, 0.5, 0.5]),
    }
    out = _run("heater_core", inputs)
    assert list(out["status"]) == [STATUS_OUTSIDE_FLUID_RANGE, STATUS_FLOW_NOT_POSITIVE, STATUS_FLOW_NOT_POSITIVE]
    assert np.all(np.isnan(out["Q"])) and np.all(np.isnan(out["T_air_out"]))


def test_heater_core_heats_cabin_air_as_a_heater_core_does():
    # 0.15 m3/s of 10 degC air through the core fed 0.2 kg/s of 60 degC coolant: a few kW, the air
    # leaving tens of kelvin warmer (production heater cores: 5-8 kW at full flow).
    out = _run(
        "heater_core",
        {
            "mdot_coolant": np.array([0.2]),
            "T_coolant_in": np.array([333.15]),
            "V_air": np.array([0.15]),
            "T_air_in": np.array([283.15]),
            "RH_air_in": np.array([0.4]),
        },
    )
    assert 3e3 < out["Q"][0] < 9e3
    assert 20.0 < out["T_air_out"][0] - 283.15 < 50.0


@pytest.mark.parametrize(
    ("bench", "axis"),
    [("radiator", "V_air=-1"), ("heater-core", "T_coolant_in=120degC"), ("radiator", "RH_air_in=1.5")],
)
def test_bad_axis_values_are_one_line_exit_2_and_write_nothing(tmp_path, bench, axis):
    from conftest import one_error_line
    from typer.testing import CliRunner

    from evtms.cli import app

    out = tmp_path / "core.nc"
    res = CliRunner().invoke(app, ["bench", bench, "--axis", axis, "-o", str(out)])
    one_error_line(res, axis.split("=")[0])
    assert not out.exists() and not any(tmp_path.iterdir())
