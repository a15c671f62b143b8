"""Drive cycles: the built-in traces against their published figures, and hostile CSV files."""

from __future__ import annotations

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.system.drive_cycles import BUILTIN, DATA, drive_cycle, read_drive_cycle


@pytest.mark.parametrize(
    ("name", "samples", "km", "top_kmh"),
    [
        # Distances as the source note computes them (trapezoid; WLTC 3b equals the wltp
        # package's cumulative speed sum / 3600 exactly); EPA quotes 7.45 mi and 10.26 mi.
        ("wltc3b", 1801, 23.2663, 131.3),
        ("nedc", 1180, 11.0132, 120.0),
        ("udds", 1370, 11.9904, 91.2513),
        ("hwfet", 766, 16.5068, 96.4),
    ],
)
def test_builtin_cycles_match_their_published_figures(name, samples, km, top_kmh):
    c = drive_cycle(name)
    assert len(c.time) == samples and c.time[0] == 0 and np.all(np.diff(c.time) == 1.0)
    assert c.distance / 1000 == pytest.approx(km, abs=5e-5)
    assert c.speed.max() * 3.6 == pytest.approx(top_kmh, abs=0.05)  # the note rounds to 0.05 km/h
    assert c.speed[0] == 0 and c.speed[-1] == 0 and (c.grade == 0).all()


def test_every_builtin_file_ships_with_its_source_note():
    assert sorted(p.name for p in DATA.glob("*.csv")) == sorted(BUILTIN.values())
    note = (DATA / "SOURCE.md").read_text(encoding="utf-8")
    for file in BUILTIN.values():
        assert f"`{file}`" in note


def test_a_user_trace_with_grade_and_comments(tmp_path):
    f = tmp_path / "hill.csv"
    f.write_text("# a ramp up a 5 % hill\ntime_s,speed_kmh,grade\n0,0,0.05\n10,36,0.05\n# end\n20,36,0.05\n")
    c = read_drive_cycle(f)
    assert c.name == "hill" and np.allclose(c.speed, [0.0, 10.0, 10.0]) and (c.grade == 0.05).all()
    assert c.distance == pytest.approx(0.5 * 10 * 10 + 10 * 10)  # linear between samples


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty; a drive cycle has a header"),
        ("t,v\n0,0\n1,1\n", "header 't,v'; expected time_s,speed_kmh"),
        ("time_s,speed_kmh\n0,0\n", "1 sample(s); a drive cycle needs at least 2"),
        ("time_s,speed_kmh\n1,0\n2,3\n", "the first time is 1 s; a drive cycle starts at 0"),
        ("time_s,speed_kmh\n0,0\n2,3\n2,4\n", "time 2 s does not increase (previous 2 s)"),
        ("time_s,speed_kmh\n0,0\n1,-3\n", "speed -3 km/h is not allowed; allowed: 0 to 400 km/h"),
        ("time_s,speed_kmh\n0,0\n1,nan\n", "holds a value that is not finite"),
        ("time_s,speed_kmh\n0,0\n1,fast\n", "'1,fast' is not 2 numbers"),
        ("time_s,speed_kmh\n0,0\n1,2,3\n", "3 values in '1,2,3'; expected 2"),
        ("time_s,speed_kmh,grade\n0,0,0\n1,2,0.9\n", "grade 0.9 is not allowed; allowed: -0.35 to 0.35"),
    ],
)
def test_hostile_traces_are_refused_in_one_line(tmp_path, text, message):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(EvtmsInputError) as err:
        read_drive_cycle(f)
    assert message in str(err.value) and "\n" not in str(err.value)
    assert str(f) in str(err.value)


def test_binary_missing_and_unknown_inputs(tmp_path):
    f = tmp_path / "bin.csv"
    f.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(EvtmsInputError, match="not UTF-8 text"):
        read_drive_cycle(f)
    with pytest.raises(EvtmsInputError, match="cannot read the drive cycle"):
        read_drive_cycle(tmp_path / "missing.csv")
    with pytest.raises(EvtmsInputError, match="not a regular file"):
        read_drive_cycle(tmp_path)
    with pytest.raises(EvtmsInputError, match="neither a built-in cycle"):
        drive_cycle("wltc")
