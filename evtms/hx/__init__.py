"""Refrigerant heat exchangers: the refrigerant-side zone march and its secondary sides.

The refrigerant passes up to three zones (subcooled, two-phase,
superheated); a core marches it through them against a secondary stream
given as an object with a small protocol, so one core serves several
secondary sides:

- :mod:`evtms.hx.crossflow`: cross-flow core, the secondary stream across
  the zones in parallel (the air coils: :mod:`evtms.benches.coil`), with the
  flat-tube refrigerant side :class:`~evtms.hx.crossflow.TubeSide`;
- :mod:`evtms.hx.counterflow`: counter-flow core, the secondary stream
  through the zones in series (the plate chiller:
  :mod:`evtms.benches.chiller`);
- :mod:`evtms.hx.sides`: the secondary sides: dry air, moist air (wet-coil
  enthalpy potential, condensate, outlet never supersaturated) and liquid
  coolant (water-glycol through CoolProp's incompressibles);
- correlations with their references and validity ranges:
  :mod:`evtms.hx.tube` (flat-tube refrigerant side), :mod:`evtms.hx.fins`
  (louvred fins), :mod:`evtms.hx.plate` (chevron plates, Martin 1996, Yan
  and Lin 1999), :mod:`evtms.hx.effectiveness` (effectiveness-NTU).
"""
