"""Heat-transfer, friction and effectiveness correlations of the coils (moved to :mod:`evtms.hx`).

The correlations live with the heat-exchanger core: tube-side refrigerant
correlations in :mod:`evtms.hx.tube`, the louvred-fin air side in
:mod:`evtms.hx.fins`, effectiveness-NTU relations in
:mod:`evtms.hx.effectiveness` (and the chiller's plate correlations in
:mod:`evtms.hx.plate`). This module keeps the old import path working.
"""

from __future__ import annotations

from evtms.hx.effectiveness import counterflow_effectiveness, crossflow_effectiveness
from evtms.hx.fins import (
    CHANG_WANG_RE_RANGE,
    LouveredFin,
    chang_wang_j,
    chang_wang_outside_range,
    louvered_fin_htc,
)
from evtms.hx.tube import (
    GAUSS_NODES,
    GAUSS_WEIGHTS,
    RE_LAMINAR,
    RE_TURBULENT,
    cavallini_zecchin_nusselt,
    chato_film_condensation_htc,
    gungor_winterton_htc,
    haaland_friction_factor,
    muller_steinhagen_heck_gradient,
    single_phase_gradient,
    single_phase_nusselt,
)

__all__ = [
    "CHANG_WANG_RE_RANGE",
    "GAUSS_NODES",
    "GAUSS_WEIGHTS",
    "RE_LAMINAR",
    "RE_TURBULENT",
    "LouveredFin",
    "cavallini_zecchin_nusselt",
    "chang_wang_j",
    "chang_wang_outside_range",
    "chato_film_condensation_htc",
    "counterflow_effectiveness",
    "crossflow_effectiveness",
    "gungor_winterton_htc",
    "haaland_friction_factor",
    "louvered_fin_htc",
    "muller_steinhagen_heck_gradient",
    "single_phase_gradient",
    "single_phase_nusselt",
]
