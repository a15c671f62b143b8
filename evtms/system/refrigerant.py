"""The refrigerant loop as the system simulator sees it: cycle maps and the saturation curve.

:func:`load_refrigerant` takes a folder of cycle LUTs (``evtms bench all
--grid cycle``) and returns the three steady cycle maps
(:mod:`evtms.system.maps`, built once by the cycle solver and cached beside
the LUTs) with the refrigerant's saturation curve, for the loop's
equalised-pressure state when the compressor is off and the supply-air floor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evtms.system.maps import CycleMap, MapSettings, load_maps
from evtms.system.params import SystemParams


@dataclass(frozen=True)
class Refrigerant:
    """What the loop needs of the refrigerant circuit: the three cycle maps and the saturation curve.

    Attributes
    ----------
    maps : dict of str to CycleMap
        ``ac``, ``chiller`` and ``ac+chiller`` (:func:`evtms.system.maps.load_maps`).
    sat_T, sat_p : numpy.ndarray
        Saturation temperature [K] and pressure [Pa], both increasing.
    coolant_mdot_max : float
        Coolant mass flow at pump command 1 the maps were built for [kg/s].
    """

    maps: dict[str, CycleMap]
    sat_T: np.ndarray
    sat_p: np.ndarray
    coolant_mdot_max: float

    def packed(self) -> tuple[np.ndarray, ...]:
        return tuple(a for name in ("ac", "chiller", "ac+chiller") for a in self.maps[name].packed())


def map_settings(params: SystemParams) -> MapSettings:
    """The map settings the system's parameters imply (condenser fan, coolant flow at pump 1)."""
    return MapSettings(
        condenser_fan=params.controls.condenser_fan,
        coolant_flow_max=params.coolant.flow_max,
        coolant_density=params.coolant.density,
    )


def load_refrigerant(
    luts_folder: str | Path,
    params: SystemParams | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    settings: MapSettings | None = None,
) -> Refrigerant:
    """Cycle maps (built and cached when missing or stale) and saturation curve of the LUTs in ``luts_folder``.

    ``settings`` overrides the map settings the parameters imply (e.g. coarser axes).
    """
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.api import saturation_curve

    params = params or SystemParams()
    settings = settings or map_settings(params)
    # Every LUT the maps need is read (headers) and checked first: a bad one is one error before any map work.
    sat = saturation_curve(load_cycle_luts(luts_folder, "cabin+chiller"))
    maps = load_maps(luts_folder, settings, progress=progress)
    return Refrigerant(
        maps=maps,
        sat_T=np.ascontiguousarray(sat.T, float),
        sat_p=np.ascontiguousarray(sat.p, float),
        coolant_mdot_max=settings.coolant_flow_max * settings.coolant_density,
    )
