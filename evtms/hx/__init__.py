"""Refrigerant heat exchangers: the refrigerant-side zone march and its secondary sides.

- :mod:`evtms.hx.counterflow`: the counter-flow moving-boundary core, an
  evaporating refrigerant (subcooled, two-phase, superheated zones) against
  a single-phase secondary stream;
- :mod:`evtms.hx.sides`: the secondary-stream protocol and the liquid
  coolant side (water-glycol through CoolProp's incompressibles);
- :mod:`evtms.hx.plate`: chevron-plate channel correlations (Martin 1996,
  Yan and Lin 1999) with their validity ranges.

The air-to-refrigerant coils (cross flow, dry and moist air) keep their own
zone march in :mod:`evtms.benches.coil`.
"""
