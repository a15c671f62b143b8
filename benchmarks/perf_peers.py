"""The performance table's peers: TESPy (an R134a cycle point) and FASTSim-3 (a WLTC), where installed.

Both are the optional ``peers`` extra (``pip install -e '.[peers]'``); a peer
that is not importable is one detail row saying so and how to get it, and the
table runs on. Each peer returns its time, which ``perf_table.py`` puts beside
the matching target rows as evtms's time / the peer's.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from accuracy_cycle import envelope
from perf_common import Table, child_fields, child_row, last_json, run_child

from evtms.benches.parameters import Parameters
from evtms.cycle import CycleSolver, OperatingPoints
from evtms.cycle.solver import VALID_CYCLE_FLAGS

INSTALL = "pip install -e '.[peers]'"


def _valid(result: dict) -> int:
    return int(np.isin(result["status"], VALID_CYCLE_FLAGS).sum())


def _one_point(points: OperatingPoints, i: int) -> OperatingPoints:
    return OperatingPoints(**{k: v[i : i + 1] for k, v in points.subset(np.arange(len(points))).items()})


def _version(module) -> str:
    return str(getattr(module, "__version__", "")).split()[0]


# -- TESPy --------------------------------------------------------------------
def tespy_peer(args, solver: CycleSolver, table: Table) -> float | None:
    """The envelope points solved one at a time by TESPy's off-design simulation of a simple R134a cycle;
    returns TESPy's median time per point [ms] (None: not run).

    Model: compressor (constant isentropic efficiency, evtms's nominal 0.65),
    ``Condenser`` (refrigerant out as saturated liquid, subcooling 0 as in the
    cycle's default), ``Valve``, evaporator ``HeatExchanger`` (air hot side,
    refrigerant cold side), closed by a ``CycleCloser``; no pressure drops;
    both air streams are dry air (TESPy's ``air``: evtms's latent heat has no
    counterpart). Design: evtms's own LUT solution at speed 0.6, fan and blower
    1, ambient 30 degC, cabin 27 degC at RH 0.2 (no condensate there), superheat
    10 K sets the suction and discharge pressures and the refrigerant flow, from
    which TESPy sizes the UA of both coils. Off design (``UA_char`` on both
    coils, TESPy's default characteristic lines) an operating point maps as:
    speed -> suction volume flow ``v = v_design * speed / 0.6`` (constant
    volumetric efficiency); fan, blower -> air volume flow at inlet
    ``fan * fan_flow_max`` of the condenser and evaporator parameters; T_amb,
    T_cabin -> air inlet temperatures at 1 atm; superheat -> ``td_dew`` at the
    evaporator outlet; RH_amb and RH_cabin are not used. Each point starts
    from the previous solution (TESPy's default); a point that does not
    converge is retried once from the design state, and that retry is timed too.
    """
    try:
        import logging

        import tespy
        from tespy.components import Compressor, Condenser, CycleCloser, HeatExchanger, Sink, Source, Valve
        from tespy.connections import Connection
        from tespy.networks import Network
        from tespy.tools.logger import TESPY_LOGGER_ID
    except ImportError:
        table.detail("tespy", "TESPy peer", f"not installed: skipped ({INSTALL}, or pip install tespy)")
        return None

    logging.getLogger(TESPY_LOGGER_ID).setLevel(logging.CRITICAL + 1)
    if args.topology != "cabin":
        table.detail("tespy", "TESPy peer", f"modelled for the cabin circuit only, not {args.topology}: skipped")
        return None
    params = Parameters()
    design = OperatingPoints(speed=0.6, fan=1.0, blower=1.0, T_amb=303.15, T_cabin=300.15, RH_cabin=0.2, superheat=10.0)
    ref = solver.solve(design)
    if _valid(ref) != 1:
        table.detail("tespy", "TESPy peer", f"evtms's design point did not solve ({ref['reason'][0]}): skipped")
        return None
    nw = Network(iterinfo=False)
    cc, comp, cond = CycleCloser("cycle closer"), Compressor("compressor"), Condenser("condenser")
    valve, evap = Valve("expansion valve"), HeatExchanger("evaporator")
    amb, amb_out, cab, cab_out = Source("ambient"), Sink("ambient out"), Source("cabin"), Sink("cabin out")
    c0 = Connection(cc, "out1", evap, "in2")
    c1 = Connection(evap, "out2", comp, "in1")
    c2 = Connection(comp, "out1", cond, "in1")
    c3 = Connection(cond, "out1", valve, "in1")
    c4 = Connection(valve, "out1", cc, "in1")
    a1, a2 = Connection(amb, "out1", cond, "in2"), Connection(cond, "out2", amb_out, "in1")
    e1, e2 = Connection(cab, "out1", evap, "in1"), Connection(evap, "out1", cab_out, "in1")
    nw.add_conns(c0, c1, c2, c3, c4, a1, a2, e1, e2)
    comp.set_attr(eta_s=params.compressor.eta_isentropic)
    cond.set_attr(pr1=1, pr2=1, offdesign=["UA_char"])
    evap.set_attr(pr1=1, pr2=1, offdesign=["UA_char"])
    c1.set_attr(fluid={"R134a": 1}, td_dew=10.0, p=float(ref["p_A"][0]), m=float(ref["mdot"][0]), design=["p", "m"])
    c2.set_attr(p=float(ref["p_B"][0]), design=["p"])
    a1.set_attr(fluid={"air": 1}, T=303.15, p=101325.0, v=params.condenser.fan_flow_max)
    e1.set_attr(fluid={"air": 1}, T=300.15, p=101325.0, v=params.evaporator.fan_flow_max)
    version = _version(tespy)
    t0 = time.perf_counter()
    try:
        nw.solve("design", print_results=False)
    except Exception as exc:  # any TESPy failure skips the peer; it does not end the run
        table.detail("tespy", "TESPy peer", f"TESPy {version} design failed ({exc}): skipped")
        return None
    t_design = time.perf_counter() - t0
    if not nw.converged:
        table.detail("tespy", "TESPy peer", f"TESPy {version} design did not converge: skipped")
        return None
    state = nw.save(as_dict=True)
    v_design = c1.v.val

    def solve(init_path=None) -> bool:
        try:
            nw.solve(
                "offdesign",
                design_path=state,
                init_path=init_path,
                init_previous=init_path is None,
                print_results=False,
            )
        except Exception:  # a crashed solve is a failed point
            return False
        return bool(nw.converged)

    points = envelope(args.peer_points, seed=14)
    times, converged, retried, cop = [], 0, 0, []
    for i in range(len(points)):
        c1.set_attr(v=v_design * points.speed[i] / 0.6, td_dew=float(points.superheat[i]))
        a1.set_attr(T=float(points.T_amb[i]), v=float(points.fan[i]) * params.condenser.fan_flow_max)
        e1.set_attr(T=float(points.T_cabin[i]), v=float(points.blower[i]) * params.evaporator.fan_flow_max)
        t0 = time.perf_counter()
        ok = solve()
        if not ok:
            retried += 1
            ok = solve(init_path=state)
        times.append(time.perf_counter() - t0)
        converged += ok
        if ok:
            cop.append(-evap.Q.val / comp.P.val)
    ms = np.array(times) * 1e3
    # evtms on the very same points: one at a time, and as one batch.
    single = []
    for i in range(len(points)):
        t0 = time.perf_counter()
        solver.solve(_one_point(points, i))
        single.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    r = solver.solve(points)
    batch_ms = (time.perf_counter() - t0) / len(points) * 1e3
    evtms_single = float(np.median(single) * 1e3)
    table.detail("tespy_design", "TESPy peer: design solve", f"{t_design * 1e3:.0f} ms (TESPy {version})")
    table.detail(
        "tespy_offdesign",
        f"TESPy peer: off-design, one point at a time ({len(points)} envelope points)",
        f"{np.median(ms):.1f} ms median, {ms.mean():.1f} ms mean per point; {converged}/{len(points)} converged "
        f"({retried} retried from the design state); median COP {np.median(cop) if cop else float('nan'):.2f}",
        median_ms=float(np.median(ms)),
        mean_ms=float(ms.mean()),
        converged=converged,
        n=len(points),
        version=version,
    )
    table.detail(
        "tespy_same_points",
        "TESPy / evtms LUT time per point, same points",
        f"one at a time: {np.median(ms) / evtms_single:.2f} x (evtms {evtms_single:.1f} ms median); "
        f"evtms as one batch: {ms.mean() / batch_ms:.0f} x (evtms {batch_ms:.2f} ms/pt; "
        f"{_valid(r)}/{len(points)} valid, median COP {np.nanmedian(r['COP']):.2f})",
        ratio_single=float(np.median(ms) / evtms_single),
        ratio_batch=float(ms.mean() / batch_ms),
    )
    return float(np.median(ms))


# -- FASTSim-3 ----------------------------------------------------------------
#: FASTSim-3's own vehicle: a battery-electric car with its cabin and battery thermal models, bundled with it.
FASTSIM_VEHICLE = "2020 Chevrolet Bolt EV thrml.yaml"

#: One WLTC through FASTSim-3 as a whole process (argv: vehicle resource, cycle CSV); prints its result line.
FASTSIM_CHILD = """
import json, sys
import fastsim as fsim
veh = fsim.Vehicle.from_resource(sys.argv[1])
sd = fsim.SimDrive(veh, fsim.Cycle.from_file(sys.argv[2]))
sd.run()
state = sd.to_dict()["veh"]["state"]
print(json.dumps({"steps": state["i"], "distance_m": state["dist_meters"]}))
"""


@dataclass
class FastsimTimes:
    """FASTSim-3's WLTC: the library call [s] (median) and the whole process [s] (median); None where failed."""

    call_s: float | None
    process_s: float | None


def write_wltc_csv(path: Path, T_amb: float) -> None:
    """evtms's WLTC class 3b trace as a FASTSim-3 cycle file (time [s], speed [m/s], ambient [K])."""
    from evtms.system.drive_cycles import drive_cycle

    cycle = drive_cycle("wltc3b")
    lines = ["time_seconds,speed_meters_per_second,temp_amb_air_kelvin"]
    lines += [f"{float(t)!r},{float(v)!r},{T_amb!r}" for t, v in zip(cycle.time, cycle.speed, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def fastsim_peer(args, table: Table) -> FastsimTimes | None:
    """FASTSim-3 over evtms's WLTC class 3b at 30 degC with its own vehicle: as a library call (vehicle and
    cycle loaded; median of ``--cli-runs``, at least 3) and as a whole ``python -c`` process (median of
    ``--cli-runs``). None where FASTSim-3 is not installed."""
    try:
        t0 = time.perf_counter()
        import fastsim
    except ImportError:
        table.detail("fastsim", "FASTSim-3 peer", f"not installed: skipped ({INSTALL}, or pip install fastsim)")
        return None
    t_import = time.perf_counter() - t0
    version = _version(fastsim)
    if not version.startswith("3"):
        table.detail("fastsim", "FASTSim-3 peer", f"FASTSim {version} is not version 3: skipped (pip install fastsim)")
        return None
    with tempfile.TemporaryDirectory(prefix="evtms-perf-fastsim-") as tmp:
        csv = Path(tmp) / "wltc3b.csv"
        write_wltc_csv(csv, 303.15)
        veh = fastsim.Vehicle.from_resource(FASTSIM_VEHICLE)
        cyc = fastsim.Cycle.from_file(str(csv))
        calls = []
        for _ in range(max(args.cli_runs, 3) + 1):  # the first call is not counted
            t0 = time.perf_counter()
            sd = fastsim.SimDrive(veh, cyc)
            sd.run()
            calls.append(time.perf_counter() - t0)
        call = statistics.median(calls[1:])
        table.detail(
            "fastsim_call",
            f"FASTSim-3 {version}: one WLTC 3b at 30 degC, library call ({FASTSIM_VEHICLE}; median of "
            f"{len(calls) - 1})",
            f"{call * 1e3:.1f} ms (first call {calls[0] * 1e3:.1f} ms; import {t_import:.2f} s)",
            seconds=call,
            version=version,
        )
        cmd = [sys.executable, "-W", "ignore", "-c", FASTSIM_CHILD, FASTSIM_VEHICLE, str(csv)]
        runs = [run_child(cmd) for _ in range(args.cli_runs)]
    fields = child_fields(runs)
    result = last_json(runs[-1]["out"]) or {}
    table.detail(
        "fastsim_process",
        f"FASTSim-3 {version}: the same as a whole `python -c` process (median of {len(runs)})",
        child_row(runs) + (f"; {result['steps']} steps, {result['distance_m'] / 1e3:.2f} km" if result else ""),
        **fields,
    )
    return FastsimTimes(call, fields.get("wall_s"))
