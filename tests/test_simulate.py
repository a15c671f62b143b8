"""System simulator (spec section 7): ledgers, analytic cases, limits and controller behaviour.

The refrigerant loop here runs on small synthetic cycle maps that close their
energy balance exactly (Q_condenser = Q_evaporator + Q_chiller + W_fluid at
every node) and fall in suction pressure with speed, so these tests check
the simulator itself; ``test_simulate_cli.py`` runs it on maps built from
the cycle LUTs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import DriveCycle, drive_cycle
from evtms.system.maps import CycleMap
from evtms.system.params import SystemParams, system_params_from_dict
from evtms.system.refrigerant import Refrigerant
from evtms.system.simulate import simulate


def _map(name: str, axes: tuple[str, ...], nodes: list[list[float]], evap: float, chill: float) -> CycleMap:
    grids = np.meshgrid(*[np.asarray(n, float) for n in nodes], indexing="ij")
    speed, fan = grids[0], grids[1]
    v = np.zeros((*speed.shape, 9))
    W = 3000.0 * speed
    q_e, q_c = evap * 6000.0 * speed, chill * 5000.0 * speed
    v[..., 0] = 0.3e6 / (0.5 + speed)  # suction pressure falls as the compressor speeds up
    v[..., 1] = 1.0e6 + 1.0e6 * speed * (1.2 - fan)  # less condenser air, higher discharge pressure
    v[..., 2] = 0.05 * speed
    v[..., 3], v[..., 4], v[..., 5] = q_e, 0.2 * q_e, q_c
    v[..., 7], v[..., 8] = W, 0.9 * W
    v[..., 6] = q_e + q_c + 0.9 * W
    return CycleMap(name, axes, tuple(np.asarray(n, float) for n in nodes), v, 0)


@pytest.fixture(scope="module")
def refrigerant() -> Refrigerant:
    sp, fan, Ta, Tair, Tc = [0.1, 0.5, 1.0], [0.2, 1.0], [263.15, 323.15], [283.15, 323.15], [273.15, 323.15]
    maps = {
        "ac": _map(
            "ac",
            ("speed", "fan", "blower", "T_amb", "T_air_in", "RH_air_in"),
            [sp, fan, [0.1, 1], Ta, Tair, [0.2, 0.8]],
            1,
            0,
        ),
        "chiller": _map(
            "chiller", ("speed", "fan", "u_pump", "T_amb", "T_coolant_in"), [sp, fan, [0.3, 1], Ta, Tc], 0, 1
        ),
        "ac+chiller": _map(
            "ac+chiller",
            ("speed", "fan", "blower", "u_pump", "T_amb", "T_air_in", "T_coolant_in"),
            [sp, fan, [0.1, 1], [0.3, 1], Ta, Tair, Tc],
            0.6,
            0.5,
        ),
    }
    T = np.linspace(220.0, 370.0, 301)
    p = 2.9e5 * np.exp(0.037 * (T - 273.15))  # R134a-like: 0.29 MPa at 0 degC
    return Refrigerant(maps, T, p, 4e-4 * 1070.0)


def parked(seconds: float) -> DriveCycle:
    t = np.arange(0.0, seconds + 1.0)
    return DriveCycle("parked", t, np.zeros_like(t), np.zeros_like(t), "test")


def params(**tables) -> SystemParams:
    return system_params_from_dict(tables)


WLTC = drive_cycle("wltc3b")


@pytest.mark.parametrize("T_amb", [313.15, 268.15])
@pytest.mark.parametrize("dt", [0.1, 1.0, 10.0])
def test_every_ledger_closes(refrigerant, T_amb, dt):
    r = simulate(WLTC, T_amb, refrigerant, dt=dt, sun=600.0)
    assert set(r.ledgers) == {
        "vehicle",
        "battery_electrical",
        "battery_thermal",
        "coolant",
        "heater_loop",
        "cabin",
        "refrigerant",
        "edrive",
        "system",
    }
    for name, residual in r.ledgers.items():
        assert residual <= 1e-9, (name, residual)
    assert r.summary["distance_km"] == pytest.approx(23.2663, abs=5e-5)


def test_ledgers_close_with_rc_branch_fresh_air_and_no_interior(refrigerant):
    p = params(
        battery={"r2": 0.02, "c2": 2000.0},
        cabin={"recirc_cool": 0.3, "recirc_heat": 0.2, "interior_heat_capacity": 0.0},
    )
    r = simulate(WLTC, 308.15, refrigerant, p, dt=0.5)
    assert max(r.ledgers.values()) <= 1e-9, r.ledgers
    assert np.nanmax(np.abs(r.records["v_rc"])) > 0.1  # the branch did carry a voltage


def test_distance_is_exact_at_any_step(refrigerant):
    for dt in (0.1, 1.0, 7.0, 10.0):
        r = simulate(WLTC, 298.15, refrigerant, dt=dt)
        assert r.records["distance"][-1] == pytest.approx(23266.3, abs=0.05)
        assert r.records["time"][-1] == 1800.0


def test_one_compiled_loop_whatever_the_tables_came_as(refrigerant):
    """Maps and a saturation curve read from files (read-only, memory mapped) or made in memory (writable)
    reach the loop as one argument type: numba compiles it once per type, for about 20 s."""
    from evtms._jit import numba_enabled

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set)")

    def read_only(a: np.ndarray) -> np.ndarray:
        a = a.copy()
        a.flags.writeable = False
        return a

    maps = {name: dataclasses.replace(m, values=read_only(m.values)) for name, m in refrigerant.maps.items()}
    mdot = refrigerant.coolant_mdot_max
    mapped = Refrigerant(maps, read_only(refrigerant.sat_T), read_only(refrigerant.sat_p), mdot)
    made = Refrigerant(refrigerant.maps, refrigerant.sat_T.copy(), refrigerant.sat_p.copy(), mdot)
    runs = [simulate(parked(10.0), 298.15, ref) for ref in (mapped, made)]
    assert runs[0].summary["T_cabin_end_degC"] == runs[1].summary["T_cabin_end_degC"]
    assert len(L.run_loop.signatures) == 1, L.run_loop.signatures


def test_passive_cabin_follows_the_matrix_exponential(refrigerant):
    """25 -> 40 degC ambient, every source off: the 4-node network's exact solution within 0.05 K."""
    p = params(cabin={"interior_heat_capacity": 0.0, "n_occupants": 0}, vehicle={"aux_power": 0.0})
    T_amb, T0 = 313.15, 298.15
    r = simulate(parked(3000.0), T_amb, refrigerant, p, dt=0.1, mode="off", T_init=T0)
    c = p.cabin
    C_air = 101325.0 / (287.05 * T_amb) * c.volume * 1006.0
    G = [c.wall_conductance(w) for w in ("glass", "doors", "roof")]
    Cw = [c.glass_heat_capacity, c.doors_heat_capacity, c.roof_heat_capacity]
    C = np.diag([C_air, *Cw])
    K = np.zeros((4, 4))
    for i, g in enumerate(G):
        K[0, 0] += g
        K[i + 1, i + 1] += 2 * g
        K[0, i + 1] = K[i + 1, 0] = -g
    A = -np.linalg.solve(C, K)
    taus = np.sort(-1.0 / np.linalg.eigvals(A).real)
    assert taus == pytest.approx([23.9, 228.4, 1088.0, 2044.7], rel=2e-3)  # the spec's time constants
    t = r.records["time"]
    exact = np.array([T_amb + (scipy.linalg.expm(A * tk) @ np.full(4, T0 - T_amb))[0] for tk in t[::50]])
    assert np.max(np.abs(r.records["T_cabin"][::50] - exact)) <= 0.05
    assert r.records["T_cabin"][-1] < T_amb


def test_battery_at_rest_keeps_its_charge_and_emf(refrigerant):
    p = params(vehicle={"aux_power": 0.0})
    r = simulate(parked(600.0), 298.15, refrigerant, p, mode="off")
    assert np.all(r.records["SOC"] == p.battery.soc_init)
    assert np.all(r.records["i_battery"][1:] == 0.0)
    from evtms.system.battery import Battery

    assert r.records["v_battery"][1:] == pytest.approx(float(Battery().emf(0.9)), rel=1e-12)


def test_rc_voltage_decays_with_r2_c2_at_rest(refrigerant):
    trace = WLTC.time[:301], WLTC.speed[:301]
    t = np.concatenate((trace[0], 300.0 + np.arange(1.0, 601.0)))
    v = np.concatenate((trace[1], np.zeros(600)))
    cycle = DriveCycle("drive-then-rest", t, v, np.zeros_like(t), "test")
    r2, c2 = 0.01, 5000.0
    p = params(battery={"r2": r2, "c2": c2}, vehicle={"aux_power": 0.0})
    r = simulate(cycle, 298.15, refrigerant, p, mode="off")
    rest = r.records["time"] >= 320.0
    v_rc = r.records["v_rc"][rest]
    assert abs(v_rc[0]) > 1e-3
    ratio = v_rc[1:] / v_rc[:-1]
    assert ratio == pytest.approx(np.exp(-1.0 / (r2 * c2)), rel=1e-9)


def test_soc_stays_in_its_window(refrigerant):
    full = params(battery={"soc_init": 0.98})
    r = simulate(WLTC, 298.15, refrigerant, full)
    assert np.nanmax(r.records["SOC"]) <= 0.98 + 1e-12
    assert np.any(r.flags & L.F_REGEN_CUT)
    small = params(battery={"n_parallel": 1, "cell_capacity": 0.4})
    r = simulate(WLTC, 298.15, refrigerant, small)
    assert r.summary["termination"] == "soc_min"
    assert r.summary["duration_s"] < 1800.0
    assert r.records["SOC"][-1] < 0.05 <= r.records["SOC"][-2]


def test_commands_stay_in_zero_one(refrigerant):
    for T_amb in (263.15, 298.15, 318.15):
        r = simulate(WLTC, T_amb, refrigerant, dt=0.5, sun=600.0)
        for name in ("compressor_speed", "blower", "u_pump"):
            x = r.records[name][1:]
            assert np.all((x >= 0.0) & (x <= 1.0)), name


def test_power_is_capped_at_the_cell_voltage_floor(refrigerant):
    from evtms.system.battery import Battery

    v_min = round(float(Battery().emf(0.9)) / 96 - 0.01, 3)  # 10 mV per cell of headroom at the start
    p = params(battery={"cell_voltage_min": v_min})
    r = simulate(WLTC, 298.15, refrigerant, p, dt=1.0)
    assert np.any(r.flags & L.F_POWER_LIMITED)
    assert np.nanmin(r.records["v_battery"]) >= 96 * v_min * (1 - 1e-9)


def test_cold_start_heats_the_cabin_and_the_battery_loop(refrigerant):
    r = simulate(WLTC, 263.15, refrigerant, dt=1.0)
    modes = set(r.mode[1:].tolist())
    assert L.CH in modes or L.CH_BH in modes
    assert np.nanmax(r.records["P_ptc"]) > 1000.0
    assert np.nanmax(r.records["P_heater"]) == pytest.approx(4000.0)
    T_cab = r.records["T_cabin"]
    assert T_cab[-1] > 273.15 + 15.0  # warming toward the 25 degC setpoint
    assert r.records["T_coolant"][-1] > 263.15


def test_hot_soak_pulls_cabin_and_battery_down(refrigerant):
    r = simulate(WLTC, 313.15, refrigerant, dt=1.0, sun=600.0, T_init=313.15)
    assert L.CC_BC in set(r.mode[1:].tolist())
    assert r.records["T_cabin"][-1] < 313.15 - 5.0
    assert r.records["T_battery"][-1] < 313.15
    mild = simulate(WLTC, 295.15, refrigerant, dt=1.0)
    assert r.summary["soc_end"] < mild.summary["soc_end"]
    assert r.summary["hvac_energy_kWh"] > mild.summary["hvac_energy_kWh"]


def test_forced_mode_runs_its_controllers_only(refrigerant):
    r = simulate(WLTC, 298.15, refrigerant, mode="cc")
    assert set(r.mode.tolist()) == {L.CC}
    speed = r.records["compressor_speed"][1:]
    assert np.all((speed == 0.0) | (speed >= 0.1 - 1e-12))  # cycled off, or at least its minimum speed
    assert np.all(r.records["P_ptc"][1:] == 0.0)  # forced cooling never heats
    r = simulate(WLTC, 298.15, refrigerant, mode="off")
    assert np.all(r.records["P_hvac"][1:] == 0.0)


def test_mode_holds_at_least_a_minute(refrigerant):
    r = simulate(WLTC, 303.15, refrigerant, dt=1.0, sun=600.0)
    changes = np.flatnonzero(np.diff(r.mode[1:].astype(int))) + 1
    assert np.all(np.diff(r.records["time"][1:][changes]) >= 60.0)


def test_refrigerant_filter_keeps_the_map_closure_every_record(refrigerant):
    r = simulate(WLTC, 313.15, refrigerant, dt=1.0, sun=600.0)
    rec = r.records
    # W_fluid = 0.9 W in the synthetic maps; the common linear filter keeps the relation exactly.
    residual = rec["Q_condenser"] - rec["Q_evaporator"] - rec["Q_chiller"] - 0.9 * rec["P_compressor"]
    assert np.nanmax(np.abs(residual)) <= 1e-9 * np.nanmax(rec["Q_condenser"])


def test_bad_arguments_are_one_line_errors(refrigerant):
    with pytest.raises(EvtmsInputError, match="`dt`"):
        simulate(WLTC, 298.15, refrigerant, dt=0.0)
    with pytest.raises(EvtmsInputError, match="`mode`"):
        simulate(WLTC, 298.15, refrigerant, mode="heat")
    with pytest.raises(EvtmsInputError, match="`output_every`"):
        simulate(WLTC, 298.15, refrigerant, dt=0.3, output_every=1.0)


def test_parameter_tables_are_checked():
    with pytest.raises(EvtmsInputError, match=r"\[cabin\] volume = -1"):
        system_params_from_dict({"cabin": {"volume": -1}})
    with pytest.raises(EvtmsInputError, match=r"\[cabin\] unknown parameter 'volumen'"):
        system_params_from_dict({"cabin": {"volumen": 3}})
    with pytest.raises(EvtmsInputError, match=r"table \[hvacs\] is unknown"):
        system_params_from_dict({"hvacs": {}})
    with pytest.raises(EvtmsInputError, match="bc_off < bc_on"):
        system_params_from_dict({"controls": {"bc_off": 320.0}})
    p = system_params_from_dict({"battery": {"n_series": 100}})
    assert dataclasses.asdict(p.battery)["n_series"] == 100


def test_docs_list_every_output_variable_and_parameter():
    from pathlib import Path

    from evtms.reports.parameter_docs import documented_sections, render
    from evtms.system.params import SECTIONS
    from evtms.system.simulate import RECORD_VARIABLES

    docs = Path(__file__).resolve().parents[1] / "docs"
    fmt = (docs / "simulation-format.md").read_text(encoding="utf-8")
    for name in [*RECORD_VARIABLES, "mode", "flags"]:
        assert f"`{name}`" in fmt, name
    for flag in L.FLAG_NAMES:
        assert flag in fmt, flag
    table = (docs / "system-parameters.md").read_text(encoding="utf-8")
    assert documented_sections(table) == list(SECTIONS)
    assert render(table) == table, "docs/system-parameters.md: rerun python3 -m evtms.reports.parameter_docs on it"


def test_output_file_round_trip(refrigerant, tmp_path):
    import json

    import xarray as xr

    from evtms.system.output import write_simulation

    runs = [simulate(WLTC, T, refrigerant) for T in (268.15, 303.15)]
    path = write_simulation(runs, tmp_path / "sweep.nc")
    with xr.open_dataset(path) as ds:
        assert ds["T_cabin"].dims == ("T_amb", "time")
        assert ds["T_amb"].values.tolist() == [268.15, 303.15]
        assert ds["mode"].dtype == np.int8 and ds["flags"].dtype == np.uint16
        assert np.array_equal(ds["T_battery"].values[1], runs[1].records["T_battery"])
        assert json.loads(ds.attrs["summary"])[0]["soc_end"] == runs[0].summary["soc_end"]
        assert json.loads(ds.attrs["parameters"])["cabin"]["T_set"] == 295.15
        assert np.isnan(ds["P_battery"].values[0, 0])
    one = write_simulation(runs[:1], tmp_path / "one.nc")
    with xr.open_dataset(one) as ds:
        assert ds["SOC"].dims == ("time",)
        assert ds.attrs["T_amb"] == 268.15


@pytest.mark.parametrize("ambients", [(303.15,), (268.15, 303.15)], ids=["one run", "two ambients"])
def test_output_writer_makes_the_file_xarray_makes(refrigerant, tmp_path, ambients):
    """The netCDF4 writer's file reads back as the file xarray's to_netcdf writes from the same Dataset:
    every variable bit for bit, every attribute but the time stamp, the storage (compression, chunks, fill)."""
    import netCDF4
    import xarray as xr

    from evtms.system.output import to_dataset, write_simulation

    runs = [simulate(WLTC, T, refrigerant) for T in ambients]
    runs[-1].records["T_cabin"][5] = np.nan  # a NaN inside the data survives both writers
    ours = write_simulation(runs, tmp_path / "netcdf4.nc")
    ds = to_dataset(runs)
    ds.to_netcdf(
        tmp_path / "xarray.nc",
        engine="netcdf4",
        format="NETCDF4",
        encoding={k: {"zlib": True, "complevel": 1} for k in ds.data_vars},
    )
    with netCDF4.Dataset(ours) as a, netCDF4.Dataset(tmp_path / "xarray.nc") as b:
        assert a.data_model == b.data_model == "NETCDF4"
        assert {d: len(v) for d, v in a.dimensions.items()} == {d: len(v) for d, v in b.dimensions.items()}
        assert a.ncattrs() == b.ncattrs()
        for k in a.ncattrs():
            if k != "created":
                assert type(a.getncattr(k)) is type(b.getncattr(k)) and a.getncattr(k) == b.getncattr(k), k
        assert list(a.variables) == list(b.variables)
        for name, va in a.variables.items():
            vb = b.variables[name]
            va.set_auto_maskandscale(False)
            vb.set_auto_maskandscale(False)
            assert (va.dtype, va.dimensions, va.chunking(), va.filters()) == (
                vb.dtype,
                vb.dimensions,
                vb.chunking(),
                vb.filters(),
            ), name
            assert va.ncattrs() == vb.ncattrs(), name
            for k in va.ncattrs():
                x, y = va.getncattr(k), vb.getncattr(k)
                assert (
                    np.asarray(x).dtype == np.asarray(y).dtype and np.asarray(x).tobytes() == np.asarray(y).tobytes()
                ), (name, k)
            assert va[...].tobytes() == vb[...].tobytes(), name
    with xr.open_dataset(ours) as x, xr.open_dataset(tmp_path / "xarray.nc") as y:
        y.attrs["created"] = x.attrs["created"]
        xr.testing.assert_identical(x, y)
        assert np.isnan(x["T_cabin"].values.reshape(len(ambients), -1)[-1, 5])


def test_precondition_runs_on_the_grid_before_the_cycle(refrigerant):
    hot = dict(T_init=313.15, sun=600.0)
    plain = simulate(WLTC, 313.15, refrigerant, **hot)
    pre = simulate(WLTC, 313.15, refrigerant, precondition=600.0, **hot)
    assert pre.records["time"][0] == -600.0 and pre.records["time"][-1] == 1800.0
    assert pre.summary["duration_s"] == 1800.0
    assert pre.summary["precondition_grid_kWh"] > 0.05
    start = pre.records["time"] == 0.0
    assert pre.records["SOC"][start][0] == pytest.approx(0.9, abs=1e-12)  # the battery did not pay
    assert pre.records["T_cabin"][start][0] < 313.15 - 5.0  # cooled while parked
    assert pre.summary["hvac_energy_kWh"] < plain.summary["hvac_energy_kWh"]
    assert max(pre.ledgers.values()) <= 1e-9
    s = pre.summary
    parts = s["motor_energy_kWh"] + s["hvac_cabin_kWh"] + s["battery_thermal_kWh"] + s["aux_energy_kWh"]
    parts += s["edrive_cooling_kWh"]
    assert parts + s["battery_loss_kWh"] == pytest.approx(s["battery_chemical_kWh"], rel=1e-9)
    with pytest.raises(EvtmsInputError, match="`precondition`"):
        simulate(WLTC, 313.15, refrigerant, precondition=0.5)


def test_a_lean_numba_runs_the_loop_and_leaves_scipy_importable():
    """After evtms._jit.lean_numba the compiled kernels run, numba imported neither SciPy nor cffi,
    and both still import for whoever needs them."""
    import subprocess
    import sys

    from evtms._jit import numba_enabled

    if not numba_enabled():
        pytest.skip("numba is not importable (or EVTMS_NO_NUMBA is set)")
    code = (
        "import sys; from evtms._jit import lean_numba, numba_enabled; lean_numba();"
        "from evtms.system import loop; w = loop.humidity_ratio(303.15, 0.5, 101325.0);"
        "assert numba_enabled() and hasattr(loop.humidity_ratio, 'py_func');"
        "before = [m for m in ('scipy', 'cffi') if m in sys.modules];"
        "import scipy.linalg, cffi;"
        "print(repr(w), before)"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    value, before = res.stdout.strip().split(" ", 1)
    assert float(value) == L.humidity_ratio(303.15, 0.5, 101325.0)  # the same machine code's number
    assert before == "[]"


def test_simulate_drives_a_deviated_trace_and_its_ledgers_close(refrigerant):
    """The input speed_deviation (within [vehicle] delta_v_ref) changes the drive: 1.5 m/s slower on a UDDS is
    less distance on less traction energy, every ledger closed; with delta_v_ref 0 it is refused."""
    cycle = drive_cycle("udds")
    bounded = params(vehicle={"delta_v_ref": 2.0})
    base = simulate(cycle, 298.15, refrigerant, bounded).summary
    slow = simulate(cycle, 298.15, refrigerant, bounded, inputs={"speed_deviation": -1.5}).summary
    assert slow["distance_km"] < base["distance_km"] - 0.5
    assert slow["traction_energy_kWh"] < base["traction_energy_kWh"]
    assert slow["ledger_worst"] < 1e-9
    with pytest.raises(EvtmsInputError, match="delta_v_ref above 0"):
        simulate(cycle, 298.15, refrigerant, inputs={"speed_deviation": -1.5})
