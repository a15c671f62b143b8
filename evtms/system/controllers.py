"""Who sets the cabin's set points: the rule-based climate control, or a supervisory controller above it.

The time loop (:mod:`evtms.system.loop`) carries the production structure
of a car's climate control: a cabin loop (feed-forward and PI) sets the
vent-air target and the blower law the blower; below it the requests and
modes, the evaporator's compressor PI, the heaters' PIs, the air mix, the
frost relays and the safety relays turn those into actuator commands.

A *supervisory* controller replaces the cabin loop and the battery-cooling
relay only. Every ``period`` seconds it reads the plant's state and writes
the vent-air target (``SP_vent``), the blower command and the
battery-cooling request (``BC_request``; NaN leaves it to the relay) for
the next period into the loop's external inputs; everything below, every
relay and every actuator range included, stays the same code in both cases,
so the two controllers are compared on one plant with one set of safety
limits. A period the supervisor cannot decide (a failed or late solve) is
written NaN: the rules run it, and the steps carry
:data:`evtms.system.loop.F_CONTROLLER_FALLBACK`.

This is the usual split of automotive climate MPC: a supervisory layer
setting the targets of fast local loops, which keep their own limits
(Rawlings, Mayne and Diehl 2017, Model Predictive Control, 2nd ed.; World
Electric Vehicle Journal 15 (2024) 224 for a cabin MPC in the loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from evtms.system import loop as L  # noqa: N812 - the loop's index constants

#: Controllers ``simulate`` knows by name.
CONTROLLERS = ("rules", "mpc")


def check_controller(name: str, label: str = "controller") -> None:
    """Refuse a controller name ``simulate`` does not know, with one line naming ``label``."""
    from evtms.errors import EvtmsInputError

    if name not in CONTROLLERS:
        raise EvtmsInputError(f"{label} {name!r} is not allowed; allowed: {', '.join(CONTROLLERS)}")


@dataclass(frozen=True)
class ControlContext:
    """What a supervisory controller may know of a run before it starts.

    Attributes
    ----------
    par : numpy.ndarray
        The loop's packed parameters (``P_*`` slots) [SI].
    edges : numpy.ndarray
        Step edges [s] on the run's clock.
    speed : numpy.ndarray
        Mean vehicle speed per step [m/s] (the trace the preview may read).
    motor_power : numpy.ndarray
        Mean motor electrical power per step [W], regeneration included (likewise).
    key_off : numpy.ndarray
        True where the key is off (no climate).
    refrigerant : object
        The run's :class:`evtms.system.refrigerant.Refrigerant` (the cycle maps).
    """

    par: np.ndarray
    edges: np.ndarray
    speed: np.ndarray
    motor_power: np.ndarray
    key_off: np.ndarray
    refrigerant: object


@dataclass(frozen=True)
class Decision:
    """A period's set points; NaN hands the period to the rules.

    Attributes
    ----------
    T_vent : float
        Vent (supply) air target [K].
    blower : float
        Blower command [1].
    solve_time : float
        Wall time of the decision [s]; NaN where there was nothing to decide.
    ok : bool
        False when the controller fell back (a failed or late solve).
    battery_cooling : float
        Battery-cooling request (1 on, 0 off; NaN: its relay decides).
    """

    T_vent: float
    blower: float
    solve_time: float
    ok: bool
    battery_cooling: float = float("nan")


class Supervisor(Protocol):
    """A supervisory controller: ``start`` once per run, ``decide`` at each period's first step."""

    period: float

    def start(self, context: ControlContext) -> None: ...

    def decide(self, n: int, state: np.ndarray, history: np.ndarray) -> Decision: ...


@dataclass
class SupervisionLog:
    """Per-decision record of a supervised run.

    Attributes
    ----------
    solve_times : list of float
        Wall time of each decision [s].
    fallbacks : int
        Periods the rules ran because the controller could not decide.
    """

    solve_times: list[float]
    fallbacks: int = 0

    def summary(self) -> dict:
        """Mean and worst decision time [s], decisions and fallbacks."""
        times = np.asarray(self.solve_times)
        return {
            "controller_decisions": int(times.size),
            "controller_solve_mean_s": float(times.mean()) if times.size else None,
            "controller_solve_max_s": float(times.max()) if times.size else None,
            "controller_fallbacks": int(self.fallbacks),
        }


def check_period(period: float, dt: float) -> None:
    """Refuse a control period that is not a whole number of time steps (the controller's model steps by it)."""
    from evtms.errors import EvtmsInputError

    k = period / dt
    if k < 1.0 - 1e-9 or abs(k - round(k)) > 1e-6:
        raise EvtmsInputError(
            f"control step {period:g} s with time step {dt:g} s is not allowed; allowed: a whole multiple of the "
            "time step"
        )


def period_steps(edges: np.ndarray, period: float) -> np.ndarray:
    """First step of every control period: the steps whose start crosses a multiple of ``period`` [s]."""
    k = np.floor((edges[:-1] - edges[0]) / period + 1e-9)
    return np.flatnonzero(np.diff(np.concatenate(([-1.0], k))) > 0)


def run_supervised(
    args: tuple, supervisor: Supervisor, context: ControlContext, run_chunk
) -> tuple[int, SupervisionLog]:
    """Run the loop period by period, the supervisor writing each period's set points first.

    Parameters
    ----------
    args : tuple
        The loop's arguments up to ``ext`` (:func:`evtms.system.loop.run_loop`).
    supervisor : Supervisor
        Decides each period's vent-air target, blower and battery-cooling request.
    context : ControlContext
        The run as the supervisor may know it.
    run_chunk : callable
        ``run_chunk(args, start) -> done``: runs the loop from ``start`` to
        the end of ``args``' (truncated) step array, as the unsupervised run
        does (physics requests included).

    Returns
    -------
    tuple of (int, SupervisionLog)
        Steps done and the decisions' record.
    """
    dts, states, out, flags, ext = args[1], args[-5], args[-4], args[-2], args[-1]
    supervisor.start(context)
    firsts = period_steps(context.edges, supervisor.period)
    bounds = np.append(firsts, dts.size)
    log = SupervisionLog([])
    done = 0
    for n0, n1 in zip(bounds[:-1], bounds[1:], strict=True):
        n0, n1 = int(n0), int(n1)
        decision = supervisor.decide(n0, states[n0], out[:n0])
        if not math.isnan(decision.solve_time):  # NaN: nothing was decided (the key is off)
            log.solve_times.append(decision.solve_time)
        given = (decision.T_vent, decision.blower, decision.battery_cooling) if decision.ok else (math.nan,) * 3
        ext[n0:n1, L.X_SP_VENT], ext[n0:n1, L.X_BLOWER], ext[n0:n1, L.X_BC_REQUEST] = given
        done = run_chunk((args[0], dts[:n1], *args[2:]), n0)
        if not decision.ok:
            log.fallbacks += 1
            flags[n0:done] |= L.F_CONTROLLER_FALLBACK
        if done < n1:
            break
    return done, log
