"""One declaration per system parameter: validation, the loop's packing, provenance and docs all derive from it."""

from __future__ import annotations

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812
from evtms.system.params import HEATING, MIGRATED, SECTIONS, SystemParams, parameter_fields, system_params_from_dict
from evtms.system.simulate import declared_slots, derived_slots, pack_parameters

MAPS = SimpleNamespace(coolant_mdot_max=0.428, fan_flow_max=0.88, blower_flow_max=0.3)


def _all_fields():
    return [(s, f) for s in SECTIONS for f in parameter_fields(s)]


def test_every_loop_slot_is_filled_once_by_a_declaration_or_a_derivation():
    params = SystemParams()
    declared = declared_slots(params)
    derived = derived_slots(params, 303.15, 0.4, 600.0, -1, MAPS)
    assert not set(declared) & set(derived), "a slot is both declared and derived"
    slots = {n for n in vars(L) if n.startswith("P_") and isinstance(getattr(L, n), int)}
    assert {f"P_{n}" for n in declared | derived} == slots
    assert len(slots) == L.N_P and sorted(getattr(L, n) for n in slots) == list(range(L.N_P))
    par = pack_parameters(params, 303.15, 0.4, 600.0, -1, MAPS)
    assert np.isfinite(par).all()


def test_a_declared_slot_carries_the_tables_value_into_the_loop():
    params = system_params_from_dict({"climate": {"cabin_band": 0.7}, "cabin": {"recirc_vent": 0.3}})
    par = pack_parameters(params, 303.15, 0.4, 0.0, -1, MAPS)
    assert par[L.P_BAND] == 0.7 and par[L.P_RC_VENT] == 0.3
    assert par[L.P_FAN_VMAX] == 0.88 and par[L.P_BLOWER_FLOW] == 0.3  # from the LUTs, not the tables


def test_a_choice_is_packed_as_its_index_and_the_loop_agrees():
    assert HEATING.index("ptc_air") == L.HEATING_PTC_AIR and HEATING.index("ptc_coolant") == L.HEATING_PTC_COOLANT
    params = system_params_from_dict({"hvac": {"heating": "ptc_coolant"}})
    assert pack_parameters(params, 303.15, 0.4, 0.0, -1, MAPS)[L.P_HEATING] == L.HEATING_PTC_COOLANT


@pytest.mark.parametrize(("section", "f"), _all_fields(), ids=lambda v: getattr(v, "name", v))
def test_every_parameter_is_validated_recorded_and_sourced_from_its_declaration(section, f):
    assert f.metadata["source"], f"[{section}] {f.name} declares no source"
    assert f.metadata["units"]
    recorded = json.loads(SystemParams().to_json())[section]
    assert f.name in recorded
    choices = f.metadata.get("choices")
    if choices is not None:
        with pytest.raises(EvtmsInputError, match=rf"\[{section}\] {f.name} = \"x\" is not allowed"):
            system_params_from_dict({section: {f.name: "x"}})
        return
    rng = f.metadata["range"]
    too_big = rng.hi * 2 + 1
    with pytest.raises(EvtmsInputError, match=rf"\[{section}\] {f.name} = .* is not allowed; allowed: .*{f.name}"):
        system_params_from_dict({section: {f.name: too_big}})
    with pytest.raises(EvtmsInputError, match=rf"\[{section}\] {f.name} = \"x\" is not a number"):
        system_params_from_dict({section: {f.name: "x"}})
    if rng.whole:
        with pytest.raises(EvtmsInputError, match="whole number"):
            system_params_from_dict({section: {f.name: rng.lo + 0.5}})
    # The default itself is allowed (or unset, for an optional parameter).
    if f.default is not None:
        assert getattr(system_params_from_dict({section: {f.name: f.default}}), section) == getattr(
            SystemParams(), section
        )


@pytest.mark.parametrize(
    ("tables", "message"),
    [
        ({"battery": {"soc_min": 0.95}}, "[battery] soc_min = 0.95 is not allowed with soc_init = 0.9; allowed: "
         "soc_min < soc_init"),
        ({"controls": {"bc_off": 310.0}}, "[controls] bc_off = 310 is not allowed with bc_on = 308.15; allowed: "
         "bc_off < bc_on"),
        ({"climate": {"p_frost_on": 0.1e6}}, "[climate] p_frost_on = 100000 is not allowed with p_frost_off = 150000"),
    ],
)  # fmt: skip
def test_relations_between_parameters_blame_the_one_given(tables, message):
    with pytest.raises(EvtmsInputError) as err:
        system_params_from_dict(tables)
    assert message in str(err.value)


@pytest.mark.parametrize(("section", "name"), sorted(MIGRATED))
def test_a_name_that_moved_or_went_is_refused_with_its_successor(section, name):
    with pytest.raises(EvtmsInputError, match=rf"^\[{section}\] {name} (is|was) "):
        system_params_from_dict({section: {name: 1.0}})


def test_a_value_shared_with_a_bench_is_not_a_system_parameter():
    """The blower's and the condenser fan's full flows are the evaporator and condenser benches' ``fan_flow_max``."""
    names = {f.name for f in parameter_fields("cabin")} | {f.name for f in parameter_fields("controls")}
    assert "blower_flow_max" not in names and "fan_flow_max" not in names
    with pytest.raises(EvtmsInputError, match=r"\[evaporator\] fan_flow_max"):
        system_params_from_dict({"cabin": {"blower_flow_max": 0.4}})


def test_the_refrigerants_default_flows_are_the_benches_defaults():
    from evtms.benches.parameters import Parameters
    from evtms.system.refrigerant import Refrigerant

    r = Refrigerant({}, np.zeros(2), np.zeros(2), 0.428)
    bench = Parameters()
    assert r.fan_flow_max == bench.condenser.fan_flow_max and r.blower_flow_max == bench.evaporator.fan_flow_max


def test_optional_parameters_are_unset_by_default_and_take_a_number():
    optional = [(s, f.name) for s, f in _all_fields() if f.metadata.get("optional")]
    assert ("cabin", "sun") in optional and ("battery", "T_init") in optional
    for section, name in optional:
        assert getattr(getattr(SystemParams(), section), name) is None
    assert system_params_from_dict({"cabin": {"sun": 300.0}}).cabin.sun == 300.0


def test_parameter_tables_are_frozen_dataclasses_whose_fields_all_declare_a_range_or_choices():
    for section in SECTIONS:
        table = getattr(SystemParams(), section)
        assert dataclasses.is_dataclass(table)
        for f in dataclasses.fields(table):
            assert "range" in f.metadata or "choices" in f.metadata, (section, f.name)


def test_one_file_holds_the_components_and_the_system_and_each_side_reads_its_tables(tmp_path):
    from evtms.system.params import load_parameter_tree

    path = tmp_path / "vehicle.toml"
    path.write_text('fluid = "R134a"\n[condenser]\nn_tubes = 44\n[cabin]\nT_set = 294.15\n')
    tree = load_parameter_tree(path)
    assert tree.components.condenser.n_tubes == 44 and tree.system.cabin.T_set == 294.15
    assert tree.given_components() == ("fluid", "condenser") and tree.path == path
    assert load_parameter_tree(None).system == SystemParams()


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("[cabni]\nT_set = 294.15\n", ["unknown table or key 'cabni'", "[condenser]", "[cabin]"]),
        ("[condenser]\nn_tubes = -1\n", ["[condenser] n_tubes = -1 is not allowed"]),
        ("[cabin]\nvolume = -1\n", ["[cabin] volume = -1 is not allowed; allowed: 0.1 <= volume <= 100 m3"]),
    ],
)
def test_a_bad_table_in_the_tree_is_one_line_naming_the_file(tmp_path, text, fragments):
    from evtms.system.params import load_parameter_tree

    path = tmp_path / "p.toml"
    path.write_text(text)
    with pytest.raises(EvtmsInputError) as err:
        load_parameter_tree(path)
    message = str(err.value)
    assert message.startswith(f"params file {str(path)!r}: ") and "\n" not in message
    for fragment in fragments:
        assert fragment in message


def test_a_component_table_the_luts_contradict_is_refused_and_one_they_agree_with_is_not(cycle_luts_dir, tmp_path):
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.tables import made_with
    from evtms.system.params import load_parameter_tree
    from evtms.workflows.common import check_lut_components

    tables = load_cycle_luts(cycle_luts_dir, "cabin+chiller")
    agree, differ, system_only = (tmp_path / f"{n}.toml" for n in ("agree", "differ", "system"))
    agree.write_text(f"[condenser]\nn_tubes = {made_with(tables['condenser']).condenser.n_tubes}\n")
    differ.write_text("[condenser]\nn_tubes = 7\n[cabin]\nT_set = 294.15\n")
    system_only.write_text("[cabin]\nT_set = 294.15\n")
    for ok in (agree, system_only):
        check_lut_components(tables, load_parameter_tree(ok), ok, cycle_luts_dir)
    with pytest.raises(EvtmsInputError, match=r"condenser\.n_tubes\); rebuild the LUTs with these parameters$"):
        check_lut_components(tables, load_parameter_tree(differ), differ, cycle_luts_dir)


def test_the_physics_model_solves_with_each_luts_own_component_parameters(cycle_luts_dir):
    import xarray as xr

    from evtms.benches.parameters import Parameters
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.tables import cycle_lut
    from evtms.system.refrigerant import lut_parameters

    tables = load_cycle_luts(cycle_luts_dir, "cabin+chiller")
    assert lut_parameters(tables, cycle_luts_dir) == Parameters()  # the session's LUTs: the defaults
    with xr.open_dataset(cycle_luts_dir / "condenser.nc") as ds:
        recorded = json.loads(ds.attrs["parameters"])
        recorded["condenser"]["n_tubes"] = 44
        ds.attrs["parameters"] = json.dumps(recorded)
        made = lut_parameters({**tables, "condenser": cycle_lut(ds, "condenser")}, cycle_luts_dir)
        assert made.condenser.n_tubes == 44 and made.evaporator == Parameters().evaporator
        recorded["fluid"] = ds.attrs["fluid"] = "R1234yf"
        ds.attrs["parameters"] = json.dumps(recorded)
        with pytest.raises(EvtmsInputError, match="disagree on their fluid"):
            lut_parameters({**tables, "condenser": cycle_lut(ds, "condenser")}, cycle_luts_dir)
