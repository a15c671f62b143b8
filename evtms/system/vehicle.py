"""Vehicle road load and e-drive over a drive cycle (backward model, one value per cycle segment).

The speed is linear between the cycle's samples, so each segment ``[t_k,
t_k+1]`` has one acceleration ``a = (v_k+1 - v_k) / (t_k+1 - t_k)`` [m/s2]
and is evaluated at its midpoint speed ``v = (v_k + v_k+1) / 2`` [m/s]: the
inertia term's energy over the segment, ``m_eff a v dt``, is then exactly
the change of kinetic energy ``m_eff (v_k+1^2 - v_k^2) / 2``.

Road load (Guzzella and Sciarretta 2013, ch. 2; the thesis' section 3.2,
simplified as the project's system spec 2.1 says):

.. math::

    F = m g (f_0 + f_1 v + f_2 v^2) \\cos\\theta [v > 0] + \\tfrac12 \\rho_{air} C_d A v^2
        + m g \\sin\\theta + m_{eff} a, \\qquad P_{wheel} = F v

with the rolling-resistance coefficient ``f_0`` [1] and its rise with speed ``f_1`` [s/m] and
``f_2`` [s2/m2] (the thesis' control-oriented form, section 3.2; a coast-down's road-load
``A + B v + C v^2`` carries the same speed terms, SAE J2263; both 0 by default: the
Simscape example's constant coefficient), ``theta = atan(grade)``,
``rho_air = 101325 / (287.05 T_amb)`` [kg/m3],
``g = 9.81`` m/s2 and the effective mass ``m_eff = m + 4 J_w / r_w^2`` [kg]
(four wheels of inertia ``J_w`` [kg m2] and radius ``r_w`` [m]).

E-drive: motor speed ``omega_m = G v / r_w`` [rad/s] (gear ratio ``G``).
Motoring, ``P_m = P_wheel / eta_g``; braking, the motor recovers
``P_m = f_regen eta_g P_wheel f_fade(v)`` (``f_fade`` rises linearly from 0
at 5 km/h to 1 at 9 km/h), no more than its torque limit allows
(``-T_max(omega_m) omega_m``) and nothing where regeneration is cut (a full
battery); the friction brakes take the rest. Motor losses come from the
e-drive loss map at ``(n, |T_m|)`` (:func:`evtms.system.tables.edrive_tables`,
bilinear and clamped) times ``loss_factor`` (1.1, the Simscape example's own
factor), 0 at standstill; ``P_motor_el = P_m + P_loss``.

Every segment closes its ledger to round-off:
``P_motor_el = P_wheel + P_gear_loss + P_loss + P_friction`` with the gear
loss ``P_m - P_wheel`` (motoring) or ``P_m - P_m / eta_g`` (braking) and the
friction brakes' ``P_friction = P_m / eta_g - P_wheel`` (>= 0).

References
----------
Guzzella, L., Sciarretta, A. (2013). Vehicle Propulsion Systems, 3rd ed.,
Springer, ch. 2 (longitudinal dynamics).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.params import param
from evtms.system.drive_cycles import DriveCycle
from evtms.system.inputs import Trace
from evtms.system.tables import bilinear_clamped, edrive_tables

GRAVITY = 9.81  # m/s2
#: The speed terms of the rolling resistance: the thesis' form, 0 by default (the example's constant).
_CONSTANT_ROLLING = "thesis 3.2 {}; 0 keeps MW P `Veh.tirecR` constant"
#: Regeneration fades in between these speeds [km/h] (the Simscape example's lookup).
FADE_KMH = (5.0, 9.0)


@dataclass(frozen=True)
class VehicleParams:
    """Vehicle and e-drive parameters (defaults: the Simscape BEV example, MW P).

    Attributes
    ----------
    mass : float
        Vehicle mass [kg] (``vehMass`` 1611).
    drag_coefficient : float
        Aerodynamic drag coefficient [1] (``Veh.cD`` 0.23).
    frontal_area : float
        Frontal area [m2] (``Veh.AVeh`` 2.130).
    rolling_resistance : float
        Rolling-resistance coefficient at rest, f_0 [1] (``Veh.tirecR`` 0.007).
    rolling_resistance_linear, rolling_resistance_quadratic : float
        Its rise with speed, f_1 [s/m] and f_2 [s2/m2] (0: constant).
    wheel_radius : float
        Wheel radius [m] (``Veh.tireR`` 0.334).
    wheel_inertia : float
        Rotational inertia of one wheel [kg m2] (``tireInert`` 2.0).
    gear_ratio : float
        Motor to wheel speed ratio [1] (``Edrive.transmissionRatio`` 9).
    gear_efficiency : float
        Gearbox efficiency [1] (``Edrive.gearboxEff`` 0.97).
    regen_fraction : float
        Share of the braking power the motor takes within its limits [1] (1.0).
    loss_factor : float
        Factor on the e-drive loss map [1] (the example's 1.1).
    aux_power : float
        Constant auxiliary electrical load [W] (FASTSim's 250).
    delta_v_ref : float
        Largest deviation [m/s] of the driven speed from the trace a run may
        be given (input ``speed_deviation``; 0: the trace is driven as it is).
    """

    mass: float = param(1611.0, 100.0, 1e5, "kg", source="MW P `vehMass`")
    drag_coefficient: float = param(0.23, 0.0, 3.0, source="MW P `Veh.cD`")
    frontal_area: float = param(2.130, 0.1, 50.0, "m2", source="MW P `Veh.AVeh`")
    rolling_resistance: float = param(0.007, 0.0, 0.1, source="MW P `Veh.tirecR`")
    rolling_resistance_linear: float = param(0.0, 0.0, 0.01, "s m-1", source=_CONSTANT_ROLLING.format("f_1"))
    rolling_resistance_quadratic: float = param(0.0, 0.0, 1e-3, "s2 m-2", source=_CONSTANT_ROLLING.format("f_2"))
    wheel_radius: float = param(0.334, 0.05, 2.0, "m", source="MW P `Veh.tireR`")
    wheel_inertia: float = param(2.0, 0.0, 100.0, "kg m2", source="MW P `tireInert`, per wheel")
    gear_ratio: float = param(9.0, 0.1, 50.0, source="MW P `Edrive.transmissionRatio`")
    gear_efficiency: float = param(0.97, 0.1, 1.0, source="MW P `Edrive.gearboxEff`")
    regen_fraction: float = param(1.0, 0.0, 1.0, source="MW M series regeneration")
    loss_factor: float = param(1.1, 0.0, 10.0, source="MW P factor on `Edrive.loss_maps`")
    aux_power: float = param(250.0, 0.0, 1e5, "W", source="FS `pwr_aux_base_watts`", slot="AUX")
    delta_v_ref: float = param(
        0.0,
        0.0,
        10.0,
        "m/s",
        source="thesis 3.2: the control-oriented model's bounded deviation from the reference speed; 0: off",
    )

    @property
    def effective_mass(self) -> float:
        """Mass plus the four wheels' rotational inertia [kg]."""
        return self.mass + 4.0 * self.wheel_inertia / self.wheel_radius**2


@dataclass(frozen=True)
class DriveSegments:
    """Road load and e-drive per cycle segment (arrays of the segments, SI).

    Attributes
    ----------
    t0, t1 : numpy.ndarray
        Segment start and end [s].
    speed, acceleration : numpy.ndarray
        Midpoint speed [m/s] and acceleration [m/s2].
    P_wheel, P_traction : numpy.ndarray
        Power at the wheels [W] (< 0 braking) and its positive part.
    P_motor, P_loss, P_motor_el : numpy.ndarray
        Motor shaft power, motor losses and motor electrical power [W].
    P_gear_loss, P_friction : numpy.ndarray
        Gearbox loss and the friction brakes' dissipation [W] (both >= 0).
    torque_limited : numpy.ndarray
        Motoring beyond the motor's torque characteristic (the trace is
        followed anyway; the output flags it).
    """

    t0: np.ndarray
    t1: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    P_wheel: np.ndarray
    P_traction: np.ndarray
    P_motor: np.ndarray
    P_loss: np.ndarray
    P_motor_el: np.ndarray
    P_gear_loss: np.ndarray
    P_friction: np.ndarray
    torque_limited: np.ndarray


def deviated_cycle(cycle: DriveCycle, deviation, bound: float) -> DriveCycle:
    """The trace driven with a bounded deviation from its speed (the thesis's control-oriented model, 3.2).

    ``v = max(v_ref + dv, 0)`` where the reference moves; where it stands the
    car stands (a deviation does not start a stopped car). The acceleration,
    the distance and every load follow from the new speed as from any trace.

    Parameters
    ----------
    cycle : DriveCycle
        The reference trace.
    deviation : float or Trace
        ``dv`` [m/s]: a constant, or a trace on the cycle's clock (linear
        between its samples, held at its ends).
    bound : float
        ``delta_v_ref`` [m/s]: the largest ``|dv|`` allowed.

    Raises
    ------
    EvtmsInputError
        A deviation with ``delta_v_ref`` 0 (off), or one beyond the bound.
    """
    check_deviation(deviation, bound)
    if isinstance(deviation, Trace):
        dv = np.interp(cycle.time, deviation.time, deviation.values)
    else:
        dv = np.full(cycle.time.shape, float(deviation))
    speed = np.where(cycle.speed > 0.0, np.maximum(cycle.speed + dv, 0.0), 0.0)
    return dataclasses.replace(cycle, speed=speed)  # its key-off soaks and every other field kept


def check_deviation(deviation, bound: float) -> None:
    """Refuse a speed deviation (a number or a trace [m/s]) beyond ``delta_v_ref`` ``bound`` [m/s], or any
    with the bound 0 (off): one line, before any work."""
    values = deviation.values if isinstance(deviation, Trace) else np.array([float(deviation)])
    largest = float(np.max(np.abs(values)))
    if bound <= 0.0 and largest > 0.0:
        raise EvtmsInputError(
            f"input speed_deviation up to {largest:g} m/s needs [vehicle] delta_v_ref above 0 (0: off); allowed: "
            "set delta_v_ref, or leave speed_deviation out"
        )
    if largest > bound:
        raise EvtmsInputError(
            f"input speed_deviation up to {largest:g} m/s is not allowed; allowed: within [vehicle] delta_v_ref "
            f"+-{bound:g} m/s"
        )


def rolling_coefficient(p: VehicleParams, speed: np.ndarray) -> np.ndarray:
    """The rolling-resistance coefficient at ``speed`` [m/s]: ``f_0 + f_1 v + f_2 v^2`` [1]."""
    v = np.asarray(speed, float)
    return p.rolling_resistance + (p.rolling_resistance_linear + p.rolling_resistance_quadratic * v) * v


def fade(speed: np.ndarray) -> np.ndarray:
    """Regeneration fade-in [1] at speed [m/s]: 0 below 5 km/h, 1 above 9 km/h, linear between."""
    kmh = np.asarray(speed, float) * 3.6
    return np.clip((kmh - FADE_KMH[0]) / (FADE_KMH[1] - FADE_KMH[0]), 0.0, 1.0)


def drive_segments(
    cycle: DriveCycle, T_amb: float, vehicle: VehicleParams | None = None, regen: bool | np.ndarray = True
) -> DriveSegments:
    """Road load and e-drive powers of every segment of ``cycle``.

    Parameters
    ----------
    cycle : DriveCycle
        The speed trace.
    T_amb : float
        Ambient temperature [K] (air density).
    vehicle : VehicleParams, optional
        Defaults to the Simscape BEV example's vehicle.
    regen : bool or numpy.ndarray
        Whether the battery takes regenerated power (per segment, or for all);
        False cuts regeneration (a full battery): the friction brakes take all.

    Returns
    -------
    DriveSegments
    """
    p = vehicle or VehicleParams()
    ed = edrive_tables()
    t0, t1 = cycle.time[:-1], cycle.time[1:]
    dt = t1 - t0
    v0, v1 = cycle.speed[:-1], cycle.speed[1:]
    v = 0.5 * (v0 + v1)
    a = (v1 - v0) / dt
    theta = np.arctan(0.5 * (cycle.grade[:-1] + cycle.grade[1:]))
    rho_air = 101325.0 / (287.05 * T_amb)
    force = (
        p.mass * GRAVITY * rolling_coefficient(p, v) * np.cos(theta) * (v > 0)
        + 0.5 * rho_air * p.drag_coefficient * p.frontal_area * v**2
        + p.mass * GRAVITY * np.sin(theta)
        + p.effective_mass * a
    )
    P_wheel = force * v
    omega = p.gear_ratio * v / p.wheel_radius
    rpm = omega * 60.0 / (2.0 * np.pi)
    T_max = np.interp(rpm, ed.curve_speed_rpm, ed.curve_torque_Nm)
    eta = p.gear_efficiency
    motoring = P_wheel >= 0
    P_regen = p.regen_fraction * eta * P_wheel * fade(v) * np.asarray(regen, float)
    P_regen = np.maximum(P_regen, -T_max * omega)  # the motor brakes no harder than its torque limit
    P_m = np.where(motoring, P_wheel / eta, P_regen)
    with np.errstate(invalid="ignore", divide="ignore"):
        torque = np.where(omega > 0, P_m / omega, 0.0)
    loss = p.loss_factor * bilinear_clamped(ed.speed_rpm, ed.torque_Nm, ed.loss_W, rpm, np.abs(torque))
    P_loss = np.where(v > 0, loss, 0.0)
    P_gear = np.where(motoring, P_m - P_wheel, P_m - P_m / eta)
    P_friction = np.where(motoring, 0.0, P_m / eta - P_wheel)
    return DriveSegments(
        t0=t0,
        t1=t1,
        speed=v,
        acceleration=a,
        P_wheel=P_wheel,
        P_traction=np.maximum(P_wheel, 0.0),
        P_motor=P_m,
        P_loss=P_loss,
        P_motor_el=P_m + P_loss,
        P_gear_loss=P_gear,
        P_friction=P_friction,
        torque_limited=motoring & (torque > T_max * (1 + 1e-12)),
    )
