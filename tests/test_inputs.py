"""Hostile input: parameter files and axis specifications are refused with one line each.

Every table below is a list of ``(case id, input, expected message fragments)``; add a row to
cover a new case. Each refusal must be an ``EvtmsInputError`` whose message is one line and
holds every fragment.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import subprocess
import sys
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from evtms.benches import BENCHES
from evtms.benches.chiller import PlateHXParams
from evtms.benches.coil import CoilParams
from evtms.benches.compressor import CompressorParams
from evtms.benches.expansion_valve import ExpansionValveParams
from evtms.benches.grid import (
    DEFAULT_MAX_POINTS,
    build_grid,
    check_axis,
    check_grid_size,
    parse_axes,
    parse_axis,
    parse_value,
    round_sig,
)
from evtms.benches.parameters import Parameters, load_parameters, parameters_from_json
from evtms.cli import app
from evtms.errors import EvtmsInputError
from evtms.params import MAX_PARAMS_BYTES, Environment, Range


def refused(fn, *args, **kwargs) -> str:
    """The one-line message of the EvtmsInputError ``fn(*args)`` raises."""
    with pytest.raises(EvtmsInputError) as info:
        fn(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message and "\r" not in message, message
    assert message.strip() == message and message
    return message


def returns_within(seconds: float, fn, *args):
    """Run ``fn(*args)`` in a daemon thread; fail if it has not returned after ``seconds``.

    Returns the exception it raised (or None).
    """
    outcome: list[BaseException | None] = []

    def target():
        try:
            fn(*args)
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            outcome.append(exc)
        else:
            outcome.append(None)

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"{fn.__name__}{args} did not return within {seconds} s"
    return outcome[0]


# --------------------------------------------------------------------------------------------
# Parameter files: (case id, file content as str or bytes, fragments of the message)
# --------------------------------------------------------------------------------------------

C = "[condenser]\n"
PARAMS_FILES = [
    # non-finite numbers
    ("nan", C + "core_length = nan\n", ["[condenser] core_length = nan is not allowed", "0 < core_length <= 10 m"]),
    ("inf", C + "fin_efficiency = inf\n", ["fin_efficiency = inf is not allowed", "0 < fin_efficiency <= 1"]),
    ("-inf", "[compressor]\ndisplacement = -inf\n", ["[compressor] displacement = -inf", "0 < displacement"]),
    ("overflow", C + "core_height = 1e999\n", ["core_height = inf is not allowed", "core_height <= 10 m"]),
    ("nan in env", "[environment]\nT = nan\n", ["[environment] T = nan", "200 <= T <= 400 K"]),
    # geometry: negative, zero, too large
    (
        "negative count",
        C + "n_tubes = -3\n",
        ["[condenser] n_tubes = -3 is not allowed; allowed: 1 <= n_tubes <= 1000 (whole number)"],
    ),
    ("zero count", "[evaporator]\nn_channels = 0\n", ["[evaporator] n_channels = 0", "1 <= n_channels <= 1000"]),
    ("fractional count", C + "n_tubes = 2.5\n", ["n_tubes = 2.5 is not allowed", "(whole number)"]),
    ("huge count", C + "n_tubes = 100000000000000000\n", ["n_tubes = 100000000000000000", "n_tubes <= 1000"]),
    ("negative length", C + "core_height = -0.39\n", ["core_height = -0.39 is not allowed", "0 < core_height"]),
    ("zero length", C + "tube_depth = 0\n", ["tube_depth = 0 is not allowed", "0 < tube_depth <= 1 m"]),
    ("zero area", C + "area_ref = 0.0\n", ["area_ref = 0.0 is not allowed", "0 < area_ref <= 1000 m2"]),
    ("huge area", C + "area_air_fin = 5000\n", ["area_air_fin = 5000", "0 < area_air_fin <= 1000 m2"]),
    ("zero fan flow", C + "fan_flow_max = 0\n", ["fan_flow_max = 0", "0 < fan_flow_max <= 100 m3/s"]),
    ("port too wide", "[expansion_valve]\nport_diameter = 0.5\n", ["port_diameter = 0.5", "<= 0.1 m"]),
    ("negative roughness", C + "roughness = -1e-6\n", ["roughness = -1e-06", "0 <= roughness <= 0.001 m"]),
    # fractions and efficiencies
    ("efficiency above 1", C + "fin_efficiency = 1.2\n", ["fin_efficiency = 1.2", "0 < fin_efficiency <= 1"]),
    ("zero efficiency", "[compressor]\neta_isentropic = 0\n", ["eta_isentropic = 0", "0 < eta_isentropic <= 1"]),
    ("eta_mechanical", "[compressor]\neta_mechanical = 1.01\n", ["eta_mechanical = 1.01", "eta_mechanical <= 1"]),
    ("RH above 1", "[environment]\nRH = 1.5\n", ["[environment] RH = 1.5", "0 <= RH <= 1"]),
    ("RH negative", "[environment]\nRH = -0.1\n", ["RH = -0.1", "0 <= RH <= 1"]),
    ("fouling at bound", C + "fouling_air = 0.01\n", ["fouling_air = 0.01", "0 <= fouling_air < 0.01 m2 K/W"]),
    ("fouling negative", "[evaporator]\nfouling_ref = -1e-4\n", ["fouling_ref = -0.0001", "0 <= fouling_ref"]),
    # environment ranges
    ("air in Celsius", "[environment]\nT = 35\n", ["[environment] T = 35 is not allowed", "200 <= T <= 400 K"]),
    ("air pressure in bar", "[environment]\np = 1.013\n", ["p = 1.013", "50000 <= p <= 200000 Pa"]),
    ("pressure ratio", "[compressor]\npr_nominal = 1\n", ["pr_nominal = 1", "1 < pr_nominal <= 50"]),
    # wrong types
    ("string", C + "n_tubes = 'many'\n", ['[condenser] n_tubes = "many" is not a number', "1 <= n_tubes <= 1000"]),
    ("numeric string", C + "fin_efficiency = '0.7'\n", ['fin_efficiency = "0.7" is not a number']),
    ("boolean", C + "fin_efficiency = true\n", ["fin_efficiency = true is not a number"]),
    ("boolean count", C + "n_tubes = false\n", ["n_tubes = false is not a number"]),
    ("date", C + "core_length = 1979-05-27\n", ['core_length = "1979-05-27" is not a number']),
    ("list for a number", C + "n_tubes = [40]\n", ["n_tubes = [40] is not a number"]),
    ("nested table", "[condenser.n_tubes]\nvalue = 3\n", ["[condenser] n_tubes is a table, not a value"]),
    ("inline table", C + "fin_spacing = { value = 5e-4 }\n", ["fin_spacing is a table, not a value"]),
    ("list for a number", C + "n_tubes = [40, 44]\n", ["n_tubes = [40, 44]"]),
    ("nan in a list for a number", C + "core_length = [1.2, nan]\n", ["core_length = [1.2, nan]"]),
    # relations between parameters
    (
        "capacity_max below nominal",
        "[expansion_valve]\ncapacity_max = 1000\n",
        [
            "[expansion_valve] capacity_max = 1000 is not allowed with capacity_nominal = 4500",
            "allowed: capacity_max >= capacity_nominal",
        ],
    ),
    (
        "nominal above max",
        "[expansion_valve]\ncapacity_nominal = 8000\n",
        ["capacity_nominal = 8000 is not allowed with capacity_max = 7000"],
    ),
    (
        "condensing below evaporating",
        "[expansion_valve]\nT_cond_nominal = 270\n",
        [
            "T_cond_nominal = 270 is not allowed with T_evap_nominal = 274.15",
            "allowed: T_cond_nominal > T_evap_nominal",
        ],
    ),
    (
        "static superheat above nominal",
        "[expansion_valve]\nsuperheat_static = 12\n",
        ["superheat_static = 12 is not allowed", "superheat_nominal > superheat_static"],
    ),
    (
        "wall thicker than tube",
        C + "wall_thickness = 0.001\n",
        ["wall_thickness = 0.001", "wall_thickness < tube_thickness / 2"],
    ),
    (
        "free area above frontal",
        C + "area_air_free = 0.6\n",
        ["area_air_free = 0.6", "area_air_free <= core_length * core_height"],
    ),
    ("tubes do not fit", "[evaporator]\nn_tubes = 200\n", ["n_tubes = 200", "n_tubes < core_height / tube_thickness"]),
    # fluid and backend
    ("backend", 'backend = "TTSE&HEOS"\n', ['backend = "TTSE&HEOS" is not allowed; allowed: HEOS, BICUBIC&HEOS']),
    ("backend number", "backend = 3\n", ["backend = 3 is not allowed"]),
    ("fluid number", "fluid = 134\n", ["fluid = 134 is not allowed", "a CoolProp fluid name"]),
    ("fluid empty", 'fluid = ""\n', ['fluid = "" is not allowed']),
    ("fluid newline", 'fluid = "R134a\\nR32"\n', ['fluid = "R134a\\nR32" is not allowed']),
    ("fluid table", '[fluid]\nname = "R134a"\n', ["fluid = {...} is not allowed"]),
    # structure
    ("value for a table", "condenser = 3\n", ["condenser = 3 is not a table", "a [condenser] table"]),
    ("unknown table", "[heater]\npower = 3\n", ["unknown table or key 'heater'", "[condenser]"]),
    ("top-level parameter", "n_tubes = 44\n", ["unknown table or key 'n_tubes'"]),
    ("unknown parameter", C + "n_tube = 3\n", ["[condenser] unknown parameter 'n_tube'", "n_tubes"]),
    ("newline in key", C + '"n\\ntubes" = 3\n', ["unknown parameter 'n\\ntubes'"]),
    ("invalid TOML", "[condenser\nn_tubes = 3\n", ["is not valid TOML"]),
    ("duplicate key", C + "n_tubes = 3\nn_tubes = 4\n", ["is not valid TOML"]),
    # bytes
    ("empty", b"", ["is empty; give at least one [table]"]),
    ("whitespace only", b"  \n\n\t\n", ["is empty; give at least one [table]"]),
    ("comments only", "# nothing here\n", ["is empty; give at least one [table]"]),
    ("empty table is fine but nothing else", "[condenser]\n", None),
    ("not UTF-8", b"[condenser]\nn_tubes = 4\xff\n", ["is not UTF-8 text (byte 0xff at offset 23)"]),
    ("Latin-1 comment", b"# caf\xe9\n[condenser]\n", ["is not UTF-8 text (byte 0xe9 at offset 5)"]),
    ("binary", b"\x7fELF\x02\x01\x01\x00\x00\x00\x00", ["is a binary file"]),
    ("UTF-16", "[condenser]\nn_tubes = 44\n".encode("utf-16"), ["is a binary file"]),
    ("too large", b"#" * (MAX_PARAMS_BYTES + 1), [f"{MAX_PARAMS_BYTES + 1:,} bytes", "at most 1,048,576 bytes"]),
]


@pytest.mark.parametrize(("content", "fragments"), [c[1:] for c in PARAMS_FILES], ids=[c[0] for c in PARAMS_FILES])
def test_hostile_params_file_is_refused_in_one_line(tmp_path, content, fragments):
    path = tmp_path / "p.toml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    if fragments is None:  # a row that must be accepted
        assert load_parameters(path) == Parameters()
        return
    message = refused(load_parameters, path)
    assert message.startswith(f"params file {str(path)!r}"), message
    for fragment in fragments:
        assert fragment in message, message


def test_params_message_names_file_table_key_value_and_range(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("[condenser]\nn_tubes = -3\n")
    assert refused(load_parameters, path) == (
        f"params file {str(path)!r}: [condenser] n_tubes = -3 is not allowed; "
        "allowed: 1 <= n_tubes <= 1000 (whole number)"
    )


# (case id, how to make the path in tmp_path, fragments)
def _missing(tmp: Path) -> Path:
    return tmp / "none.toml"


def _folder(tmp: Path) -> Path:
    (tmp / "d.toml").mkdir()
    return tmp / "d.toml"


def _fifo(tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo.toml")
    return tmp / "fifo.toml"


def _link_to_fifo(tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo")
    (tmp / "link.toml").symlink_to(tmp / "fifo")
    return tmp / "link.toml"


def _dev_zero(tmp: Path) -> Path:
    return Path("/dev/zero")


def _sparse_huge(tmp: Path) -> Path:
    path = tmp / "huge.toml"
    with open(path, "wb") as fh:
        fh.truncate(10 * 2**30)  # 10 GiB, sparse: must not be read
    return path


PARAMS_PATHS = [
    ("missing", _missing, ["cannot be read", "No such file"]),
    ("folder", _folder, ["is a folder; allowed: a TOML text file"]),
    ("fifo", _fifo, ["is a named pipe (FIFO)"]),
    ("symlink to fifo", _link_to_fifo, ["is a named pipe (FIFO)"]),
    ("device", _dev_zero, ["'/dev/zero' is a character device"]),
    ("10 GiB", _sparse_huge, ["has 10,737,418,240 bytes", "at most 1,048,576 bytes (1 MiB)"]),
]


@pytest.mark.parametrize(("make", "fragments"), [c[1:] for c in PARAMS_PATHS], ids=[c[0] for c in PARAMS_PATHS])
def test_params_path_that_is_not_a_small_regular_file_is_refused_without_reading(tmp_path, make, fragments):
    if not hasattr(os, "mkfifo") and make in (_fifo, _link_to_fifo):
        pytest.skip("no named pipes on this system")
    if make is _dev_zero and not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    path = make(tmp_path)
    try:
        exc = returns_within(5.0, load_parameters, path)
    finally:
        if path.exists() and stat.S_ISFIFO(path.stat().st_mode):  # release a reader blocked on the pipe
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass
    assert isinstance(exc, EvtmsInputError), exc
    message = str(exc)
    assert "\n" not in message and message.startswith(f"params file {str(path)!r}")
    for fragment in fragments:
        assert fragment in message, message


def test_good_params_file_is_read(tmp_path):
    path = tmp_path / "p.toml"
    path.write_bytes(
        "\ufeff# a BOM and a non-ASCII comment: °C\n"
        'fluid = "R134a"\nbackend = "BICUBIC&HEOS"\n'
        "[condenser]\nn_tubes = 44.0\nlouver_angle = 0.5\n"
        "[environment]\nT = 308.15\nRH = 0\n".encode()
    )
    p = load_parameters(path)
    assert p.condenser.n_tubes == 44 and isinstance(p.condenser.n_tubes, int)
    assert p.condenser.louver_angle == 0.5
    assert p.environment.T == 308.15 and p.environment.RH == 0.0 and p.backend == "BICUBIC&HEOS"
    p.validate()


@pytest.mark.parametrize("cls", [Environment, CoilParams, CompressorParams, ExpansionValveParams, PlateHXParams])
def test_every_parameter_declares_a_range_its_default_keeps(cls):
    for f in dataclasses.fields(cls):
        rng = f.metadata.get("range")
        assert isinstance(rng, Range), f"{cls.__name__}.{f.name} has no range"
        assert f.metadata["units"] == rng.units
        default = f.default if f.default is not dataclasses.MISSING else None
        values = default if isinstance(default, tuple) else (default,)
        assert all(rng.contains(v) for v in values), f"{cls.__name__}.{f.name} = {default} is outside its range"
    Parameters().validate()


def test_validate_catches_values_set_in_code():
    bad = dataclasses.replace(Parameters(), condenser=CoilParams(fin_efficiency=1.5))
    assert refused(bad.validate) == "[condenser] fin_efficiency = 1.5 is not allowed; allowed: 0 < fin_efficiency <= 1"
    assert "backend" in refused(dataclasses.replace(Parameters(), backend="heos").validate)


def test_differences_lists_dotted_keys():
    a = Parameters()
    assert a.differences(Parameters()) == []
    b = dataclasses.replace(
        a,
        fluid="R1234yf",
        condenser=dataclasses.replace(a.condenser, n_tubes=44),
        environment=dataclasses.replace(a.environment, T=308.15),
    )
    assert a.differences(b) == ["condenser.n_tubes", "environment.T", "fluid"]
    assert b.differences(a) == a.differences(b)
    assert a.differences(b, sections=("condenser",)) == ["condenser.n_tubes"]
    assert a.differences(b, sections=("evaporator", "backend")) == []


def test_parameters_from_a_luts_json_round_trip_and_contradictions(tmp_path):
    default = Parameters()
    for component in ("condenser", "evaporator", "compressor", "expansion_valve"):
        text = default.component_json(component)
        assert parameters_from_json(component, text, default.environment_json()) == default
        assert default.differences_from_lut(component, text) == []
    mine = tmp_path / "mine.toml"
    mine.write_text("[condenser]\nn_tubes = 44\n[evaporator]\nn_tubes = 22\n")
    user = load_parameters(mine)
    lut = default.component_json("condenser")
    assert user.differences_from_lut("condenser", lut) == ["condenser.n_tubes"]
    assert user.differences_from_lut("compressor", default.component_json("compressor")) == []
    assert parameters_from_json("condenser", user.component_json("condenser")).condenser.n_tubes == 44
    other_fluid = json.dumps({**json.loads(lut), "fluid": "R1234yf"})
    assert default.differences_from_lut("condenser", other_fluid) == ["fluid"]


PARAMETERS_JSON = [
    ("not JSON", "condenser", "{", ["LUT attribute 'parameters' is not JSON"]),
    ("not an object", "condenser", "[1, 2]", ["is not a JSON object"]),
    ("unknown parameter", "condenser", '{"condenser": {"n_tube": 3}}', ["unknown parameter 'n_tube'"]),
    ("other component", "condenser", '{"compressor": {}}', ["unknown table or key 'compressor'"]),
    ("NaN", "condenser", '{"condenser": {"fin_efficiency": NaN}}', ["fin_efficiency = nan is not allowed"]),
    ("unknown component", "heater", "{}", ["unknown component 'heater'"]),
]


@pytest.mark.parametrize(
    ("component", "text", "fragments"), [c[1:] for c in PARAMETERS_JSON], ids=[c[0] for c in PARAMETERS_JSON]
)
def test_bad_lut_parameters_json_is_refused(component, text, fragments):
    message = refused(parameters_from_json, component, text)
    for fragment in fragments:
        assert fragment in message, message


# --------------------------------------------------------------------------------------------
# Axes: (case id, bench, --axis text, fragments of the message)
# --------------------------------------------------------------------------------------------

AXIS_CASES = [
    # malformed numbers
    ("nan", "condenser", "mdot=nan", ["axis mdot: 'nan' is not a finite number"]),
    ("NaN in list", "condenser", "fan=0.1,NaN", ["axis fan: 'NaN' is not a finite number"]),
    ("inf", "condenser", "mdot=0.001:inf:3", ["axis mdot: 'inf' is not a finite number"]),
    ("-inf", "condenser", "T_res=-inf,300", ["'-inf' is not a finite number"]),
    ("overflow", "condenser", "mdot=1e999", ["axis mdot: '1e999' is too large to be a number"]),
    ("empty item", "condenser", "mdot=1,,2", ["axis mdot: empty value in '1,,2'"]),
    ("trailing comma", "condenser", "fan=0.1,", ["axis fan: empty value in '0.1,'"]),
    ("empty start", "condenser", "fan=:1:3", ["axis fan: empty value in ':1:3'"]),
    ("fractional count", "condenser", "mdot=1:2:2.5g/s", ["axis mdot: count '2.5' must be a whole number >= 1"]),
    ("zero count", "condenser", "mdot=1:2:0", ["count '0' must be a whole number >= 1"]),
    ("negative count", "condenser", "mdot=1:2:-3", ["count '-3' must be a whole number >= 1"]),
    ("infinite count", "condenser", "mdot=1:2:1e999", ["count '1e999' must be a whole number >= 1"]),
    ("nan count", "condenser", "mdot=1:2:nan", ["count 'nan' must be a whole number >= 1"]),
    ("two parts", "condenser", "fan=0.1:1", ["axis fan: '0.1:1' must be start:stop:count"]),
    ("mixed separators", "condenser", "fan=0.1:1,3", ["mixes ':' and ','"]),
    ("word", "condenser", "fan=abc", ["axis fan: 'abc' is not a number", "start:stop:count"]),
    ("unit inside", "condenser", "mdot=4g/s,5", ["'4g/s' in '4g/s,5' is not a number"]),
    ("unknown unit", "condenser", "p_in=1:2:3psi", ["unit 'psi' is not allowed; allowed: Pa, kPa, MPa, bar"]),
    ("no form", "condenser", "mdot", ["is not of the form name=start:stop:count"]),
    ("unknown axis", "condenser", "mdto=0.005", ["unknown axis 'mdto' for condenser"]),
    # order and range (the existing wording)
    ("decreasing", "condenser", "fan=0.5,0.1", ["axis fan: values must be strictly increasing, got 0.5, 0.1"]),
    ("constant linspace", "condenser", "fan=0.5:0.5:3", ["strictly increasing, got 0.5, 0.5, 0.5"]),
    ("equal after rounding", "condenser", "fan=0.3,0.30000000000000004", ["strictly increasing, got 0.3, 0.3"]),
    ("long list shortened", "condenser", "fan=0.5:0.1:1000", ["... (1000 values)"]),
    ("zero mdot", "condenser", "mdot=0,0.005", ["axis mdot: value 0 is not allowed; allowed: mdot > 0 kg s-1"]),
    ("below closed bound", "condenser", "T_air_in=-40.01degC", ["value 233.14 is not allowed", "233.15 <= T_air_in"]),
    # likely another unit
    (
        "pressure of 1 Pa",
        "condenser",
        "p_in=1",
        ["axis p_in: value 1 Pa is below R134a's triple-point pressure 389.6 Pa; did you mean 1MPa?"],
    ),
    ("pressure in bar", "condenser", "p_in=9,12", ["value 9 Pa is below", "did you mean 9bar?"]),
    ("pressure in kPa", "evaporator", "p_in=300", ["value 300 Pa is below", "did you mean 300kPa?"]),
    ("pressure below 1 kPa", "evaporator", "p_in=500,600", ["value 500 Pa is below 1 kPa", "did you mean 500kPa?"]),
    ("pressure in Pa unit", "condenser", "p_in=0.9:1.2:4Pa", ["value 0.9 Pa is below", "did you mean 0.9MPa?"]),
    ("temperature in K", "condenser", "T_in=70", ["axis T_in: value 70 K is below 150 K", "did you mean 70degC?"]),
    ("reservoir in K", "condenser", "T_res=25,30", ["axis T_res: value 25 K", "did you mean 25degC?"]),
    (
        "negative kelvin",
        "condenser",
        "T_res=-10",
        ["value -10 is not allowed; allowed: T_res > 0 K", "did you mean -10degC?"],
    ),
    ("air in K", "evaporator", "T_air_in=25", ["allowed: 233.15 <= T_air_in <= 353.15 K; did you mean 25degC?"]),
    ("compressor T_in", "compressor", "T_in=100", ["axis T_in: value 100 K", "did you mean 100degC?"]),
    ("mass flow in kg/s", "condenser", "mdot=5", ["axis mdot: value 5 kg/s is above 1 kg/s", "did you mean 5g/s?"]),
    ("mass flow list", "expansion_valve", "mdot=4,6,8", ["value 8 kg/s is above 1 kg/s", "did you mean 8g/s?"]),
    ("fan in percent", "condenser", "fan=50", ["allowed: 0 < fan <= 1; did you mean 50%?"]),
    ("blower in percent", "evaporator", "blower=20:80:4", ["value 20 is not allowed", "did you mean 20%?"]),
    ("RH in percent", "evaporator", "RH_air_in=40", ["0 <= RH_air_in <= 1; did you mean 40%?"]),
    ("speed in percent", "compressor", "speed=30,60", ["0 < speed <= 1; did you mean 30%?"]),
    # sizes
    (
        "billion values",
        "condenser",
        "mdot=1:2:1000000000",
        ["grid of 1,000,000,000 points (mdot 1000000000) is above the limit of 200,000,000 points", "`max_points`"],
    ),
    ("count in e-notation", "condenser", "fan=0.1:1:1e12", ["grid of 1,000,000,000,000 points (fan 1000000000000)"]),
]


@pytest.mark.parametrize(("bench", "spec", "fragments"), [c[1:] for c in AXIS_CASES], ids=[c[0] for c in AXIS_CASES])
def test_bad_axis_is_refused_in_one_line(bench, spec, fragments):
    message = refused(parse_axis, spec, BENCHES[bench])
    for fragment in fragments:
        assert fragment in message, message


# (case id, bench, --axis texts, fragments)
AXES_CASES = [
    ("same axis twice", "condenser", ["mdot=4:8:3g/s", "fan=0.5", "mdot=5g/s"], ["axis mdot is given twice"]),
    ("same values twice", "condenser", ["fan=0.5", "fan=0.5"], ["'fan=0.5' and 'fan=0.5'", "give each axis once"]),
    ("T_in and h_in", "condenser", ["T_in=340", "h_in=420kJ/kg"], ["axes T_in and h_in both set", "give one of"]),
    ("h_in and T_in", "compressor", ["h_in=400kJ/kg", "T_in=270"], ["axes h_in and T_in both set"]),
    (
        "product too large",
        "condenser",
        ["mdot=1:8:100000g/s", "fan=0.01:1:100000"],
        ["grid of 10,000,000,000 points (mdot 100000 x fan 100000)"],
    ),
]


@pytest.mark.parametrize(("bench", "specs", "fragments"), [c[1:] for c in AXES_CASES], ids=[c[0] for c in AXES_CASES])
def test_conflicting_axes_are_refused(bench, specs, fragments):
    message = refused(parse_axes, specs, BENCHES[bench])
    for fragment in fragments:
        assert fragment in message, message


# (case id, bench, --axis text, expected SI values, compared exactly)
EXACT_VALUES = [
    ("-40 degC is 233.15 K", "condenser", "T_air_in=-40degC", [233.15]),
    ("80 degC is 353.15 K", "condenser", "T_air_in=-40:80:3degC", [233.15, 293.15, 353.15]),
    ("linspace to 0.3", "condenser", "fan=0.1:1:10", [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]),
    ("percent", "condenser", "fan=7,10,100%", [0.07, 0.1, 1.0]),
    ("RH bounds", "evaporator", "RH_air_in=0:100:3%", [0.0, 0.5, 1.0]),
    ("g/s", "condenser", "mdot=4:8:3g/s", [0.004, 0.006, 0.008]),
    ("MPa", "condenser", "p_in=0.9:1.2:4MPa", [900000.0, 1000000.0, 1100000.0, 1200000.0]),
    ("bar", "condenser", "p_in=9, 12 bar", [900000.0, 1200000.0]),
    ("kJ/kg", "condenser", "h_in=400.1kJ/kg", [400100.0]),
    ("spaces", "condenser", " mdot = 0.004 : 0.008 : 2 ", [0.004, 0.008]),
    ("exponent", "condenser", "p_in=9e5,1.2E6", [900000.0, 1200000.0]),
]


@pytest.mark.parametrize(("bench", "spec", "expected"), [c[1:] for c in EXACT_VALUES], ids=[c[0] for c in EXACT_VALUES])
def test_axis_values_are_exact_decimals(bench, spec, expected):
    _, values = parse_axis(spec, BENCHES[bench])
    assert values.tolist() == expected  # exact, not approx


ROUNDING = [
    (233.14999999999998, 233.15),
    (0.30000000000000004, 0.3),
    (-40.000000000000004, -40.0),
    (1.0000000000001, 1.0),
    (1.00000000001, 1.00000000001),
    (123456789012345.6, 123456789012000.0),
    (7e-20 * 1.0000000000000002, 7e-20),
    (0.0, 0.0),
]


@pytest.mark.parametrize(("value", "expected"), ROUNDING)
def test_round_sig(value, expected):
    assert round_sig(value).tolist() == [expected]
    assert math.isnan(round_sig([math.nan])[0]) and round_sig([math.inf])[0] == math.inf


def test_huge_count_is_refused_before_allocating():
    tracemalloc.start()
    try:
        message = refused(parse_axis, "mdot=1:2:1000000000", BENCHES["condenser"])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert "1,000,000,000 points" in message
    assert peak < 10e6  # the count is refused from the axis text: nothing of its size was allocated


def test_max_points_is_the_callers():
    bench = BENCHES["condenser"]
    assert parse_axis("fan=0.1:1:10", bench, max_points=10)[1].size == 10
    assert "limit of 9 points" in refused(parse_axis, "fan=0.1:1:10", bench, max_points=9)
    assert "limit of 9 points" in refused(parse_axis, "fan=0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1", bench, max_points=9)
    assert "limit of 767 points" in refused(build_grid, bench, "thesis", {}, max_points=767)
    assert sum(1 for _ in build_grid(bench, "thesis", {}, max_points=768)) == 5


CHECK_GRID_SIZE = [
    (
        "points",
        {"mdot": 1_000_000_000, "fan": 4},
        {},
        "grid of 4,000,000,000 points (mdot 1000000000 x fan 4) is above the limit of 200,000,000 points; "
        "raise it with `max_points` or use a coarser grid",
    ),
    ("raised limit", {"mdot": 10, "fan": 10}, {"max_points": 99}, "grid of 100 points (mdot 10 x fan 10)"),
    (
        "memory",
        {"mdot": 1000, "fan": 1000},
        {"bytes_per_point": 100, "available_bytes": 100_000_000},
        "grid of 1,000,000 points (mdot 1000 x fan 1000) needs about 0.1 GB of memory, above 80% of the 0.1 GB",
    ),
    ("shape without names", (10, 10), {"max_points": 50}, "grid of 100 points (axis 0 10 x axis 1 10)"),
]


@pytest.mark.parametrize(
    ("shape", "kwargs", "fragment"), [c[1:] for c in CHECK_GRID_SIZE], ids=[c[0] for c in CHECK_GRID_SIZE]
)
def test_check_grid_size(shape, kwargs, fragment):
    assert fragment in refused(check_grid_size, shape, **kwargs)


def test_check_grid_size_accepts_and_counts():
    assert DEFAULT_MAX_POINTS == 200_000_000
    assert check_grid_size({"mdot": 4, "fan": 4}) == 16
    assert check_grid_size((10, 10), max_points=100, bytes_per_point=8, available_bytes=1001) == 100
    assert check_grid_size((10, 10), available_bytes=None) == 100  # reads MemAvailable or skips


def test_build_grid_refuses_T_in_with_h_in():
    bench = BENCHES["condenser"]
    message = refused(build_grid, bench, "thesis", {"T_in": np.array([340.0]), "h_in": np.array([420e3])})
    assert "T_in and h_in" in message
    grid = build_grid(bench, "thesis", {"h_in": np.array([420e3])})
    assert list(grid) == ["mdot", "fan", "p_in", "h_in", "T_res"]


def test_check_axis_with_a_fluid():
    class Fake:
        name, p_triple, p_crit, T_triple, T_max = "CO2", 517950.0, 7.3773e6, 216.59, 2000.0

    message = refused(check_axis, "p_in", np.array([300e3, 400e3]), Fake())
    assert message == "axis p_in: value 300000 Pa is below CO2's triple-point pressure 518000 Pa"
    check_axis("p_in", np.array([600e3, 7e6]), Fake())
    assert "critical pressure of CO2" in refused(check_axis, "p_in", np.array([8e6]), Fake())


PARSE_VALUE = [
    ("nan", "mdot", "nan", "mdot: 'nan' is not a finite number"),
    ("inf", "fan", "inf%", "fan: 'inf%' is not a finite number"),
    ("overflow", "p_in", "1e999", "p_in: '1e999' is not a finite number"),
    ("empty", "p_in", " ", "p_in: ' ' is not a finite number"),
    ("list", "p_in", "1,2", "is not a finite number"),
    ("unit", "p_in", "3psi", "p_in: unit 'psi' is not allowed"),
]


@pytest.mark.parametrize(("name", "text", "fragment"), [c[1:] for c in PARSE_VALUE], ids=[c[0] for c in PARSE_VALUE])
def test_parse_value_refuses(name, text, fragment):
    assert fragment in refused(parse_value, name, text)


def test_parse_value_is_exact():
    assert parse_value("T_air_in", "-40degC") == 233.15
    assert parse_value("fan", "7%") == 0.07
    assert parse_value("p_in", "1.2MPa") == 1.2e6


# --------------------------------------------------------------------------------------------
# Through the command line: exit code 2, one line starting with "error: ", no output file.
# --------------------------------------------------------------------------------------------

CLI_CASES = [
    ("huge axis", ["-a", "mdot=1:2:1000000000"], "1,000,000,000 points"),
    ("nan axis", ["-a", "fan=nan"], "'nan' is not a finite number"),
    ("Celsius without unit", ["-a", "T_in=70"], "did you mean 70degC?"),
    ("percent without unit", ["-a", "fan=10,50"], "did you mean 10%?"),
    ("T_in and h_in", ["-a", "T_in=340", "-a", "h_in=420kJ/kg"], "T_in and h_in"),
    ("empty params", ["--params", "{empty}"], "is empty; give at least one [table]"),
    ("params out of range", ["--params", "{negative}"], "[condenser] n_tubes = -3 is not allowed"),
    ("params folder", ["--params", "{folder}"], "is a folder"),
]


@pytest.mark.parametrize(("args", "fragment"), [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_cli_refuses_in_one_line(tmp_path, args, fragment):
    inputs = tmp_path / "inputs"
    inputs.mkdir()
    (inputs / "empty.toml").write_text("")
    (inputs / "negative.toml").write_text("[condenser]\nn_tubes = -3\n")
    (inputs / "folder").mkdir()
    paths = {"empty": inputs / "empty.toml", "negative": inputs / "negative.toml", "folder": inputs / "folder"}
    args = [a.format(**paths) for a in args]
    out = tmp_path / "c.nc"
    t0 = time.perf_counter()
    res = CliRunner().invoke(app, ["bench", "condenser", *args, "-o", str(out)])
    assert time.perf_counter() - t0 < 10
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0], res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["inputs"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes")
def test_cli_with_a_fifo_as_params_file_returns(tmp_path):
    fifo = tmp_path / "p.toml"
    os.mkfifo(fifo)
    out = tmp_path / "c.nc"
    code = "import sys; from evtms.cli import main; sys.argv[0] = 'evtms'; main()"
    args = ["bench", "condenser", "--params", str(fifo), "-o", str(out)]
    res = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "pipe" in lines[0], res.stderr
    assert str(fifo) in lines[0]
    assert not out.exists()
