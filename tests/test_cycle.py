"""Vapor-compression cycle on LUTs vs the direct-physics reference; states; trends; CLI."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.benches.parameters import Parameters
from evtms.cli import app
from evtms.cycle import OperatingPoints, run_cycle
from evtms.cycle.models import LutModels
from evtms.cycle.solver import (
    CYCLE_FLAGS,
    FROST_RISK_FLAGS,
    STATUS_CONDENSER_NO_ROOT,
    STATUS_CONVERGED,
    STATUS_EVAPORATOR_WET,
    STATUS_OUTSIDE_ENVELOPE,
    VALID_CYCLE_FLAGS,
    VALVE_SATURATED_FLAGS,
)
from evtms.fluid import Fluid

runner = CliRunner()


def envelope_points(n: int = 24, seed: int = 3) -> OperatingPoints:
    """Operating points spread over the cycle envelope (fixed seed)."""
    rng = np.random.default_rng(seed)
    return OperatingPoints(
        speed=rng.uniform(0.15, 1.0, n),
        fan=rng.uniform(0.2, 1.0, n),
        blower=rng.uniform(0.2, 1.0, n),
        T_amb=rng.uniform(288.15, 318.15, n),
        RH_amb=0.4,
        T_cabin=rng.uniform(290.15, 306.15, n),
        RH_cabin=rng.uniform(0.3, 0.7, n),
        superheat=rng.uniform(5.0, 10.0, n),
    )


@pytest.fixture(scope="module")
def comparison(cycle_luts):
    points = envelope_points()
    lut = run_cycle(points, cycle_luts)
    direct = run_cycle(points)
    return points, lut, direct


def test_lut_cycle_matches_direct_reference(comparison):
    _, lut, direct = comparison
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    assert ok.sum() >= 20
    for name in ("p_A", "p_B", "Q_evap", "COP"):
        err = np.abs(lut[name][ok] / direct[name][ok] - 1)
        # Measured (docs/guide/cycle.md): at most 0.71 % (discharge pressure), 0.77 % on COP, the median 0.07-0.13 %.
        assert err.max() < 0.01, (name, err.max(), int(np.argmax(err)))
        assert np.median(err) < 0.003, (name, np.median(err))


def test_direct_cycle_conserves_energy_and_lut_balance_below_half_percent(comparison):
    _, lut, direct = comparison
    ok_d = np.isin(direct["status"], VALID_CYCLE_FLAGS)
    assert (np.abs(direct["balance_relative"][ok_d]) < 1e-5).all()
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS)
    assert (np.abs(lut["balance_relative"][ok]) < 0.005).all()


def test_states_on_the_right_side_of_saturation(comparison):
    points, r, _ = comparison
    ok = np.isin(r["status"], VALID_CYCLE_FLAGS)
    curve = Fluid().saturation_curve()
    # A: superheated by the setpoint at the suction pressure, or more where the valve is saturated.
    superheat = r["T_A"] - curve.temperature(r["p_A"])
    np.testing.assert_allclose(superheat[ok], r["superheat_actual"][ok], atol=1e-6)
    held = np.isin(r["status"], (STATUS_CONVERGED, *FROST_RISK_FLAGS)) & ~np.isin(r["status"], VALVE_SATURATED_FLAGS)
    np.testing.assert_allclose(superheat[held], points.superheat[held], atol=1e-6)
    assert (superheat[ok] >= points.superheat[ok] - 1e-6).all()
    # B: superheated vapour at the high pressure.
    assert (r["T_B"][ok] > curve.temperature(r["p_B"][ok]) + 1).all()
    assert (r["p_B"][ok] > 1.2 * r["p_A"][ok]).all()
    assert (curve.temperature(r["p_B"][ok]) > points.T_amb[ok]).all()  # condensing above the ambient air
    # C: at (or below) saturation; D: two-phase at the evaporating pressure.
    assert (r["h_C"][ok] <= curve.liquid_enthalpy(r["p_C"][ok]) + 1e-6).all()
    x_D = (r["h_D"] - curve.liquid_enthalpy(r["p_D"])) / (
        curve.vapour_enthalpy(r["p_D"]) - curve.liquid_enthalpy(r["p_D"])
    )
    assert ((x_D[ok] > 0) & (x_D[ok] < 1)).all()
    assert (r["p_D"][ok] >= r["p_A"][ok]).all() and (r["p_D"][ok] < 1.1 * r["p_A"][ok]).all()
    assert (r["Q_evap"][ok] < 0).all() and (r["Q_cond"][ok] > r["W_fluid"][ok]).all()


def test_speed_and_ambient_trends(cycle_luts):
    speeds = np.linspace(0.2, 1.0, 6)
    r = run_cycle(OperatingPoints(speed=speeds, fan=0.6, blower=0.5, T_amb=303.15, T_cabin=300.15), cycle_luts)
    assert np.isin(r["status"], VALID_CYCLE_FLAGS).all()
    assert (np.diff(-r["Q_evap"]) > 0).all()  # more speed, more cooling
    assert (np.diff(r["p_A"]) < 0).all()  # and a lower evaporating pressure
    ambients = np.linspace(293.15, 313.15, 5)
    r = run_cycle(OperatingPoints(speed=0.5, fan=0.6, blower=0.5, T_amb=ambients, T_cabin=300.15), cycle_luts)
    assert np.isin(r["status"], VALID_CYCLE_FLAGS).all()
    assert (np.diff(r["p_B"]) > 0).all()  # hotter ambient, higher condensing pressure


def test_outside_the_envelope_names_the_axis(cycle_luts):
    # Cabin air at 55 degC is beyond the evaporator LUT's air axis (10-50 degC).
    r = run_cycle(OperatingPoints(speed=0.5, fan=0.5, blower=0.5, T_amb=303.15, T_cabin=328.15), cycle_luts)
    assert r["status"][0] == STATUS_OUTSIDE_ENVELOPE
    assert "evaporator LUT axis T_air_in" in r["reason"][0] and "328.15" in r["reason"][0]
    assert np.isnan(r["p_A"][0]) and np.isnan(r["COP"][0])


def test_condenser_cells_next_to_no_heat_nodes_in_a_later_iterate(cycle_luts):
    """Ambient at 2 degC, full speed: the discharge search meets condenser cells next to nodes where
    the refrigerant is not warmer than the air (no heat flows) only after its first iterates. The
    solver gathers the iterates' results; a key that appeared late (no_heat_flow) once raised
    KeyError. The low condensing pressure leaves the valve too little pressure drop: it saturates
    and the superheat floats at 46.6 K, evaporating near -10 degC, 48 K below the cabin air (the
    direct models: 46.63 K, p_A 199.0 kPa). Before the suction search reached below 45 K under the
    cabin air, both said 'the superheat stays below its setpoint' (status 3)."""
    point = OperatingPoints(
        speed=0.9968, fan=0.3243, blower=0.9235, T_amb=275.065, T_cabin=311.504, RH_cabin=0.4094, superheat=8.24
    )
    r = run_cycle(point, cycle_luts)
    assert r["status"][0] in VALVE_SATURATED_FLAGS, r["reason"]
    assert abs(r["superheat_actual"][0] - 46.63) < 0.5 and abs(r["p_A"][0] / 199.0e3 - 1) < 0.01
    assert np.isfinite(r["COP"][0])


def test_a_solved_state_where_a_branch_takes_no_heat_is_not_valid(cycle_luts, monkeypatch):
    """A root can sit on a jump of the superheat residual where the evaporator's LUT cell turns to
    'no heat flows'. Forced here: the final evaluation says no heat flows at the solved state. That
    point must not come out valid with NaN figures; it is outside the envelope, and says why."""
    point = OperatingPoints(speed=[0.5, 0.5], fan=0.5, blower=0.5, T_amb=303.15, T_cabin=300.15)
    calls = []
    evaporator = LutModels.evaporator

    def final_without_heat(self, *args):
        r = evaporator(self, *args)
        if self.luts["evaporator"].detailed:  # the final states' evaluation
            calls.append(1)
            r["no_heat_flow"] = np.array([True, False])[: r["no_heat_flow"].size]
        return r

    monkeypatch.setattr(LutModels, "evaporator", final_without_heat)
    r = run_cycle(point, cycle_luts)
    assert calls, "the final states were not evaluated in detail"
    assert r["status"].tolist() == [STATUS_OUTSIDE_ENVELOPE, STATUS_CONVERGED], r["reason"]
    assert "takes no heat" in r["reason"][0]
    assert np.isnan(r["COP"][0]) and np.isfinite(r["COP"][1])


def test_a_root_beyond_a_lut_pressure_axis_is_outside_the_envelope_not_its_end(cycle_luts):
    # Hot ambient, small fan, fast compressor: the direct physics condenses at 3.7 MPa,
    # beyond the condenser LUT's p_in axis (up to 3.29 MPa, 91 degC). The LUT cycle must
    # not return the axis' end as a root.
    point = OperatingPoints(
        speed=0.935, fan=0.132, blower=0.867, T_amb=309.69, T_cabin=297.8, RH_cabin=0.74, superheat=5.8
    )
    direct = run_cycle(point)
    assert np.isin(direct["status"], VALID_CYCLE_FLAGS).all()
    assert direct["p_B"][0] > float(cycle_luts["condenser"].axes["p_in"].max())
    lut = run_cycle(point, cycle_luts)
    assert lut["status"][0] == STATUS_OUTSIDE_ENVELOPE
    assert "condenser LUT axis p_in" in lut["reason"][0]
    assert np.isnan(lut["p_B"][0])


def test_valve_opening_matches_the_direct_reference(comparison):
    _, lut, direct = comparison
    ok = np.isin(lut["status"], VALID_CYCLE_FLAGS) & np.isin(direct["status"], VALID_CYCLE_FLAGS)
    # The orifice law with the valve's area; LUT states within 1 %, so the opening within 2 %.
    np.testing.assert_allclose(lut["valve_opening"][ok], direct["valve_opening"][ok], rtol=0.02)
    assert (lut["status"] == direct["status"]).mean() >= 0.9


def test_cli_cycle_run_and_envelope_error(cycle_luts_dir):
    res = runner.invoke(
        app,
        [
            "cycle",
            "run",
            "--luts",
            str(cycle_luts_dir),
            "--speed",
            "0.6",
            "--fan",
            "0.5",
            "--blower",
            "0.4",
            "--t-amb",
            "30",
            "--t-cabin",
            "27",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "A evaporator outlet" in res.stdout and "cooling COP" in res.stdout
    res = runner.invoke(app, ["cycle", "run", "--luts", str(cycle_luts_dir), "--t-cabin", "-20"])
    assert res.exit_code == 2
    assert res.stderr.startswith("error: operating point not solved: evaporator LUT axis T_air_in")
    assert len(res.stderr.strip().splitlines()) == 1
    res = runner.invoke(app, ["cycle", "run", "--luts", str(cycle_luts_dir), "--speed", "1.5"])
    assert res.exit_code == 2 and "speed = 1.5 is not allowed" in res.stderr
    res = runner.invoke(app, ["cycle", "run", "--luts", "/nonexistent/luts"])
    assert res.exit_code == 2 and "does not exist" in res.stderr


def test_cli_sweep_and_reports(tmp_path, cycle_luts_dir):
    out = tmp_path / "speed.nc"
    res = runner.invoke(app, ["cycle", "sweep", "--luts", str(cycle_luts_dir), "--speed", "0.3:1:5", "-o", str(out)])
    assert res.exit_code == 0, res.output
    import xarray as xr

    with xr.open_dataset(out) as ds:
        assert ds["Q_evap"].attrs["units"] == "W" and ds["p_A"].attrs["units"] == "Pa"
        assert ds.sizes["speed"] == 5 and np.isin(ds["status"].values, VALID_CYCLE_FLAGS).all()
        assert ds["superheat_actual"].attrs["units"] == "K"
        assert ds["status"].attrs["flag_meanings"].split() == [CYCLE_FLAGS[c] for c in sorted(CYCLE_FLAGS)]
        assert list(ds["status"].attrs["valid_flag_values"]) == list(VALID_CYCLE_FLAGS)
    for kind, name in (("ph-diagram", "ph.png"), ("pt-diagram", "pt.svg"), ("energy-balance", "eb.png")):
        res = runner.invoke(app, ["report", kind, str(out), "-o", str(tmp_path / name)])
        assert res.exit_code == 0, res.output
        assert (tmp_path / name).stat().st_size > 1000
    assert (tmp_path / "eb.csv").read_text().startswith("speed [1],Q_cond [W]")
    res = runner.invoke(app, ["report", "ph-diagram", str(out), "-o", str(tmp_path / "x.pdf")])
    assert res.exit_code == 2 and ".png or .svg" in res.stderr


def test_subcooled_condenser_outlet(cycle_luts):
    points = OperatingPoints(speed=[0.4, 0.8], fan=0.6, blower=0.5, T_amb=303.15, T_cabin=300.15, subcooling=3.0)
    fluid = Fluid()
    curve = fluid.saturation_curve()
    direct = run_cycle(points)
    lut = run_cycle(points, cycle_luts)
    for r, tol in ((direct, 0.05), (lut, 0.3)):
        assert np.isin(r["status"], VALID_CYCLE_FLAGS).all()
        # The outlet's real temperature (a CoolProp flash of its p and h) is 3 K below saturation.
        T_out = fluid.state("PH", r["p_C"], r["h_C"], ("T",))["T"]
        np.testing.assert_allclose(curve.temperature(r["p_C"]) - T_out, 3.0, atol=tol)
        np.testing.assert_allclose(r["T_C"], T_out, atol=0.05)
    np.testing.assert_allclose(lut["COP"], direct["COP"], rtol=0.01)


# --- the valve's limit, flooding and frost -----------------------------------------------

#: The demo's speed sweep (evtms cycle sweep --speed 0.2:1:9, every other input at its default).
DEMO = OperatingPoints(speed=np.linspace(0.2, 1.0, 9), fan=0.5, blower=0.4, T_amb=303.15, T_cabin=300.15)


def _orifice_opening(r, area):
    """Opening over the nominal that passes each point's flow at its valve drop (saturated liquid in)."""
    rho = Fluid().saturation_curve().liquid_density(r["p_C"])
    return r["mdot"] / (area * np.sqrt(2 * rho * r["dp_valve"]))


def test_default_valve_holds_the_superheat_at_the_demo_points(cycle_luts):
    r = run_cycle(DEMO, cycle_luts)
    valve, area = LutModels(cycle_luts).valve()
    max_opening = valve.capacity_max / valve.capacity_nominal
    assert np.isin(r["status"], VALID_CYCLE_FLAGS).all()
    assert not np.isin(r["status"], VALVE_SATURATED_FLAGS).any(), r["reason"]
    np.testing.assert_allclose(r["superheat_actual"], 10.0)
    # The valve passes the flow below its maximum opening, the more open the faster the compressor.
    np.testing.assert_allclose(r["valve_opening"], _orifice_opening(r, area), rtol=1e-9)
    assert (r["valve_opening"] < max_opening).all() and (np.diff(r["valve_opening"]) > 0).all()
    assert (np.abs(r["balance_relative"]) < 1e-5).all()


@pytest.fixture(scope="module")
def saturated(cycle_luts):
    """Cool ambient (low condensing pressure, small valve drop) and warm cabin air: the valve saturates."""
    points = OperatingPoints(
        speed=[0.6, 0.8, 0.8, 1.0],
        fan=[0.5, 0.5, 1.0, 1.0],
        blower=[0.7, 0.7, 0.4, 0.4],
        T_amb=288.15,
        T_cabin=[306.15] * 2 + [300.15] * 2,
    )
    return points, run_cycle(points, cycle_luts), run_cycle(points)


def test_saturated_valve_floats_the_superheat_alike_on_luts_and_direct(saturated, cycle_luts):
    points, lut, direct = saturated
    valve, area = LutModels(cycle_luts).valve()
    max_opening = valve.capacity_max / valve.capacity_nominal
    for r in (lut, direct):
        assert np.isin(r["status"], VALVE_SATURATED_FLAGS).all(), r["reason"]
        # At its maximum opening by the orifice law, the superheat above the 10 K setpoint.
        np.testing.assert_allclose(r["valve_opening"], max_opening)
        np.testing.assert_allclose(_orifice_opening(r, area), max_opening, rtol=1e-3)
        assert (r["superheat_actual"] > points.superheat + 1.0).all()
        assert (np.abs(r["balance_relative"]) < 1e-5).all()
        # A faster compressor pulls the suction pressure down further and the superheat up.
        assert r["superheat_actual"][1] > r["superheat_actual"][0] and r["p_A"][1] < r["p_A"][0]
        assert r["superheat_actual"][3] > r["superheat_actual"][2]
    # The colder evaporators of the last two (cabin air at 27 degC) also risk frost; the flags agree.
    np.testing.assert_array_equal(lut["status"], direct["status"])
    assert not np.isin(lut["status"][:2], FROST_RISK_FLAGS).any() and np.isin(lut["status"][2:], FROST_RISK_FLAGS).all()
    # Within the cycle's accuracy (docs/guide/cycle.md): 1 % on the states, 0.5 K on the superheat.
    np.testing.assert_allclose(lut["superheat_actual"], direct["superheat_actual"], atol=0.5)
    for name in ("p_A", "p_B", "Q_evap", "COP"):
        np.testing.assert_allclose(lut[name], direct[name], rtol=0.01, err_msg=name)


def test_a_larger_valve_holds_the_setpoint_the_default_cannot(saturated):
    points, _, direct = saturated
    params = Parameters()
    big = dataclasses.replace(params.expansion_valve, capacity_max=4 * params.expansion_valve.capacity_nominal)
    held = run_cycle(points, params=dataclasses.replace(params, expansion_valve=big))
    assert not np.isin(held["status"], VALVE_SATURATED_FLAGS).any()
    np.testing.assert_allclose(held["superheat_actual"], points.superheat)
    # Holding the setpoint needs more than the default valve's maximum: more flow, more cooling.
    assert (held["valve_opening"] > params.expansion_valve.capacity_max / params.expansion_valve.capacity_nominal).all()
    assert (held["mdot"] > direct["mdot"]).all() and (held["Q_evap"] < direct["Q_evap"]).all()


def test_flooded_evaporator_is_invalid():
    # A compressor 25 times the default's at a low blower: the evaporator cannot boil the flow
    # off even 45 K below the cabin air. The compressor would draw liquid: no valid state.
    params = Parameters()
    params = dataclasses.replace(params, compressor=dataclasses.replace(params.compressor, displacement=2e-3))
    r = run_cycle(OperatingPoints(speed=0.2, fan=1.0, blower=0.1, T_amb=298.15, T_cabin=293.15), params=params)
    assert r["status"][0] == STATUS_EVAPORATOR_WET and CYCLE_FLAGS[STATUS_EVAPORATOR_WET] == "evaporator_outlet_wet"
    assert STATUS_EVAPORATOR_WET not in VALID_CYCLE_FLAGS
    assert "two-phase" in r["reason"][0]
    assert np.isnan(r["p_A"][0]) and np.isnan(r["superheat_actual"][0])


def test_a_starved_chiller_on_hot_coolant_floats_its_superheat():
    """Full speed on 40-55 degC coolant: the default valve saturates and the superheat floats, rising
    with the coolant temperature, the suction evaporating 45-50 K below the coolant. The search's low
    end was 45 K below the coolant: from 43 degC the root lay beyond it and the point failed ('the
    superheat stays below its setpoint', at 50 degC 'the evaporator floods'). The bench physics, ~3 s."""
    T_coolant = np.array([40.0, 45.0, 55.0]) + 273.15
    r = run_cycle(OperatingPoints(speed=1.0, fan=0.5, T_amb=303.15, T_coolant_in=T_coolant), circuit="chiller")
    assert np.isin(r["status"], VALVE_SATURATED_FLAGS).all(), r["reason"]
    sh = r["superheat_actual"]
    assert (sh > 10.0).all() and (np.diff(sh) > 0).all() and (np.diff(r["p_A"]) > 0).all()
    assert (T_coolant - (r["T_A"] - sh) > 45.0)[1:].all()  # beyond the old low end
    assert (np.abs(r["balance_relative"]) < 1e-5).all()


def test_cold_coolant_points_close_their_energy_balance_or_say_why():
    """Coolant at -20 to -6 degC: the chiller evaporates near 0.5-1 bar and drops 30-45 % of its inlet
    pressure. Below -11.4 degC the suction search's low end (45 K below the coolant) fell off the
    saturation table and every point failed; above it, points were reported converged with the
    suction state kilojoules per kilogram off the chiller's outlet (energy balance off by up to 6 %
    of the fluid work). Now a point is valid with its balance closed, or not converged with the
    reason (most of them still: the suction residual jumps there; outside the chiller LUT's 0-50 degC)."""
    T = np.array([-20.0, -15.0, -12.5, -10.0, -7.5]) + 273.15
    points = OperatingPoints(speed=0.6, T_coolant_in=np.r_[T, T], mdot_coolant=np.repeat([0.15, 2.0], T.size))
    r = run_cycle(points, circuit="chiller")
    valid = np.isin(r["status"], VALID_CYCLE_FLAGS)
    assert valid.any()
    assert (np.abs(r["balance_relative"][valid]) < 1e-5).all()
    assert all("suction closure stopped" in x for x in r["reason"][~valid]), r["reason"][~valid]


def test_a_condenser_too_weak_at_every_suction_pressure_says_so_in_its_status():
    """Fan 0.05-0.1 at 45 degC ambient, full speed: at no discharge pressure does the condenser
    reach its outlet condition, at any suction pressure tried. The status was 1 (outside a model's
    envelope) with the condenser's reason; it is the condenser's own status 2."""
    r = run_cycle(OperatingPoints(speed=1.0, fan=np.array([0.05, 0.1]), T_amb=318.15))
    assert (r["status"] == STATUS_CONDENSER_NO_ROOT).all(), r["status"]
    assert CYCLE_FLAGS[STATUS_CONDENSER_NO_ROOT] == "condenser_outlet_condition_not_reachable"
    assert all("condenser cannot reach its outlet" in x for x in r["reason"])


def test_frost_risk_is_flagged_in_both_modes(cycle_luts, cycle_luts_dir):
    # Full speed, small fan and blower, hot ambient: the evaporator surface drops below 0 degC.
    points = OperatingPoints(
        speed=[1.0, 0.2], fan=[0.3, 0.5], blower=[0.3, 0.4], T_amb=[313.15, 303.15], T_cabin=[298.15, 300.15]
    )
    for r in (run_cycle(points, cycle_luts), run_cycle(points)):
        # Direct mode: the evaporator's own flag (1); LUT mode: its 0/1 indicator interpolated, flagged from 0.5.
        assert np.isin(r["status"][0], FROST_RISK_FLAGS) and r["frost_risk"][0] >= 0.5
        assert "frost" in r["reason"][0]
        assert r["T_D"][0] < 273.15  # evaporating below freezing
        assert r["status"][1] == STATUS_CONVERGED and r["frost_risk"][1] == 0.0 and r["reason"][1] == ""
    common = ["--speed", "1", "--fan", "0.3", "--blower", "0.3", "--t-amb", "40", "--t-cabin", "25"]
    res = runner.invoke(app, ["cycle", "run", "--luts", str(cycle_luts_dir), *common])
    assert res.exit_code == 0, res.output
    assert "frost risk" in res.stdout


def test_valid_status_is_isin_of_the_valid_flags_for_any_code():
    """The table lookup that replaces np.isin on small batches: the same answer for every code,
    False for codes that are not statuses (negative, or beyond the last)."""
    from evtms.cycle.status import CYCLE_FLAGS, VALID_CYCLE_FLAGS, valid_status

    codes = np.arange(-3, len(CYCLE_FLAGS) + 3)
    for dtype in (np.int8, np.int64):
        np.testing.assert_array_equal(valid_status(codes.astype(dtype)), np.isin(codes, VALID_CYCLE_FLAGS))
    assert valid_status(np.int8(0)) and not valid_status(np.int8(1))
