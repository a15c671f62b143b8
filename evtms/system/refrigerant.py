"""The refrigerant loop as the system simulator sees it: cycle maps and the saturation curve.

:func:`load_refrigerant` takes a folder of cycle LUTs (``evtms bench all
--grid cycle``) and returns the three steady cycle maps
(:mod:`evtms.system.maps`, built once by the cycle solver and cached beside
the LUTs) with the refrigerant's saturation curve, for the loop's
equalised-pressure state when the compressor is off and the supply-air floor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evtms._jit import kernel_array
from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812 - the loop's constants, read as L.*
from evtms.system.maps import (
    MAPS,
    CycleMap,
    MapSettings,
    load_maps,
    map_interp,
    map_values,
    operating_inputs,
)
from evtms.system.params import SystemParams

if TYPE_CHECKING:
    from evtms.cycle.results import CycleResult
    from evtms.cycle.solver import CycleSolver

#: Map names by the loop's map id.
MAP_NAMES = {L.MAP_AC: "ac", L.MAP_CHILLER: "chiller", L.MAP_ACCH: "ac+chiller", L.MAP_HP: "hp"}
#: Physics model: how far a map input may drift from the last solved point before the cycle is solved again.
PHYSICS_TOLERANCE = {
    "speed": 0.02,
    "fan": 0.02,
    "blower": 0.02,
    "u_pump": 0.02,
    "T_amb": 0.1,
    "T_air_in": 0.25,
    "RH_air_in": 0.02,
    "T_coolant_in": 0.25,
    "u_H": 0.02,
    "T_H": 0.25,
    "u_E": 0.02,
    "T_E": 0.25,
}
#: The loop's stand-in for a map not loaded (the heat pump's, unless ``hvac.heating`` is ``heat_pump``): one
#: node of NaN outputs on each of its axes, which the loop never reads.
_NO_MAP = {
    name: (
        kernel_array(np.zeros(len(MAPS[name].axes))),
        kernel_array(np.arange(len(MAPS[name].axes) + 1), np.int64),
        kernel_array(np.full((1, L.N_Y), np.nan)),
    )
    for name in ("hp",)
}


def _bench_default(component: str, name: str) -> float:
    """A component parameter's default, as its bench declares it."""
    from evtms.benches.parameters import Parameters

    return float(getattr(getattr(Parameters(), component), name))


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
    settings : MapSettings
        What besides the LUTs the maps depend on.
    folder : Path, optional
        The cycle LUTs' folder (the physics model solves on its LUTs).
    fan_flow_max, blower_flow_max : float
        Condenser air flow at fan 1 and evaporator air flow at blower 1
        [m3/s]: the ``fan_flow_max`` of the condenser and evaporator LUTs the
        maps were built on (the maps' ``fan`` and ``blower`` axes are shares of
        them); default, the benches' defaults.
    """

    maps: dict[str, CycleMap]
    sat_T: np.ndarray
    sat_p: np.ndarray
    coolant_mdot_max: float
    settings: MapSettings = field(default_factory=MapSettings)
    folder: Path | None = None
    fan_flow_max: float = field(default_factory=lambda: _bench_default("condenser", "fan_flow_max"))
    blower_flow_max: float = field(default_factory=lambda: _bench_default("evaporator", "fan_flow_max"))
    #: Direct-physics solves by map id, reused across runs: a list of (inputs, targets, fallback); under
    #: ``"lut_parameters"`` the outcome of :meth:`check_physics` (the LUT headers are read once per object);
    #: under ``("solver", circuit)`` the physics' cycle solver and under ``("warm", map name)`` the map's
    #: last solution, which the next solve of that map starts from.
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        # The loop's tables, read-only whatever they came as (see evtms._jit.kernel_array).
        object.__setattr__(self, "sat_T", kernel_array(self.sat_T))
        object.__setattr__(self, "sat_p", kernel_array(self.sat_p))

    def packed(self) -> tuple[np.ndarray, ...]:
        """The maps as the loop takes them, in map-id order; one not loaded is a stand-in it never reads."""
        out = []
        for name in MAP_NAMES.values():
            out.extend(self.maps[name].packed() if name in self.maps else _NO_MAP[name])
        return tuple(out)

    def tolerances(self) -> np.ndarray:
        """``(maps, 7)`` input tolerances of the physics model by map id and axis (:data:`PHYSICS_TOLERANCE`)."""
        tol = np.zeros((len(MAP_NAMES), L.N_MAP_X))
        for map_id, name in MAP_NAMES.items():
            for k, axis in enumerate(MAPS[name].axes):
                tol[map_id, k] = PHYSICS_TOLERANCE[axis]
        return tol

    def check_physics(self) -> None:
        """Refuse the physics model where there are no LUTs to take its component parameters from."""
        if self.folder is None:
            raise EvtmsInputError("the physics model needs the cycle LUTs' folder (`luts`)")
        self.physics_parameters()

    def physics_parameters(self):
        """The component parameters the physics model solves with: the ones the cycle LUTs were made with.

        Each component's table comes from its own LUT (:func:`lut_parameters`),
        so the physics describes the same components as the maps; read once per
        object.
        """
        if "lut_parameters" not in self.memo:
            from evtms.cycle import load_cycle_luts

            self.memo["lut_parameters"] = lut_parameters(load_cycle_luts(self.folder, "cabin+chiller"), self.folder)
        return self.memo["lut_parameters"]

    def solve_direct(self, map_id: int, x: np.ndarray) -> tuple[np.ndarray, bool, bool]:
        """Steady targets (:data:`evtms.system.maps.MAP_OUTPUTS`) of the bench physics at the map inputs ``x``.

        Returns ``(y, fallback, solved)``: a point the cycle cannot solve
        takes the LUT map's value and ``fallback`` True; a point within
        :data:`PHYSICS_TOLERANCE` of one solved before (this run or an earlier
        one on this object) is reused, ``solved`` False.
        """
        name = MAP_NAMES[map_id]
        axes = MAPS[name].axes
        x = np.asarray(x[: len(axes)], float)
        tol = self.tolerances()[map_id, : len(axes)]
        for xs, ys, fb in self.memo.get(map_id, ()):
            if np.all(np.abs(xs - x) <= tol):
                return ys, fb, False
        inputs = operating_inputs(name, {a: np.array([v]) for a, v in zip(axes, x, strict=True)}, self.settings)
        values, valid, _ = map_values(self._physics_solve(name, inputs))
        y = values[0].copy()
        fallback = not bool(valid[0])
        if fallback:
            y = np.zeros(L.N_Y)
            map_interp(*self.maps[name].packed(), x, y)
        self.memo.setdefault(map_id, []).append((x.copy(), y, fallback))
        return y, fallback, True

    def _physics_solve(self, name: str, inputs: dict[str, np.ndarray]) -> CycleResult:
        """Map ``name``'s cycle at one point on the bench physics, warm-started from its previous solve.

        The solver (its models and saturation curve) is made once per map and
        object; each solve starts its closures from the last valid solution of
        the same map (:class:`~evtms.cycle.state.WarmStart`), which the loop's
        next point lies near.
        """
        from evtms.cycle.solver import OperatingPoints

        solver = self._physics_solver(MAPS[name].topology)
        warm = self.memo.get(("warm", name))
        res = solver.solve(OperatingPoints(**inputs), warm=warm)
        if np.isfinite(solver.warm_start.t_A).all():
            self.memo[("warm", name)] = solver.warm_start
        return res

    def _physics_solver(self, circuit: str) -> CycleSolver:
        """The direct-physics cycle solver of ``circuit``, made once per object."""
        key = ("solver", circuit)
        if key not in self.memo:
            from evtms.cycle.models import DirectModels
            from evtms.cycle.solver import CycleSolver
            from evtms.fluid import Fluid, SaturationCurve

            params = self.physics_parameters()
            fluid = Fluid(params.fluid, params.backend)
            self.memo[key] = CycleSolver(DirectModels(params, fluid), SaturationCurve(fluid), circuit)
        return self.memo[key]


def lut_parameters(luts: dict, folder: Path):
    """The component parameters a set of cycle LUTs was made with: each component's table from its own LUT.

    Raises
    ------
    EvtmsInputError
        The LUTs disagree on the fluid, the CoolProp backend or the air
        boundary (they cannot describe one circuit).
    """
    import dataclasses

    from evtms.cycle.tables import made_with

    made = {c: made_with(lut) for c, lut in luts.items()}
    first = next(iter(made.values()))
    for c, p in made.items():
        for shared in ("fluid", "backend", "environment"):
            if getattr(p, shared) != getattr(first, shared):
                raise EvtmsInputError(
                    f"the cycle LUTs in {str(folder)!r} disagree on their {shared} ({c} and "
                    f"{next(iter(made))}); build them with one parameter file"
                )
    return dataclasses.replace(first, **{c: getattr(p, c) for c, p in made.items()})


def map_settings(params: SystemParams) -> MapSettings:
    """The map settings the system's parameters imply (the coolant flow at pump 1)."""
    return MapSettings(
        coolant_flow_max=params.coolant.flow_max,
        coolant_density=params.coolant.density,
        heating_flow_max=params.hvac.pump_h_flow,
        edrive_flow_max=params.edrive.flow_max,
    )


def map_names(params: SystemParams) -> tuple[str, ...]:
    """The cycle maps (:data:`evtms.system.maps.MAPS`) a simulation with ``params`` reads: the heat
    pump's only where the cabin heats with one."""
    return ("ac", "chiller", "ac+chiller", *(("hp",) if params.hvac.heating == "heat_pump" else ()))


def load_refrigerant(
    luts_folder: str | Path,
    params: SystemParams | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    settings: MapSettings | None = None,
) -> Refrigerant:
    """Cycle maps (built and cached when missing or stale) and saturation curve of the LUTs in ``luts_folder``.

    ``luts_folder`` is the folder of the cycle LUTs, or the ``luts/`` folder
    or output folder of ``evtms demo`` (:func:`evtms.cycle.api.cycle_luts_folder`);
    the maps are cached beside the LUTs. ``settings`` overrides the map
    settings the parameters imply (e.g. coarser axes).
    """
    from evtms.cycle import load_cycle_luts
    from evtms.cycle.api import saturation_curve
    from evtms.cycle.tables import made_with
    from evtms.luts.store import LutStore

    params = params or SystemParams()
    settings = settings or map_settings(params)
    # Every LUT the maps need is read (headers) and checked first: a bad one is one error before any map work.
    luts = load_cycle_luts(luts_folder, "cabin+chiller")
    sat = saturation_curve(luts)
    # The LUTs all come from one folder, the one found in luts_folder: its store caches the maps.
    folder = LutStore.containing(next(iter(luts.values())).path).folder
    maps = load_maps(folder, settings, map_names(params), progress=progress)
    return Refrigerant(
        maps=maps,
        sat_T=np.ascontiguousarray(sat.T, float),
        sat_p=np.ascontiguousarray(sat.p, float),
        coolant_mdot_max=settings.coolant_flow_max * settings.coolant_density,
        settings=settings,
        folder=folder,
        fan_flow_max=made_with(luts["condenser"]).condenser.fan_flow_max,
        blower_flow_max=made_with(luts["evaporator"]).evaporator.fan_flow_max,
    )
