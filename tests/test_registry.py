"""The registry is the one list of components: each registered bench brings its parameter table.

A component is its module plus one line in :data:`evtms.benches.MODULES`; its
bench declares its parameter table's default (``Bench.parameters``) and
:class:`evtms.benches.parameters.Parameters` gets a table of the bench's name
(a ``[name]`` table of a parameter file, a ``name`` table in a LUT's
``parameters`` attribute), with no other file to edit.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys

from evtms.benches import BENCHES
from evtms.benches.parameters import SECTIONS, Parameters, load_parameters, parameters_from_json
from evtms.params import Range

#: The fields of :class:`Parameters` that are not a component's table.
NOT_COMPONENTS = {"fluid", "backend", "environment"}


def test_every_registered_bench_is_a_table_of_parameters_with_its_declared_default():
    fields = {f.name: f for f in dataclasses.fields(Parameters)}
    assert set(fields) - NOT_COMPONENTS == set(BENCHES)
    assert SECTIONS == ("environment", *BENCHES)
    for name, bench in BENCHES.items():
        assert fields[name].default_factory is bench.parameters, name
        table = getattr(Parameters(), name)
        assert table == bench.parameters() and dataclasses.is_dataclass(table), name
        for f in dataclasses.fields(table):
            assert isinstance(f.metadata.get("range"), Range), f"{name}.{f.name} has no range"


def test_every_registered_benchs_table_is_read_from_toml_and_lut_json(tmp_path):
    for name, bench in BENCHES.items():
        default = bench.parameters()
        key = dataclasses.fields(default)[0].name
        path = tmp_path / f"{name}.toml"
        path.write_text(f"[{name}]\n{key} = {getattr(default, key)!r}\n")
        assert load_parameters(path) == Parameters(), name
        assert parameters_from_json(name, Parameters().component_json(name)) == Parameters(), name


#: A new component in a fresh interpreter: its parameter class and its bench's registry entry, nothing else.
NEW_COMPONENT = """
import dataclasses
import sys

from evtms.benches import BENCHES
from evtms.errors import EvtmsInputError
from evtms.params import param


@dataclasses.dataclass(frozen=True)
class HeaterParams:
    power_max: float = param(5000.0, 0.0, 1e5, "W", lo_open=True)


BENCHES["heater"] = dataclasses.replace(BENCHES["condenser"], name="heater", parameters=HeaterParams)

from evtms.benches.parameters import Parameters, load_parameters

assert Parameters().heater == HeaterParams()
print(load_parameters(sys.argv[1]).heater.power_max)
try:
    load_parameters(sys.argv[2])
except EvtmsInputError as exc:
    print(exc)
"""


def test_a_new_registry_entry_gets_its_toml_table(tmp_path):
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text("[heater]\npower_max = 3000.0\n")
    bad.write_text("[heater]\npower_max = -1\n")
    res = subprocess.run([sys.executable, "-c", NEW_COMPONENT, good, bad], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0] == "3000.0"
    assert lines[1] == (
        f"params file {str(bad)!r}: [heater] power_max = -1 is not allowed; allowed: 0 < power_max <= 100000 W"
    )
