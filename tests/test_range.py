"""Range tests (spec v2 section 7): the J1634 and GTR 15 sequences, their arithmetic, runs to break-off, the CLI.

The runs use the synthetic cycle maps of ``test_simulate.py`` (the CLI's map
loading is replaced by them), so every test here takes seconds.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_simulate import params, refrigerant  # noqa: F401 - the synthetic maps' fixture

from evtms.system import loop as L  # noqa: N812
from evtms.system.drive_cycles import DriveCycle
from evtms.system.simulate import simulate


def test_key_off_steps_draw_nothing_while_the_network_runs_on(refrigerant):  # noqa: F811
    t = np.array([0.0, 10.0, 300.0, 310.0, 910.0, 920.0, 1200.0, 1210.0])
    v = np.array([0.0, 15.0, 15.0, 0.0, 0.0, 15.0, 15.0, 0.0])
    off = np.array([False, False, False, True, False, False, False, False])
    cycle = DriveCycle("drive-soak-drive", t, v, np.zeros_like(t), "test", off)
    r = simulate(cycle, 313.15, refrigerant, dt=1.0, sun=600.0, T_init=313.15)
    rec = r.records
    soak = (rec["time"] > 310.0) & (rec["time"] <= 910.0)
    assert np.all(rec["P_battery"][soak] == 0.0) and np.all(rec["P_hvac"][soak] == 0.0)
    assert np.all(r.mode[soak] == L.OFF) and np.all(rec["blower"][soak] == 0.0)
    before = rec["time"] <= 310.0
    assert np.nanmax(rec["P_hvac"][before]) > 500.0  # the cabin was being cooled before the soak
    T_cab = rec["T_cabin"][soak]
    assert T_cab[-1] > T_cab[0] + 1.0  # the hot car warms up with the HVAC off
    assert max(r.ledgers.values()) <= 1e-9, r.ledgers
    aux = params().vehicle.aux_power
    assert r.summary["aux_energy_kWh"] == pytest.approx(aux * (1210.0 - 600.0) / 3.6e6, rel=1e-12)
