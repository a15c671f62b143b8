"""Package tables of the system simulator (MW P numbers) and the clamped bilinear lookup."""

from __future__ import annotations

import json

import numpy as np
import pytest

from evtms.system.tables import (
    DATA,
    battery_cell_tables,
    bilinear_clamped,
    edrive_tables,
)

RPM = np.pi / 30.0  # rad/s per rpm


def test_edrive_axes_and_shapes():
    ed = edrive_tables()
    np.testing.assert_array_equal(ed.speed_rpm, [500, 1000, 2000, 3000, 4000, 5000, 6000, 7000, 8000, 10000])
    np.testing.assert_array_equal(ed.torque_Nm, [10, 20, 40, 60, 80, 100, 120, 150, 180, 200])
    assert ed.loss_W.shape == (10, 10)
    assert ed.max_torque_Nm == 200.0 and ed.max_power_W == 100e3
    assert ed.curve_speed_rpm.shape == ed.curve_torque_Nm.shape == (200,)
    assert ed.curve_speed_rpm[0] == 1.0 and ed.curve_speed_rpm[-1] == 23875.0


def test_loss_map_values_physical_and_placeholders():
    ed = edrive_tables()
    loss = ed.loss_W
    assert np.all(loss >= 0)
    # Source literals, without the source's factor 1.1 (corners of the measured part).
    assert loss[0, 0] == 49.74 and loss[0, -1] == 879.28 and loss[-1, 0] == 974.03
    shaft = RPM * ed.speed_rpm[:, None] * ed.torque_Nm[None, :]
    placeholder = np.round(shaft / 2, 2) == loss
    # The source's placeholder, half the shaft power, fills exactly the cells at >= 62.8 kW.
    assert placeholder.sum() == 31
    np.testing.assert_array_equal(placeholder, shaft > 60e3)
    # Measured cells: efficiency between 90 % and 99 %.
    eff = shaft / (shaft + loss)
    assert 0.90 < eff[~placeholder].min() and eff[~placeholder].max() < 0.99


def test_torque_curve_capped_at_200_Nm_and_100_kW():
    ed = edrive_tables()
    trq, n = ed.curve_torque_Nm, ed.curve_speed_rpm
    assert np.all(trq <= 200.0) and np.all(trq > 0)
    power = trq * n * RPM
    assert power.max() == pytest.approx(100e3, rel=1e-9)
    np.testing.assert_allclose(trq, np.minimum(200.0, 100e3 / (n * RPM)), rtol=1e-9)
    corner = 100e3 / 200.0 / RPM  # 4774.6 rpm
    assert np.all(trq[n < corner] == 200.0)
    assert np.all(np.diff(trq) <= 0)


def test_cell_axes_and_shapes():
    cell = battery_cell_tables()
    np.testing.assert_allclose(cell.soc, np.linspace(0.0, 1.0, 101), rtol=0, atol=1e-15)
    np.testing.assert_allclose(cell.temperature_K - 273.15, [-40, -30, -20, 0, 23, 45, 60], rtol=0, atol=1e-9)
    assert cell.ocv_V.shape == cell.r0_ohm.shape == (101, 7)


def test_cell_tables_physical():
    cell = battery_cell_tables()
    ocv, r0 = cell.ocv_V, cell.r0_ohm
    assert np.all(np.diff(ocv, axis=0) > 0)  # increasing with SOC at every temperature
    assert 2.5 < ocv.min() and ocv.max() < 4.5
    assert ocv.min() == 3.17242 and ocv.max() == 4.16831
    # The MW OCV has no temperature dependence (spec 2.2: dE = 0).
    np.testing.assert_array_equal(ocv, np.repeat(ocv[:, :1], 7, axis=1))
    assert np.all(r0 > 0)
    assert r0.max() == 0.35142 and r0.min() == 0.00014  # 60 degC, SOC 0.51
    # Data quirk kept (spec 2.2): R0 rises from 23 to 45 degC at SOC <= 0.29 and only there.
    rises = cell.soc[r0[:, 5] > r0[:, 4]]
    np.testing.assert_allclose(rises, np.arange(30) / 100, atol=1e-12)


def test_pack_capacity_from_ocv_integral():
    """Spec 3 / 10: 96 s x 32 p x 4.5 Ah, 50.8 kWh (full OCV integral at 25 degC)."""
    cell = battery_cell_tables()
    soc = cell.soc
    ocv25 = bilinear_clamped(cell.soc, cell.temperature_K, cell.ocv_V, soc, 298.15)
    trapezoid = float(np.sum(np.diff(soc) * (ocv25[1:] + ocv25[:-1]) / 2))
    energy_kwh = 96 * 32 * 4.5 * trapezoid / 1e3
    assert energy_kwh == pytest.approx(50.8, rel=0.01)
    assert energy_kwh == pytest.approx(50.83, abs=0.01)
    # Usable between soc_min 0.05 and soc_max 0.98 (spec 10: 47.5 kWh).
    use = (soc > 0.05 - 1e-9) & (soc < 0.98 + 1e-9)
    s, v = soc[use], ocv25[use]
    usable = 96 * 32 * 4.5 * float(np.sum(np.diff(s) * (v[1:] + v[:-1]) / 2)) / 1e3
    assert usable == pytest.approx(47.5, abs=0.05)


def test_pack_resistance_at_23C_soc_09():
    """Spec 9: pack R 0.0388 ohm at 23 degC, SOC 0.9 (R_cell Ns/Np)."""
    cell = battery_cell_tables()
    r = bilinear_clamped(cell.soc, cell.temperature_K, cell.r0_ohm, 0.9, 296.15)
    assert r * 96 / 32 == pytest.approx(0.03882, rel=1e-9)


def test_tables_read_only_and_cached():
    ed, cell = edrive_tables(), battery_cell_tables()
    assert edrive_tables() is ed and battery_cell_tables() is cell
    with pytest.raises(ValueError):
        cell.r0_ohm[0, 0] = 1.0
    with pytest.raises(AttributeError):
        ed.max_power_W = 1.0  # type: ignore[misc]


def test_data_files_name_their_source():
    for name in ("edrive.json", "battery_cell.json"):
        src = json.loads((DATA / name).read_text(encoding="utf-8"))["source"]
        assert src["repository"] == "simscape/Optimize-BEV-Thermal-Management-with-Simscape"
        assert len(src["commit"]) == 40
        assert src["file"] == "Scripts_Data/Data/BEV_Thermal_Management_param.m"
    assert "1.1" in (DATA / "SOURCE_MW.md").read_text(encoding="utf-8")
    assert "simscape/Optimize" in edrive_tables().source


# --- bilinear_clamped -------------------------------------------------------------------------

XA = np.array([0.0, 1.0, 3.0])
YA = np.array([10.0, 20.0])
TAB = np.array([[1.0, 2.0], [5.0, -1.0], [0.5, 7.0]])


def test_bilinear_exact_at_nodes():
    xx, yy = np.meshgrid(XA, YA, indexing="ij")
    np.testing.assert_array_equal(bilinear_clamped(XA, YA, TAB, xx, yy), TAB)
    ed = edrive_tables()
    n, t = np.meshgrid(ed.speed_rpm, ed.torque_Nm, indexing="ij")
    np.testing.assert_array_equal(bilinear_clamped(ed.speed_rpm, ed.torque_Nm, ed.loss_W, n, t), ed.loss_W)


def test_bilinear_linear_between_nodes():
    # Along x at a y node: linear.
    x = np.linspace(1.0, 3.0, 9)
    got = bilinear_clamped(XA, YA, TAB, x, 10.0)
    np.testing.assert_allclose(got, 5.0 + (x - 1.0) / 2.0 * (0.5 - 5.0), rtol=1e-14)
    # Along y at an x node: linear.
    y = np.linspace(10.0, 20.0, 11)
    np.testing.assert_allclose(bilinear_clamped(XA, YA, TAB, 1.0, y), 5.0 - 6.0 * (y - 10.0) / 10.0)
    # Cell centre: mean of the four corners.
    assert bilinear_clamped(XA, YA, TAB, 0.5, 15.0) == pytest.approx((1 + 2 + 5 - 1) / 4)
    # A bilinear function is reproduced exactly everywhere inside.
    f = lambda a, b: 2.0 + 3.0 * a - 0.5 * b + 0.25 * a * b  # noqa: E731
    xx, yy = np.meshgrid(XA, YA, indexing="ij")
    rng = np.random.default_rng(0)
    xq, yq = rng.uniform(0, 3, 50), rng.uniform(10, 20, 50)
    np.testing.assert_allclose(bilinear_clamped(XA, YA, f(xx, yy), xq, yq), f(xq, yq), rtol=1e-12)


def test_bilinear_clamped_outside():
    for xq, xc in ((-5.0, 0.0), (99.0, 3.0)):
        for yq, yc in ((-1e9, 10.0), (15.0, 15.0), (1e9, 20.0)):
            assert bilinear_clamped(XA, YA, TAB, xq, yq) == bilinear_clamped(XA, YA, TAB, xc, yc)
    ed = edrive_tables()
    # Below 10 N m and 500 rpm the corner cell holds; above 10000 rpm the last row.
    assert bilinear_clamped(ed.speed_rpm, ed.torque_Nm, ed.loss_W, 0.0, 0.0) == 49.74
    assert bilinear_clamped(ed.speed_rpm, ed.torque_Nm, ed.loss_W, 2e4, 10.0) == 974.03


def test_bilinear_shapes_scalars_and_nan():
    out = bilinear_clamped(XA, YA, TAB, np.zeros((4, 1)), np.full(3, 12.0))
    assert out.shape == (4, 3)
    scalar = bilinear_clamped(XA, YA, TAB, 2.0, 12.0)
    assert isinstance(scalar, np.float64)
    assert np.isnan(bilinear_clamped(XA, YA, TAB, np.nan, 12.0))


@pytest.mark.parametrize(
    ("xa", "ya", "tab"),
    [
        (np.array([0.0, 0.0, 1.0]), YA, TAB),  # not strictly increasing
        (np.array([1.0]), YA, TAB[:1]),  # one point
        (XA, YA, TAB.T),  # shape mismatch
    ],
)
def test_bilinear_rejects_bad_grids(xa, ya, tab):
    with pytest.raises(ValueError):
        bilinear_clamped(xa, ya, tab, 0.5, 15.0)
