"""The system simulator's time loop: one compiled function over flat arrays.

Per step ``n`` (length ``dt_n`` [s]), as the project's system spec (v1 2.6,
v2 sections 2-3) says:

(a) controls from the states at ``t_n``, in the structure of production
    climate controls (cabin target -> vent-air target -> evaporator target
    -> air mix; SM-M, SM-S, SM-F, SM-L of the spec):

    - the vent-air target ``T_v* = T_v,ff + K_v e + I_c`` with the
      feed-forward of the cabin's steady balance
      ``T_v,ff = T_set - (UA_shell (T_amb - T_set) + Q_sun + Q_occ) / (m_a c_p)``;
    - cooling, heating, dehumidifying (RH) and fresh-air economy requests on
      first-order filtered cabin and vent-target temperatures, each with its
      set and exit rules and a minimum hold; the mode follows the requests
      and the battery relays (MW M), forced modes skip only the requests;
    - the blower from the vent-target gap, never off while the climate is on,
      in heating capped by what the heater can warm, rate limited;
    - the compressor on the evaporator outlet air (a PI between its minimum
      speed and 1) that cycles on and off with minimum on and off times where
      even its minimum capacity exceeds the load, and a frost relay on the
      evaporator air and the suction pressure that overrides both; the
      chiller's own suction PI for the battery;
    - heat after the evaporator (air PTC, or a coolant PTC through a heater
      core and an air-mix door) only in heating or to reheat under an RH
      request, never to trim a cooling temperature;
    - safety relays in every mode: the coolant heater off above its coolant
      and battery limits, battery cooling off below its battery limit;
    - every PI integrates conditionally: frozen while its output, or an
      actuator downstream of it, is saturated in the direction of its error
      (Astrom and Hagglund 2006, 3.5), so none can wind up;

(b) the refrigerant loop: the steady cycle map's target ``y(u)`` for the
    step's circuit (:mod:`evtms.system.maps`, multilinear) or, with the
    compressor off, zero flows and equalised pressures; every output follows
    the same first-order lag ``tau`` exactly, ``y_f,n+1 = y + (y_f,n - y)
    e^(-dt/tau)``, and the step's sources are the interval means ``y + (y_f,n
    - y) (tau/dt)(1 - e^(-dt/tau))``: a linear filter common to every output
    keeps the map's closure ``Q_condenser = Q_evaporator + Q_chiller +
    W_fluid`` at every step. A step whose evaporator air would end at or
    below the frost relay's threshold is run again with the relay open, so
    the air never crosses it within a step;
(c) the battery: terminal power of motor, auxiliaries and HVAC (heaters cut
    first above the voltage cap), current from the quadratic ``v i = P`` with
    the RC branch's exact interval mean, Joule heat, SOC;
(d) the thermal network by backward Euler with the sources of (b)-(c) held:
    battery and coolant as one 2 x 2 system (the plate's conductance at the
    step's pump flow); the heater-core loop implicit in its own temperature;
    cabin air with the walls and the interior eliminated in closed form
    (each wall mass sees only the air and the ambient), so no matrix is
    factorised; the cabin humidity ratio likewise. Flows computed from the
    new temperatures close every node's ledger to round-off.

Everything is float64 scalars and arrays so that :func:`evtms._jit.jit`
compiles it (numba); with ``EVTMS_NO_NUMBA=1`` the same code runs as Python.
Parameters travel packed in one array (``P_*`` indices), per-step outputs in
one 2-D array (``O_*`` columns), states in another (``S_*`` columns), the
controllers' memory in ``mem`` (``M_*``).

References
----------
Astrom, K. J., Hagglund, T. (2006). Advanced PID Control. ISA, section 3.5
(integrator windup, conditional integration).
Alduchov, O. A., Eskridge, R. E. (1996). Improved Magnus form approximation
of saturation vapor pressure. J. Appl. Meteorol. 35, 601-609.
Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th
ed. Wiley: eq. 8.57 (Hausen's developing laminar flow), eq. 8.62
(Gnielinski), Table 11.3 eqs. 11.33-11.34 (cross flow, one fluid mixed).
Haaland, S. E. (1983). Simple and explicit formulas for the friction factor
in turbulent pipe flow. J. Fluids Eng. 105(1), 89-90.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.hx._kernels import interp
from evtms.system.maps import map_interp

# Modes (T section 4.6 order).
OFF, BH, BC, CC, CH, CH_BH, CH_BC, CC_BC = range(8)
MODE_NAMES = ("off", "BH", "BC", "CC", "CH", "CH+BH", "CH+BC", "CC+BC")

# Flag bits of the output's ``flags``.
(
    F_POWER_LIMITED, F_REF_CLIPPED, F_SURROGATE_OOR, F_REGEN_CUT, F_FREEZE_CUTOFF, F_TRACTION_CUT,
    F_PHYSICS_FALLBACK, F_ECONOMY, F_REHEAT, F_KEY_OFF, F_SAFETY_RELAY, F_FROST_OUTSIDE, F_HP_BACKUP, F_HP_LOCKED,
    F_CONTROLLER_FALLBACK,
) = (1 << i for i in range(15))  # fmt: skip
FLAG_NAMES = (
    "power_limited",
    "ref_clipped",
    "surrogate_out_of_range",
    "regen_cut",
    "freeze_cutoff",
    "traction_cut",
    "physics_fallback",
    "economy",
    "reheat",
    "key_off",
    "safety_relay",
    "frost_outside_hx",
    "hp_backup",
    "hp_locked",
    "controller_fallback",  # set by the supervisory controller's runner (evtms.system.controllers), not the loop
)

# Where the refrigerant loop's steady targets come from (``source``).
SRC_MAPS, SRC_HELD, SRC_SURROGATE = 0, 1, 2
# Map ids of ``held`` (and of the physics requests).
MAP_AC, MAP_CHILLER, MAP_ACCH, MAP_HP = 0, 1, 2, 3
# Refrigerant circuits (output ``circuit``): none, the cabin evaporator, the chiller, both, the heat pump.
CIRCUIT_NONE, CIRCUIT_CABIN, CIRCUIT_CHILLER, CIRCUIT_BOTH, CIRCUIT_HP = range(5)
CIRCUIT_NAMES = ("none", "cabin", "chiller", "cabin+chiller", "hp")
# What the e-drive's losses heat (``edrive.model``): the coolant loop E, or the ambient directly.
EDRIVE_LOOP, EDRIVE_AMBIENT = 0, 1
# Cabin heating options (``hvac.heating``).
HEATING_PTC_AIR, HEATING_PTC_COOLANT, HEATING_HEAT_PUMP = 0, 1, 2

# ``held``: the last refrigerant point the caller solved (SRC_HELD): map id, inputs, targets, fallback.
# Map inputs a request carries (the largest map's axes: ac+chiller's seven).
N_MAP_X = 7
H_MAP, H_X, H_Y, H_FALLBACK = 0, 1, 1 + N_MAP_X, 1 + N_MAP_X + 9
N_H = H_FALLBACK + 1

# ``mem``: the controllers' memory at the start of the next step (resumable runs restart a step from it).
(
    M_SET, M_MODE, M_BC, M_CRIT, M_BH, M_COOL, M_HEAT, M_ECON, M_RHQ, M_WARM,
    M_T_COOL, M_T_HEAT, M_CLR_COOL, M_CLR_HEAT, M_TCAB_F, M_TVS_F, M_I_VENT, M_SAT_UP, M_SAT_DN,
    M_COMP_ON, M_T_COMP, M_I_EV, M_FROST_OK, M_CH_FROST_OK, M_I_CH, M_I_PTC, M_I_PTCW, M_I_BLEND,
    M_BLOWER, M_MDOT, M_TV, M_HEATER_OK, M_HEATER_BAT_OK, M_CHILL_OK, M_Q_HEAT, M_T, M_T_WARM, M_CAB_OFF,
    M_RETRY_STEP, M_FAN_1, M_FAN_2, M_FAN_3, M_STOP, M_RAD_IN,
    M_HP_ON, M_T_HP, M_I_HP, M_U_PS, M_PS_LOW, M_HP_UNTIL, M_TRIP_1, M_TRIP_2, M_TRIP_3,
    M_BACKUP, M_T_BACKUP, M_SRC_1, M_SRC_2, M_SRC_3, M_LAST_CIRCUIT, M_P_PTCW, M_T_RELEASE,
    N_M,
) = range(62)  # fmt: skip

# Why a run ended before its last step (``mem[M_STOP]``): not at all, SOC at its floor, or a mode model's state
# left the physical range (the step that would have put it there is not done).
STOP_NONE, STOP_SOC_MIN, STOP_SURROGATE_RANGE = 0, 1, 2
STOP_NAMES = ("end of cycle", "soc_min", "surrogate_out_of_bounds")

# Map output slots (evtms.system.maps.MAP_OUTPUTS order).
Y_PS, Y_PD, Y_MDOT, Y_QEVAP, Y_QLAT, Y_QCH, Y_QCOND, Y_W, Y_WFLUID = range(9)
N_Y = 9

# Columns of ``ext``, the external inputs per step (evtms.system.inputs.INPUT_NAMES order; NaN: not given).
X_Q_BATTERY, X_INLET_T, X_INLET_RH, X_SP_EVAP, X_SP_COHX, X_BLOWER, X_SP_VENT, X_BC_REQUEST = range(8)
N_X = 8

# Packed parameters.
(
    P_T_AMB, P_W_AMB, P_P_ATM, P_FORCED_MODE, P_AUX,
    P_NS, P_R_SCALE, P_R2, P_C2, P_VMIN, P_CAP_AS, P_SOC_MIN, P_SOC_MAX,
    P_C_BAT, P_G_BA, P_C_COOL, P_HEATER_MAX, P_PUMP_REF, P_PUMP_NMAX,
    P_G_BC_FIXED, P_G_CP, P_PLATE_RE1, P_PLATE_PR, P_PLATE_DL, P_PLATE_KA,
    P_C_AIR, P_M_AIR, P_C_INT, P_G_INT, P_Q_OCC, P_MOIST, P_Q_SUN, P_UA_SHELL,
    P_BLOWER_FLOW, P_BLOWER_POWER, P_T_SET, P_RC_COOL, P_RC_HEAT, P_RC_WARM, P_RC_VENT,
    P_CH_KP, P_CH_KI, P_CH_PS, P_SPEED_MIN, P_DRIVE_EFF, P_TAU,
    P_BC_ON, P_BC_OFF, P_CRIT_ON, P_CRIT_OFF, P_BH_ON, P_BH_OFF, P_BH_AMB_MAX,
    P_PUMP_IDLE, P_PUMP_BC, P_PUMP_CRIT, P_HOLD, P_COOLANT_MDOT_MAX,
    P_G_GLASS, P_G_DOORS, P_G_ROOF, P_C_GLASS, P_C_DOORS, P_C_ROOF,
    P_VENT_KP, P_VENT_TI, P_TV_MIN, P_TV_MAX, P_BLOWER_MIN, P_BL_DT0, P_BL_DT1, P_BL_RATE, P_WARMUP_MAX,
    P_BAND, P_T_CLEAR, P_TAU_REQ, P_TEV_MIN, P_TEV_MAX, P_EV_KP, P_EV_KI, P_DT_CYC, P_T_ON_MIN, P_T_OFF_MIN,
    P_TFR_OFF, P_TFR_ON, P_PF_OFF, P_PF_ON, P_AC_TAMB_MIN, P_RH_DEHUM, P_BLEND_KP, P_BLEND_KI,
    P_HEATING, P_PTC_MAX, P_PTC_KP, P_PTC_KI, P_PTCW_MAX, P_PTCW_KP, P_PTCW_KI, P_TH_MAX, P_C_H,
    P_MDOT_H, P_CP_H, P_PUMP_H_POWER, P_BH_TC_MAX, P_BH_TB_MAX, P_BC_TB_MIN,
    P_FAN_VMAX, P_FAN_PNOM, P_FAN_VNOM, P_RAM_AREA, P_V_FRONT_MIN, P_RAM_FLOOR,
    P_FAN_P1, P_FAN_D1, P_FAN_P2, P_FAN_P3, P_FAN_D23,
    P_EDRIVE_MODEL, P_C_M, P_K1_M, P_C_I, P_F_INV, P_C_D, P_ETA_DC, P_C_E, P_PUMP_E_POWER, P_PUMP_E_MIN,
    P_RAD_ON, P_RAD_OFF, P_JACKET_PR, P_MDOT_E_MAX, P_JACKET_M_RE1, P_JACKET_M_DL, P_JACKET_M_KA,
    P_JACKET_D_RE1, P_JACKET_D_DL, P_JACKET_D_KA,
    P_HP_T_MIN, P_HP_PS_MIN, P_HP_KP, P_HP_KI, P_HP_BACKUP_DELAY, P_HP_RAD_BAND, P_HP_RESTART, P_HP_TRIPS_MAX,
    P_HP_PS_KP, P_HP_PS_KI,
    N_P,
) = range(148)  # fmt: skip

# States at the step boundaries.
(
    S_SOC, S_VRC, S_TB, S_TC, S_TA, S_TGLASS, S_TDOORS, S_TROOF, S_TINT, S_W, S_TH,
    S_YF,
) = range(12)  # fmt: skip
# The e-drive loop's nodes (motor, inverter, DC-DC, coolant E), after the filter's block.
S_TM, S_TI, S_TD, S_TE = range(S_YF + N_Y, S_YF + N_Y + 4)
N_S = S_YF + N_Y + 4

# Per-step outputs (means over the step; commands as held over the step).
(
    O_P_MOTOR_EL, O_P_BATTERY, O_P_HVAC, O_P_COMPRESSOR, O_P_PTC, O_P_HEATER, O_P_BLOWER, O_P_FAN, O_P_PUMP,
    O_Q_EVAP, O_Q_LATENT, O_Q_CHILLER, O_Q_COND, O_W, O_W_FLUID, O_P_SUCTION, O_P_DISCHARGE, O_MDOT_REF,
    O_Q_GEN, O_EMF, O_V, O_I, O_E_RC, O_SPEED_CMD, O_BLOWER, O_U_PUMP, O_MDOT_AIR, O_Q_HEATER,
    O_Q_AIR_SOURCES, O_Q_SUN_INT, O_T_SUPPLY, O_P_DEFICIT, O_REGEN, O_P_GRID,
    O_T_EVAP_AIR, O_T_VENT_TARGET, O_T_EVAP_TARGET, O_RECIRC, O_G_IN, O_T_IN_SRC, O_W_IN_SRC, O_G_BC, O_Q_EXT,
    O_Q_HC, O_P_PTCW, O_P_PUMP_H, O_BLEND, O_T_H_TARGET, O_COMP_ON, O_CIRCUIT, O_P_AUX, O_FAN, O_V_FRONT,
    O_P_PUMP_E, O_P_EDRIVE_AUX, O_Q_DRIVE, O_Q_DCDC, O_Q_RAD, O_T_AIR_RAD, O_U_PUMP_E, O_RAD_IN,
    O_Q_WCC, O_Q_CH_E, O_HP_CEILING,
    N_O,
) = range(65)  # fmt: skip

#: State columns a mode model carries (:data:`evtms.system.mode_model.STATE_NAMES` order).
SURROGATE_STATES = (
    S_TB,
    S_TC,
    S_TA,
    S_TGLASS,
    S_TDOORS,
    S_TROOF,
    S_TINT,
    S_W,
    S_YF + Y_PS,
    S_YF + Y_QEVAP,
    S_YF + Y_QCH,
)
_MLP_WIDTH = 512  # widest network layer the kernel evaluates
# The temperatures a mode model's states may take [K]: -100 to +200 degC, far beyond any trained state. Below
# -243 degC the Magnus saturation pressure of the humidity lookups is 0 and the loop would divide by it.
T_STATE_MIN, T_STATE_MAX = 173.15, 473.15

_H_FG = 2.45e6  # latent heat of condensing water at cabin conditions [J/kg]
_CP_AIR = 1006.0  # dry air [J/(kg K)]
_R_AIR = 287.05  # [J/(kg K)]
_NU_STAGNANT = 2.0  # plate channels with the pump off: natural convection (A, spec v2 section 8)


@jit
def saturation_vapour_pressure(T: float) -> float:
    """Water's saturation pressure over liquid [Pa] at ``T`` [K] (Magnus form, Alduchov and Eskridge 1996)."""
    tc = T - 273.15
    return 610.94 * np.exp(17.625 * tc / (tc + 243.04))


@jit
def relative_humidity(T: float, w: float, p: float) -> float:
    """Relative humidity [1] of air at ``T`` [K], humidity ratio ``w`` [kg/kg] and pressure ``p`` [Pa]."""
    pw = w * p / (0.621945 + w)
    return pw / saturation_vapour_pressure(T)


@jit
def humidity_ratio(T: float, rh: float, p: float) -> float:
    """Humidity ratio [kg/kg dry air] of air at ``T`` [K], relative humidity ``rh`` [1] and ``p`` [Pa]."""
    pw = rh * saturation_vapour_pressure(T)
    return 0.621945 * pw / (p - pw)


@jit
def _table(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """``np.interp(x, xp, fp)`` for one ``x`` (the ends held beyond the table), with NumPy's arithmetic.

    The scalar kernel the other compiled code uses, where numba's ``np.interp`` would be compiled
    again for each of its argument types (seconds each)."""
    if x != x:
        return math.nan
    if x <= xp[0]:
        return fp[0]
    if x >= xp[xp.size - 1]:
        return fp[fp.size - 1]
    return interp(x, xp, fp)


@jit
def _bilinear(xs, ys, table, x, y):
    """Bilinear interpolation clamped to the axes (as evtms.system.tables.bilinear_clamped)."""
    x = min(max(x, xs[0]), xs[-1])
    y = min(max(y, ys[0]), ys[-1])
    i = min(max(np.searchsorted(xs, x, side="right") - 1, 0), xs.size - 2)
    j = min(max(np.searchsorted(ys, y, side="right") - 1, 0), ys.size - 2)
    wx = (x - xs[i]) / (xs[i + 1] - xs[i])
    wy = (y - ys[j]) / (ys[j + 1] - ys[j])
    return (1.0 - wx) * ((1.0 - wy) * table[i, j] + wy * table[i, j + 1]) + wx * (
        (1.0 - wy) * table[i + 1, j] + wy * table[i + 1, j + 1]
    )


@jit
def _pick_mode(bc, crit, bh, cc, ch):
    """The mode the hysteresis flags ask for (spec section 4)."""
    if crit:
        if cc:
            return CC_BC
        if ch:
            return CH_BC
        return BC
    if cc and bc:
        return CC_BC
    if cc:
        return CC
    if bc:
        return CH_BC if ch else BC
    if ch and bh:
        return CH_BH
    if ch:
        return CH
    if bh:
        return BH
    return OFF


@jit
def _input_block(net, offset):
    """Where the packed network at ``net[offset:]`` keeps its input statistics (``x_mean``, ``x_scale``, ``x_min``,
    ``x_max``, each ``n_in`` long, in that order), and ``n_in``."""
    n_layers = int(net[offset])
    return offset + 3 + n_layers, int(net[offset + 2])


@jit
def mlp_eval(net, offset, f, out, h0, h1):
    """Evaluate the packed network at ``net[offset:]`` (:meth:`evtms.system.mode_model.Network.packed`).

    ``f``: features [physical units]; ``out``: outputs [physical units];
    ``h0``, ``h1``: scratch of at least the widest layer. Returns True when a
    feature lies outside the network's training range.
    """
    n_layers = int(net[offset])
    relu = net[offset + 1] == 0.0
    w0 = offset + 2
    p, n_in = _input_block(net, offset)
    n_out = int(net[w0 + n_layers])
    x_mean, x_scale, x_min, x_max = p, p + n_in, p + 2 * n_in, p + 3 * n_in
    y_mean, y_scale = p + 4 * n_in, p + 4 * n_in + n_out
    p = y_scale + n_out
    outside = False
    for i in range(n_in):
        v = f[i]
        # A margin of 1e-6 of the feature's scale: a state the model holds at 0 drifts by round-off.
        margin = 1e-6 * net[x_scale + i]
        if v < net[x_min + i] - margin or v > net[x_max + i] + margin:
            outside = True
        h0[i] = (v - net[x_mean + i]) / net[x_scale + i]
    width = n_in
    for k in range(n_layers):
        nxt = int(net[w0 + k + 1])
        b = p + width * nxt
        for j in range(nxt):
            h1[j] = net[b + j]
        for i in range(width):
            hi = h0[i]
            if hi != 0.0:
                row = p + i * nxt
                for j in range(nxt):
                    h1[j] += hi * net[row + j]
        last = k == n_layers - 1
        for j in range(nxt):
            v = h1[j]
            if not last:
                v = max(v, 0.0) if relu else math.tanh(v)
            h0[j] = v
        p = b + nxt
        width = nxt
    for j in range(n_out):
        out[j] = net[y_mean + j] + net[y_scale + j] * h0[j]
    return outside


@jit
def dew_point(w: float, p: float) -> float:
    """Dew point [K] of air with humidity ratio ``w`` [kg/kg] at ``p`` [Pa] (the Magnus form inverted)."""
    pw = max(w * p / (0.621945 + w), 1e-3)
    g = math.log(pw / 610.94)
    return 273.15 + 243.04 * g / (17.625 - g)


@jit
def frost_point(w: float, p: float) -> float:
    """Frost point [K] of air with humidity ratio ``w`` [kg/kg] at ``p`` [Pa]: where its vapour saturates over ice
    (the Magnus form over ice of Alduchov and Eskridge 1996, inverted)."""
    pw = max(w * p / (0.621945 + w), 1e-3)
    g = math.log(pw / 611.21)
    return 273.15 + 273.86 * g / (22.587 - g)


@jit
def plate_conductance(u_pump: float, re_1: float, pr: float, d_over_l: float, k_area: float, g_cp: float) -> float:
    """Pack-to-coolant conductance [W/K]: cells to plate ``g_cp`` in series with the channels' convection.

    Hausen's thermally developing laminar flow (Incropera eq. 8.57),
    ``Nu = 3.66 + 0.0668 Gz / (1 + 0.04 Gz^(2/3))``, ``Gz = (D/L) Re Pr``,
    with ``Re = u_pump re_1``; with the pump off the channels keep
    ``Nu = 2`` (natural convection, A). ``k_area`` [W/K] is ``k / D`` times
    the channels' wetted area.
    """
    if u_pump <= 0.0:
        nu = _NU_STAGNANT
    else:
        gz = d_over_l * u_pump * re_1 * pr
        nu = 3.66 + 0.0668 * gz / (1.0 + 0.04 * gz ** (2.0 / 3.0))
    h_a = nu * k_area
    return 1.0 / (1.0 / g_cp + 1.0 / h_a)


@jit
def jacket_conductance(u_pump: float, re_1: float, pr: float, d_over_l: float, k_area: float) -> float:
    """Coolant-side conductance [W/K] of a cooling jacket's channels at pump command ``u_pump`` [1].

    ``Re = u_pump re_1``: Hausen's developing laminar flow (Incropera et al.
    2007, eq. 8.57, ``Nu = 3.66 + 0.0668 Gz / (1 + 0.04 Gz^(2/3))``,
    ``Gz = (D/L) Re Pr``) below Re 2300, Gnielinski (eq. 8.62) with Haaland's
    smooth-pipe friction factor at ``max(Re, 4000)`` above, blended linearly
    in Re between (spec v2 5.2): the benches' correlations
    (:func:`evtms.hx.tube.single_phase_nusselt`,
    :func:`evtms.hx.tube.hausen_nusselt`), written out here because the
    simulate path imports no ``evtms.hx`` module (their SciPy). With the pump
    off ``Nu = 2`` (natural convection in the stagnant channels, A).
    ``k_area`` [W/K] is ``k / D`` times the channels' wetted area.
    """
    if u_pump <= 0.0:
        return _NU_STAGNANT * k_area
    re = u_pump * re_1
    gz = d_over_l * re * pr
    laminar = 3.66 + 0.0668 * gz / (1.0 + 0.04 * gz ** (2.0 / 3.0))
    w = min(max((re - 2300.0) / 1700.0, 0.0), 1.0)
    nu = laminar
    if w > 0.0:
        re_t = max(re, 4000.0)
        f8 = (-1.8 * math.log10(6.9 / re_t)) ** -2 / 8.0  # Haaland (1983), smooth channel
        turbulent = max(f8 * (re_t - 1000.0) * pr / (1.0 + 12.7 * math.sqrt(f8) * (pr ** (2.0 / 3.0) - 1.0)), laminar)
        nu = (1.0 - w) * laminar + w * turbulent
    return nu * k_area


@jit
def heating_loop_target(par, T_in, T_vs, T_H, mdot_air, rho_in, sp_cohx, hc_knots, hc_starts, hc_table, x_hc, ua_hc):
    """The heater-core loop's target temperature [K]: the coolant that would bring the air at ``T_in`` to the
    vent target ``T_vs`` through the whole core (``T_in + (T_vs - T_in) / eps``), or the given ``SP_CoHX``;
    at least 3 K above the vent target, at most ``T_H_max``. ``x_hc``, ``ua_hc``: scratch."""
    if not math.isnan(sp_cohx):
        return sp_cohx
    mdot_h = par[P_MDOT_H]
    x_hc[0], x_hc[1], x_hc[2] = mdot_h, T_H, mdot_air / rho_in
    map_interp(hc_knots, hc_starts, hc_table, x_hc, ua_hc)
    eps_full = crossflow_effectiveness(mdot_air * _CP_AIR, mdot_h * par[P_CP_H], ua_hc[0])
    T_H_t = T_in + (T_vs - T_in) / max(eps_full, 0.05)
    return max(min(T_H_t, par[P_TH_MAX]), min(T_vs + 3.0, par[P_TH_MAX]))


@jit
def jacket_conductances(par, u_pump: float) -> tuple[float, float]:
    """The motor's jacket and each drive jacket's (inverter, DC-DC) conductance [W/K] at pump command ``u_pump``."""
    g_m = jacket_conductance(u_pump, par[P_JACKET_M_RE1], par[P_JACKET_PR], par[P_JACKET_M_DL], par[P_JACKET_M_KA])
    g_d = jacket_conductance(u_pump, par[P_JACKET_D_RE1], par[P_JACKET_PR], par[P_JACKET_D_DL], par[P_JACKET_D_KA])
    return g_m, g_d


@jit
def edrive_network(par, s0, s1, dt, T_amb, p_loss, q_dcdc, g_m, g_d, g_rad, T_air_rad, q_chiller) -> float:
    """Advance the e-drive loop's four nodes over one step; returns the radiator's heat [W] (to the air).

    Backward Euler with the sources held (spec v2 5.2, 5.8): the motor
    ``C_m dT_m/dt = (1 - f_inv) P_loss + K_1 (T_amb - T_m) - G_m (T_m - T_E)``,
    the inverter ``C_i dT_i/dt = f_inv P_loss - G_d (T_i - T_E)``, the DC-DC
    ``C_d dT_d/dt = Q_dcdc - G_d (T_d - T_E)`` and the loop
    ``C_E dT_E/dt = sum_k G_k (T_k - T_E) - g_rad (T_E - T_air_rad) - Q_ch`` with
    ``g_rad = eps C_min`` of the radiator (0 while bypassed) and ``Q_ch`` the
    heat pump's chiller drawing on the loop (``q_chiller``, 0 otherwise). Each of the
    three masses sees only the loop (and the motor the ambient), so each is
    eliminated in closed form, ``dT_k = a_k + b_k dT_E``, and the loop's
    change is one division; solved for the changes, not the temperatures, so
    the ledger closes to round-off. ``s0``/``s1``: the state rows at the
    step's start and end (``S_TM``, ``S_TI``, ``S_TD``, ``S_TE``).
    """
    T_m, T_i, T_d, T_E = s0[S_TM], s0[S_TI], s0[S_TD], s0[S_TE]
    q_m = (1.0 - par[P_F_INV]) * p_loss
    q_i = par[P_F_INV] * p_loss
    k1 = par[P_K1_M]
    d_m = par[P_C_M] / dt + k1 + g_m
    a_m = (q_m + k1 * (T_amb - T_m) - g_m * (T_m - T_E)) / d_m
    d_i = par[P_C_I] / dt + g_d
    a_i = (q_i - g_d * (T_i - T_E)) / d_i
    d_d = par[P_C_D] / dt + g_d
    a_d = (q_dcdc - g_d * (T_d - T_E)) / d_d
    num = g_m * (T_m - T_E + a_m) + g_d * (T_i - T_E + a_i) + g_d * (T_d - T_E + a_d) - g_rad * (T_E - T_air_rad)
    num -= q_chiller
    den = par[P_C_E] / dt + g_m * (1.0 - g_m / d_m) + g_d * (1.0 - g_d / d_i) + g_d * (1.0 - g_d / d_d) + g_rad
    d_e = num / den
    s1[S_TE] = T_E + d_e
    s1[S_TM] = T_m + a_m + g_m / d_m * d_e
    s1[S_TI] = T_i + a_i + g_d / d_i * d_e
    s1[S_TD] = T_d + a_d + g_d / d_d * d_e
    return g_rad * (s1[S_TE] - T_air_rad)


@jit
def crossflow_effectiveness(c_air: float, c_liquid: float, ua: float) -> float:
    """Effectiveness [1] of a cross-flow coil, liquid mixed and air unmixed (Incropera eqs. 11.33-11.34).

    Air the smaller stream: ``eps = (1/C_r)(1 - exp(-C_r (1 - e^-NTU)))``;
    liquid the smaller: ``eps = 1 - exp(-(1 - e^(-C_r NTU))/C_r)``; both tend
    to ``1 - e^-NTU`` as ``C_r -> 0`` and coincide at ``C_r = 1``.
    """
    c_min = min(c_air, c_liquid)
    if c_min <= 0.0:
        return 0.0
    c_r = c_min / max(c_air, c_liquid)
    ntu = ua / c_min
    if c_r < 1e-9:
        return 1.0 - math.exp(-ntu)
    if c_air <= c_liquid:
        return (1.0 - math.exp(-c_r * (1.0 - math.exp(-ntu)))) / c_r
    return 1.0 - math.exp(-(1.0 - math.exp(-c_r * ntu)) / c_r)


@jit
def _pi(e, integral, kp, ki, dt, lo, hi):
    """Parallel PI saturated to [lo, hi]; returns (output, integral, saturated in e's direction)."""
    u = kp * e + integral
    out = min(max(u, lo), hi)
    blocked = (u >= hi and e > 0.0) or (u <= lo and e < 0.0)
    if not blocked:
        integral += ki * e * dt
    return out, integral, blocked


@jit
def _relay(on, x, x_off, band):
    """Hysteresis relay: switches on above ``x_off + band``, off below ``x_off``; NaN ``x`` keeps the state."""
    if x > x_off + band:
        return 1.0
    if x < x_off:
        return 0.0
    return on


@jit
def _fan_stages(p_d, s_1, s_2, s_3, par):
    """The condenser fan's three stages [0/1] on the filtered discharge pressure ``p_d`` [Pa].

    Each stage is a relay, on at ``p_k + band_k``, off at ``p_k``
    (the model's condenser-fan requirement, spec v2 5.4): ``p_1`` fixed,
    ``p_2`` and ``p_3`` by ambient temperature (packed per run).
    """
    s_1 = _relay(s_1, p_d, par[P_FAN_P1], par[P_FAN_D1])
    s_2 = _relay(s_2, p_d, par[P_FAN_P2], par[P_FAN_D23])
    s_3 = _relay(s_3, p_d, par[P_FAN_P3], par[P_FAN_D23])
    return s_1, s_2, s_3


@jit
def _filter(y, yf, s1, dt, tau):
    """Advance the common first-order filter: ``s1`` gets the step-end values, ``y`` becomes the interval mean."""
    decay = math.exp(-dt / tau)
    mean_f = tau / dt * (1.0 - decay)
    for k in range(N_Y):
        s1[S_YF + k] = y[k] + (yf[S_YF + k] - y[k]) * decay
        y[k] = y[k] + (yf[S_YF + k] - y[k]) * mean_f


@jit
def surrogate_state_ok(s) -> bool:
    """Whether the mode-model states in the state row ``s`` are physical: finite, every temperature within
    ``T_STATE_MIN`` to ``T_STATE_MAX`` [K]."""
    for k in SURROGATE_STATES:
        if not math.isfinite(s[k]):
            return False
    for k in (S_TB, S_TC, S_TA, S_TGLASS, S_TDOORS, S_TROOF, S_TINT):
        if not T_STATE_MIN <= s[k] <= T_STATE_MAX:
            return False
    return True


@jit
def run_loop(
    par, dts, p_motor_el, soc_ocv, cell_T, cell_ocv, cell_r0, sat_T, sat_p,
    ac_knots, ac_starts, ac_table, ch_knots, ch_starts, ch_table, acch_knots, acch_starts, acch_table,
    hp_knots, hp_starts, hp_table, motor_T, motor_u, rad_knots, rad_starts, rad_table, hc_knots, hc_starts, hc_table,
    states, out, modes, flags, ext, start, source, mem, held, tol, net, net_index,
):  # fmt: skip
    """Run the loop from step ``start`` to ``dts.size``; returns the number of steps done (fewer when SOC hits
    its floor or a mode model leaves the physical range, the reason in ``mem[M_STOP]``), or ``-(n + 1)`` when
    step ``n`` needs a refrigerant point solved (``source`` SRC_HELD).

    ``states`` (steps + 1, N_S) holds the initial state in row 0 and is filled
    row by row; ``out`` (steps, N_O), ``modes`` and ``flags`` (steps) per step.
    ``p_motor_el`` (steps, 7): the step's mean motor electrical power [W]
    with regeneration and with it cut, 1 where the car is plugged in
    (preconditioning: the grid, not the battery, feeds auxiliaries and HVAC),
    1 where the key is off (a soak: no propulsion, auxiliaries, HVAC,
    pumps or DC-DC), the mean vehicle speed [m/s] (ram air) and the e-drive
    loss [W] with regeneration and with it cut. ``motor_T``, ``motor_u``:
    the e-drive pump's and fan's motor-temperature requirement (nodes [K],
    commands [1]); ``rad_knots``, ``rad_starts``, ``rad_table``: the
    radiator's conductance table, ``hc_*`` the heater core's
    (:func:`evtms.system.edrive.core_table`).
    ``ext`` (steps, N_X): external inputs, NaN where not given
    (:mod:`evtms.system.inputs`).

    ``source`` says where the refrigerant targets come from: SRC_MAPS the
    cycle maps; SRC_HELD the caller's solved point in ``held``, reused while
    every map input stays within ``tol`` of the point's inputs (else the loop
    returns a request with the inputs in ``held``; the caller solves, fills
    ``held[H_Y:]`` and calls again from that step); SRC_SURROGATE the mode
    models packed in ``net`` (``net_index[mode, head]``: offset, -1 none)
    replace the refrigerant loop and the thermal network. ``mem`` (N_M)
    carries the controllers' memory between steps and calls.
    """
    T_amb = par[P_T_AMB]
    w_amb = par[P_W_AMB]
    p_atm = par[P_P_ATM]
    forced = int(par[P_FORCED_MODE])
    T_set, band, hold = par[P_T_SET], par[P_BAND], par[P_HOLD]
    u_min = par[P_SPEED_MIN]
    heating_opt = int(par[P_HEATING])
    forced_cabin = forced == CC or forced == CC_BC or forced == CH or forced == CH_BH or forced == CH_BC
    y = np.zeros(N_Y)
    x = np.zeros(N_MAP_X)
    g_w = np.array([par[P_G_GLASS], par[P_G_DOORS], par[P_G_ROOF]])
    c_w = np.array([par[P_C_GLASS], par[P_C_DOORS], par[P_C_ROOF]])
    alphas = np.empty(3)  # per step: wall temperature T_w' = alpha_w + beta_w T_air'
    betas = np.empty(3)
    # Surrogate features, outputs and scratch.
    feat = np.zeros(len(SURROGATE_STATES) + 9)
    pred = np.zeros(len(SURROGATE_STATES))
    h0 = np.empty(_MLP_WIDTH)
    h1 = np.empty(_MLP_WIDTH)
    x_rad = np.zeros(3)  # the radiator table's point: coolant flow, coolant temperature, air flow
    ua_rad = np.zeros(1)
    x_hc = np.zeros(3)  # the heater core's: coolant flow, coolant temperature, air flow through it
    ua_hc = np.zeros(1)
    y_cap = np.zeros(N_Y)  # the heat pump map at full speed, for the blower's cap
    edrive_loop = int(par[P_EDRIVE_MODEL]) == EDRIVE_LOOP
    eta_dc = par[P_ETA_DC] if edrive_loop else 1.0
    if mem[M_SET] == 0.0:
        for k in range(N_M):
            mem[k] = 0.0
        mem[M_SET] = 1.0
        mem[M_MODE] = OFF if forced < 0 else forced
        mem[M_T_COOL] = mem[M_T_HEAT] = mem[M_T_COMP] = -1e300
        mem[M_TCAB_F] = mem[M_TVS_F] = mem[M_TV] = np.nan
        mem[M_FROST_OK] = mem[M_CH_FROST_OK] = 1.0
        mem[M_HEATER_OK] = mem[M_HEATER_BAT_OK] = mem[M_CHILL_OK] = 1.0
        mem[M_CAB_OFF] = 1.0
        mem[M_RETRY_STEP] = -1.0
        mem[M_T_HP] = mem[M_HP_UNTIL] = -1e300
        mem[M_U_PS] = 1.0
        mem[M_TRIP_1] = mem[M_TRIP_2] = mem[M_TRIP_3] = -1e300
        mem[M_T_RELEASE] = -1e300
    n_steps = dts.size
    n = start
    while n < n_steps:
        dt = dts[n]
        t = mem[M_T]
        s0 = states[n]
        s1 = states[n + 1]
        o = out[n]
        soc, v_rc, Tb, Tc, Ta = s0[S_SOC], s0[S_VRC], s0[S_TB], s0[S_TC], s0[S_TA]
        w_cab, T_H = s0[S_W], s0[S_TH]
        key_off = p_motor_el[n, 3] > 0.0
        q_ext = ext[n, X_Q_BATTERY] if not math.isnan(ext[n, X_Q_BATTERY]) else 0.0
        flag = 0
        # (a) controls ------------------------------------------------------------
        bc, crit, bh = mem[M_BC] > 0.0, mem[M_CRIT] > 0.0, mem[M_BH] > 0.0
        cool, heat, econ, rhq, warm = (
            mem[M_COOL] > 0.0,
            mem[M_HEAT] > 0.0,
            mem[M_ECON] > 0.0,
            mem[M_RHQ] > 0.0,
            mem[M_WARM] > 0.0,
        )
        # Battery relays (MW M): requests, skipped by forced modes.
        if Tb > par[P_BC_ON]:
            bc = True
        elif Tb < par[P_BC_OFF]:
            bc = False
        if Tb > par[P_CRIT_ON]:
            crit = True
        elif Tb < par[P_CRIT_OFF]:
            crit = False
        # A given battery-cooling request (a supervisor's) replaces its relay; the critical relay and the
        # safety relays below stay.
        if not math.isnan(ext[n, X_BC_REQUEST]):
            bc = ext[n, X_BC_REQUEST] > 0.5
        if Tc < par[P_BH_ON] and T_amb <= par[P_BH_AMB_MAX]:
            bh = True
        elif Tc > par[P_BH_OFF]:
            bh = False
        # Safety relays, kept in every mode (spec v2 section 3).
        heater_ok, heater_bat_ok, chill_ok = mem[M_HEATER_OK] > 0.0, mem[M_HEATER_BAT_OK] > 0.0, mem[M_CHILL_OK] > 0.0
        if Tc > par[P_BH_TC_MAX]:
            heater_ok = False
        elif Tc < par[P_BH_TC_MAX] - 5.0:
            heater_ok = True
        if Tb >= par[P_BH_TB_MAX]:
            heater_bat_ok = False
        elif Tb < par[P_BH_TB_MAX] - 1.0:
            heater_bat_ok = True
        if Tb < par[P_BC_TB_MIN] or Tc < 278.15:
            chill_ok = False
        elif Tb > par[P_BC_TB_MIN] + 1.0 and Tc > 279.15:
            chill_ok = True
        # Inlet air: fixed (Table 12 Tin) or the mix of cabin and ambient air.
        fixed_inlet = not math.isnan(ext[n, X_INLET_T])
        rc, rh_, rw, rv = par[P_RC_COOL], par[P_RC_HEAT], par[P_RC_WARM], par[P_RC_VENT]
        rh_cab = min(max(relative_humidity(Ta, w_cab, p_atm), 0.0), 1.5)
        # Vent-air target: feed-forward of the cabin's steady balance, proportional and integral terms.
        m_max = par[P_BLOWER_FLOW] * p_atm / (_R_AIR * Ta)
        mdot_ff = max(mem[M_MDOT], par[P_BLOWER_MIN] * m_max)
        q_load = par[P_UA_SHELL] * (T_amb - T_set) + par[P_Q_SUN] + par[P_Q_OCC]
        e_cab = T_set - Ta
        tvs_raw = T_set - q_load / (mdot_ff * _CP_AIR) + par[P_VENT_KP] * e_cab + mem[M_I_VENT]
        # A given vent target (a supervisory controller's, or a trace) replaces the cabin loop's law; the
        # integral then rests, so the law takes over where it left off.
        vent_given = not math.isnan(ext[n, X_SP_VENT])
        if vent_given:
            tvs_raw = ext[n, X_SP_VENT]
        T_vs = min(max(tvs_raw, par[P_TV_MIN]), par[P_TV_MAX])
        up_blocked = tvs_raw >= par[P_TV_MAX] or mem[M_SAT_UP] > 0.0
        dn_blocked = tvs_raw <= par[P_TV_MIN] or mem[M_SAT_DN] > 0.0
        i_vent = mem[M_I_VENT]
        # The integral acts only through a running request (or economy's air mix): idle in the band, parked
        # with the key off or in a battery-only mode it holds, else it winds the vent target 10 K off while
        # nothing follows it, and the next request starts from there.
        acting = (cool or heat or econ) if forced < 0 else forced_cabin
        if (
            not key_off
            and acting
            and not vent_given
            and not ((e_cab > 0.0 and up_blocked) or (e_cab < 0.0 and dn_blocked))
        ):
            i_vent += par[P_VENT_KP] / par[P_VENT_TI] * e_cab * dt
        span = par[P_TV_MAX] - par[P_TV_MIN]
        i_vent = min(max(i_vent, -span), span)
        # Request filters (tau_request): what the requests are tested on.
        a_req = 1.0 - math.exp(-dt / par[P_TAU_REQ])
        tcab_f = Ta if math.isnan(mem[M_TCAB_F]) else mem[M_TCAB_F] + (Ta - mem[M_TCAB_F]) * a_req
        tvs_f = T_vs if math.isnan(mem[M_TVS_F]) else mem[M_TVS_F] + (T_vs - mem[M_TVS_F]) * a_req
        t_cool, t_heat = mem[M_T_COOL], mem[M_T_HEAT]
        clr_cool, clr_heat = mem[M_CLR_COOL], mem[M_CLR_HEAT]
        climate = not key_off and forced != OFF
        if key_off:
            cool = heat = econ = warm = False
            clr_cool = clr_heat = 0.0
        elif forced < 0:
            T_in_c = rc * tcab_f + (1.0 - rc) * T_amb
            T_in_h = rh_ * tcab_f + (1.0 - rh_) * T_amb
            if rh_cab > par[P_RH_DEHUM]:
                rhq = True
            elif rh_cab < par[P_RH_DEHUM] - 0.05:
                rhq = False
            if econ:
                if T_amb > tvs_f - 0.5 or tvs_f > tcab_f + 0.5 or rhq:
                    econ = False
            elif T_amb <= tvs_f - 1.0 and tvs_f <= tcab_f and not rhq:
                econ = True
            if cool:
                # A request ends on the clock only once the compressor has stayed off that long with the cabin
                # cold: counting its minimum speed too ends it while on/off cycling holds the band.
                if mem[M_CAB_OFF] > 0.0 and tcab_f < T_set:
                    clr_cool += dt
                else:
                    clr_cool = 0.0
                # The vent-target exit waits until the compressor has been off for the hold: while it cycles
                # at its minimum below a small load, each on phase overcools the 3.5 kJ/K air and lifts the
                # vent target over the exit, which ended the request every 2-3 min (23.9 degC, no sun).
                comp_rested = mem[M_COMP_ON] == 0.0 and t - mem[M_T_COMP] >= hold
                vent_exit = tvs_f > T_in_c - 0.5 and comp_rested
                if t - t_cool >= hold and (vent_exit or clr_cool >= par[P_T_CLEAR] or econ):
                    cool = False
            elif (
                tvs_f < T_in_c - 2.0
                and (vent_given or tcab_f > T_set + band)
                and T_amb >= par[P_AC_TAMB_MIN]
                and not econ
            ):
                cool = True
                t_cool = t
                clr_cool = 0.0
            if heat:
                if mem[M_Q_HEAT] <= 0.0 and tcab_f > T_set + band:
                    clr_heat += dt
                else:
                    clr_heat = 0.0
                if cool or (t - t_heat >= hold and (tvs_f < T_in_h + 0.5 or clr_heat >= par[P_T_CLEAR])):
                    heat = False
            elif tvs_f > T_in_h + 2.0 and (vent_given or tcab_f < T_set - band) and not cool:
                heat = True
                t_heat = t
                clr_heat = 0.0
                warm = True
                mem[M_T_WARM] = t
            if tcab_f >= T_set:
                warm = False
        # The mode: requests and battery relays, or forced.
        if key_off:
            mode = OFF
        elif forced >= 0:
            mode = forced
        else:
            mode = _pick_mode(bc, crit, bh, cool, heat)
        cab_cool = mode == CC or mode == CC_BC
        cab_heat = mode == CH or mode == CH_BH or mode == CH_BC
        chill = (mode == BC or mode == CH_BC or mode == CC_BC) and chill_ok
        heat_bat = (mode == BH or mode == CH_BH) and heater_ok and heater_bat_ok
        if (mode == BH or mode == CH_BH) and not (heater_ok and heater_bat_ok):
            flag |= F_SAFETY_RELAY
        if (mode == BC or mode == CH_BC or mode == CC_BC) and not chill_ok:
            flag |= F_SAFETY_RELAY
        cabin_on = climate and (forced < 0 or cab_cool or cab_heat)
        # Dehumidifying: the compressor on the cabin coil with reheat; in the cold, fresh air instead.
        rh_active = cabin_on and forced < 0 and rhq and T_amb >= par[P_AC_TAMB_MIN]
        if econ:
            flag |= F_ECONOMY
        # Recirculated share.
        if forced < 0 and econ and abs(Ta - T_amb) > 0.1:
            r = min(max((T_vs - T_amb) / (Ta - T_amb), 0.0), rc)
        elif forced < 0 and rhq and not rh_active:
            r = 0.0
        elif cab_cool or (not cab_heat and T_amb > Ta):
            r = rc
        else:
            # Fog-limited outside cooling: the share falls to 0 as the cabin RH rises from rh_dehum - 0.1 to
            # rh_dehum. Heating recirculates more (a fixed half of fresh air heated 0.66 kW more at 10 degC);
            # with no request the fresh air is what holds a mild cabin (0.8 let 22 degC air drift 1.3 K).
            share = (rw if warm else rh_) if cab_heat else rv
            r = share * min(max((par[P_RH_DEHUM] - rh_cab) / 0.1, 0.0), 1.0)
        if fixed_inlet:
            r = 0.0
            T_in = ext[n, X_INLET_T]
            rh_fix = ext[n, X_INLET_RH]
            w_in = w_amb if math.isnan(rh_fix) else humidity_ratio(T_in, rh_fix, p_atm)
            w_in = min(w_in, humidity_ratio(T_in, 1.0, p_atm))
            T_src, w_src = T_in, w_in
        else:
            T_in = r * Ta + (1.0 - r) * T_amb
            w_in = r * w_cab + (1.0 - r) * w_amb
            T_src, w_src = T_amb, w_amb
        rho_in = p_atm / (_R_AIR * T_in)
        # Heater capability for the blower cap: the heat pump's at full speed adds to its backup's.
        p_heat_max = par[P_PTC_MAX] if heating_opt == HEATING_PTC_AIR else par[P_PTCW_MAX]
        # The heater-core loop's return (the WCC's inlet): the node less what the heater core took last step.
        T_H_ret = T_H - max(mem[M_Q_HEAT], 0.0) / (par[P_MDOT_H] * par[P_CP_H])
        hp_available = T_amb >= par[P_HP_T_MIN] and t >= mem[M_HP_UNTIL] and source != SRC_SURROGATE
        if heating_opt == HEATING_HEAT_PUMP and hp_available:
            x[0], x[1], x[2], x[3], x[4] = 1.0, 1.0, T_H_ret, 0.5, s0[S_TE]
            map_interp(hp_knots, hp_starts, hp_table, x[:5], y_cap)
            if math.isfinite(y_cap[Y_QCOND]):
                p_heat_max += y_cap[Y_QCOND]
        blower = 0.0
        blower_prev = mem[M_BLOWER]
        if cabin_on:
            if not math.isnan(ext[n, X_BLOWER]):
                blower = ext[n, X_BLOWER]
            else:
                b_min = par[P_BLOWER_MIN]
                gap = (abs(T_vs - Ta) - par[P_BL_DT0]) / par[P_BL_DT1]
                law = b_min + (1.0 - b_min) * min(max(gap, 0.0), 1.0)
                if cab_heat:
                    cap = p_heat_max / (max(T_vs - T_in, 1.0) * par[P_BLOWER_FLOW] * rho_in * _CP_AIR)
                    law = max(b_min, min(law, cap))
                    tv_prev = mem[M_TV]
                    if (math.isnan(tv_prev) or tv_prev < Ta + 5.0) and t - mem[M_T_WARM] < par[P_WARMUP_MAX]:
                        law = b_min
                step = par[P_BL_RATE] * dt
                blower = max(min(law, max(blower_prev, b_min) + step), blower_prev - step, b_min)
        mdot_air = blower * par[P_BLOWER_FLOW] * rho_in
        g_in = mdot_air * _CP_AIR * (1.0 - r)
        # Evaporator air: inlet less the filtered sensible duty (its tail after a stop included).
        ps_f = s0[S_YF + Y_PS]
        q_lat_f = s0[S_YF + Y_QLAT]
        if math.isnan(q_lat_f):  # a mode model carries the total duty only
            q_lat_f = 0.0
        sens_f = s0[S_YF + Y_QEVAP] - q_lat_f
        T_ev = T_in - sens_f / (mdot_air * _CP_AIR) if mdot_air > 0.0 else T_in
        sp_evap_given = not math.isnan(ext[n, X_SP_EVAP])
        if sp_evap_given:
            T_ev_t = ext[n, X_SP_EVAP]
        else:
            # The evaporator's highest setting binds only as the cabin air nears the dehumidifying threshold:
            # in dry air the target rises to the inlet less 2 K at part load, so the minimum speed's duty
            # meets a small load without overcooling the cabin (and ending its request).
            t_max = par[P_TEV_MAX] if rh_cab > par[P_RH_DEHUM] - 0.1 else T_in - 2.0
            T_ev_t = max(min(T_vs, t_max, T_in - 2.0), par[P_TEV_MIN])
        if rh_active:
            T_dp = dew_point(w_cab, p_atm)
            T_ev_t = min(T_ev_t, min(max(T_dp - 2.0, par[P_TEV_MIN]), par[P_TEV_MAX]))
        # Frost relays. A step the look-ahead runs again (below) starts from the relays as that step left them
        # (re-armed, less what tripped), also when a physics request re-enters it: it re-arms nothing, so it
        # makes the same decisions every time and each retry opens one more relay (two at most).
        frost_ok, ch_frost_ok = mem[M_FROST_OK] > 0.0, mem[M_CH_FROST_OK] > 0.0
        if mem[M_RETRY_STEP] != n:
            if T_ev <= par[P_TFR_OFF] or ps_f <= par[P_PF_OFF]:
                frost_ok = False
            elif T_ev >= par[P_TFR_ON] and ps_f >= par[P_PF_ON]:
                frost_ok = True
            if ps_f <= par[P_PF_OFF]:
                ch_frost_ok = False
            elif ps_f >= par[P_PF_ON]:
                ch_frost_ok = True
        # Cabin compressor: PI on the evaporator air between u_min and 1, cycling with minimum times.
        cab_coil = cabin_on and (cab_cool or rh_active) and mdot_air > 0.0 and not econ
        comp_on, t_comp, i_ev = mem[M_COMP_ON] > 0.0, mem[M_T_COMP], mem[M_I_EV]
        u_cab = 0.0
        if cab_coil and frost_ok:
            e_ev = T_ev - T_ev_t
            if not comp_on:
                # Not back on into a cabin already below its band: below a small load the minimum speed's
                # 30 s on phases would otherwise stack up and overcool it (a given SP_evap or vent target restarts
                # on its air: the controller that gives it holds the cabin).
                cabin_wants = sp_evap_given or vent_given or tcab_f > T_set - band
                coil_warm = T_ev > T_ev_t + par[P_DT_CYC] and T_ev >= par[P_TFR_ON]
                if coil_warm and cabin_wants and t - t_comp >= par[P_T_OFF_MIN]:
                    comp_on = True
                    t_comp = t
                    i_ev = u_min - par[P_EV_KP] * e_ev  # restart at the minimum speed
            if comp_on:
                u_cab, i_ev, _ = _pi(e_ev, i_ev, par[P_EV_KP], par[P_EV_KI], dt, u_min, 1.0)
                # Off when the compressor can give no less cooling: at its minimum speed with the evaporator air
                # below its target, or, once the cabin is colder than its setpoint, with the evaporator target
                # clipped below a warmer vent target (its highest setting, or the inlet less 2 K) and the air
                # below that: then the duty of on/off cycling, not an ever colder cabin, meets the load. A given
                # SP_evap is held whatever the cabin (the thesis's experiments).
                at_floor = u_cab <= u_min and T_ev < T_ev_t - par[P_DT_CYC]
                clipped_warm = not sp_evap_given and T_vs > T_ev_t and T_ev < T_vs - par[P_DT_CYC] and tcab_f < T_set
                # While a critical battery holds the compressor faster, the cabin branch closes only once the
                # cabin itself is too cold: closing it on its air alone stops the cabin's cooling for the minimum
                # off time, and the 3.5 kJ/K air swings by several kelvin.
                held_up = (
                    crit and chill and ch_frost_ok and mem[M_I_CH] + par[P_CH_KP] * (ps_f - par[P_CH_PS]) * 1e-6 > u_min
                )
                overcooled = tcab_f < T_set - band or not held_up
                if (at_floor or clipped_warm) and overcooled and t - t_comp >= par[P_T_ON_MIN]:
                    comp_on = False
                    t_comp = t
                    u_cab = 0.0
        elif comp_on:
            comp_on = False
            t_comp = t
        if cab_coil and not frost_ok:
            flag |= F_FREEZE_CUTOFF
        # Chiller: suction-pressure PI (battery cooling), floor u_min, its own frost relay.
        u_ch = 0.0
        i_ch = mem[M_I_CH]
        if chill and ch_frost_ok:
            e_ch = (ps_f - par[P_CH_PS]) * 1e-6
            u, i_ch, _ = _pi(e_ch, i_ch, par[P_CH_KP], par[P_CH_KI], dt, 0.0, 1.0)
            u_ch = max(u, u_min)
        elif chill:
            flag |= F_FREEZE_CUTOFF
            i_ch = 0.0
        else:
            i_ch = 0.0
        # Heat pump (spec v2 6): the hp circuit on a PI of the heater-core loop, HP first, the coolant PTC its
        # backup; off with a battery or cabin cooling request, below T_hp_min, after a suction trip until its
        # restart delay, and locked after too many trips.
        u_hp = 0.0
        u_ps = np.nan
        hp_limited = False
        hp_on, t_hp, i_hp, i_ps = mem[M_HP_ON] > 0.0, mem[M_T_HP], mem[M_I_HP], mem[M_U_PS]
        ps_low, hp_until = mem[M_PS_LOW], mem[M_HP_UNTIL]
        trip_1, trip_2, trip_3 = mem[M_TRIP_1], mem[M_TRIP_2], mem[M_TRIP_3]
        trips_in_window = (t - trip_1 < 600.0) + (t - trip_2 < 600.0) + (t - trip_3 < 600.0)
        hp_locked = trips_in_window >= par[P_HP_TRIPS_MAX]
        if hp_locked:
            flag |= F_HP_LOCKED
        T_H_t = np.nan
        if heating_opt != HEATING_PTC_AIR and cab_heat and mdot_air > 0.0:
            T_H_t = heating_loop_target(
                par, T_in, T_vs, T_H, mdot_air, rho_in, ext[n, X_SP_COHX], hc_knots, hc_starts, hc_table, x_hc, ua_hc
            )
        hp_wanted = (
            heating_opt == HEATING_HEAT_PUMP
            and cab_heat
            and mdot_air > 0.0
            and not (cab_coil or chill or bc or crit)
            and hp_available
            and not hp_locked
        )
        backup_restart = False
        if hp_wanted:
            # The heat pump alone reaches at most its map's warmest loop (about 70 degC; the backup gives more).
            T_H_hp = min(T_H_t, hp_knots[hp_starts[3] - 1])
            e_hp = T_H_hp - T_H
            if not hp_on and T_H < T_H_t - par[P_DT_CYC] and t - t_hp >= par[P_T_OFF_MIN]:
                hp_on = True
                t_hp = t
                i_hp = u_min - par[P_HP_KP] * e_hp  # restart at the minimum speed
                i_ps = 1.0
                backup_restart = mem[M_P_PTCW] > 0.0  # the coolant PTC was carrying the load: it backs up at once
            if hp_on:
                # Suction limiter: a PI on the filtered suction's distance from its floor plus 10 kPa sets the
                # speed's ceiling, so the heat pump slows before the guard trips it; the PI on T_H runs below it.
                e_ps = ps_f - (par[P_HP_PS_MIN] + 0.01e6)
                u_ps, i_ps, _ = _pi(e_ps, i_ps, par[P_HP_PS_KP], par[P_HP_PS_KI], dt, u_min, 1.0)
                u_hp, i_hp, _ = _pi(e_hp, i_hp, par[P_HP_KP], par[P_HP_KI], dt, u_min, u_ps)
                hp_limited = (u_ps < 1.0 and u_hp >= u_ps) or T_H_hp < T_H_t
                if u_hp <= u_min and T_H > T_H_t + par[P_DT_CYC] and t - t_hp >= par[P_T_ON_MIN]:
                    hp_on = False
                    t_hp = t
                    u_hp = 0.0
                ps_low = ps_low + dt if ps_f < par[P_HP_PS_MIN] else 0.0
                if ps_low >= 30.0:  # a suction trip
                    hp_on = False
                    t_hp = t
                    u_hp = 0.0
                    ps_low = 0.0
                    hp_until = t + par[P_HP_RESTART]
                    trip_1, trip_2, trip_3 = trip_2, trip_3, t
        else:
            if hp_on:
                t_hp = t
            hp_on = False
            ps_low = 0.0
            i_hp = 0.0
        if u_hp > 0.0:
            circuit = CIRCUIT_HP
        elif u_cab > 0.0 and u_ch > 0.0:
            circuit = CIRCUIT_BOTH
        elif u_cab > 0.0:
            circuit = CIRCUIT_CABIN
        elif u_ch > 0.0:
            circuit = CIRCUIT_CHILLER
        else:
            circuit = CIRCUIT_NONE
        # One compressor for both branches: the cabin's PI sets its speed and the chiller takes what its valve
        # passes, unless the battery is critical. The larger of the two would run the cabin coil at the
        # chiller's suction target (6-7 degC air), overcool the cabin and close its branch for the minimum off
        # time, which swings the 3.5 kJ/K air by 6 K.
        speed = max(u_cab, u_ch) if (crit or u_cab <= 0.0) else u_cab
        if circuit == CIRCUIT_HP:
            speed = u_hp
        p_heater = par[P_HEATER_MAX] if heat_bat else 0.0
        u_pump = 0.0
        if not key_off:
            if crit:
                u_pump = par[P_PUMP_CRIT]
            elif mode == BC or mode == CH_BC or mode == CC_BC:
                u_pump = par[P_PUMP_BC]
            elif mode != OFF:
                u_pump = par[P_PUMP_IDLE]
        if par[P_G_BC_FIXED] >= 0.0:
            g_bc = par[P_G_BC_FIXED]
        else:
            g_bc = plate_conductance(
                u_pump, par[P_PLATE_RE1], par[P_PLATE_PR], par[P_PLATE_DL], par[P_PLATE_KA], par[P_G_CP]
            )
        # E-drive pump: the motor's requirement, never below its floor while the drive works (spec v2 5.3); with
        # the car standing and the motor below the table's first node nothing needs the flow (the table's 0).
        motor_need = 0.0
        u_pump_e = 0.0
        if edrive_loop and not key_off:
            motor_need = _table(s0[S_TM], motor_T, motor_u)
            if motor_need > 0.0 or p_motor_el[n, 5] > 0.0 or p_motor_el[n, 6] > 0.0:
                u_pump_e = min(max(motor_need, par[P_PUMP_E_MIN]), 1.0)
            if circuit == CIRCUIT_HP:  # the chiller's source needs its flow (spec v2 5.3)
                u_pump_e = max(u_pump_e, 0.5)
        # Condenser fan (spec v2 5.4): three stages on the filtered discharge pressure while the compressor is
        # commanded, at least one while ram air is weak, and at least the motor's requirement; fan and ram air
        # add over one quadratic resistance.
        surrogate = source == SRC_SURROGATE
        fan_1, fan_2, fan_3 = _fan_stages(s0[S_YF + Y_PD], mem[M_FAN_1], mem[M_FAN_2], mem[M_FAN_3], par)
        v_ram = par[P_RAM_AREA] * p_motor_el[n, 4]
        u_fan = 0.0
        # The heat pump's source fan: a third per stage on at T_amb - T_E of 4, 7 and 10 K (each off 2 K lower),
        # while the radiator is the source and the compressor runs flat out.
        src_1, src_2, src_3 = mem[M_SRC_1], mem[M_SRC_2], mem[M_SRC_3]
        if circuit == CIRCUIT_HP and mem[M_RAD_IN] > 0.0:
            # A stage switches on only with the compressor flat out, off on its own band: the fan's extra source
            # lets the compressor off its limit, which must not switch the fan off again (a limit cycle).
            lift = T_amb - s0[S_TE]
            flat_out = u_hp >= 1.0 or hp_limited
            new_1, new_2, new_3 = (
                _relay(src_1, lift, 2.0, 2.0),
                _relay(src_2, lift, 5.0, 2.0),
                _relay(src_3, lift, 8.0, 2.0),
            )
            src_1, src_2, src_3 = (
                (new_1, new_2, new_3) if flat_out else (min(new_1, src_1), min(new_2, src_2), min(new_3, src_3))
            )
        else:
            src_1 = src_2 = src_3 = 0.0
        if circuit == CIRCUIT_HP:
            u_fan = (src_1 + src_2 + src_3) / 3.0  # the condenser is shut: its pressure stages do not run
        elif speed > 0.0:
            u_fan = (fan_1 + fan_2 + fan_3) / 3.0
            if surrogate:
                u_fan = 1.0  # the mode models carry no discharge pressure: the fan at full flow
            elif v_ram < par[P_RAM_FLOOR]:
                u_fan = max(u_fan, 1.0 / 3.0)
        u_fan = max(u_fan, motor_need)
        v_fan = u_fan * par[P_FAN_VMAX]
        v_front = max(math.sqrt(v_fan * v_fan + v_ram * v_ram), par[P_V_FRONT_MIN])
        # The maps' fan axis ends at the fan's full flow (the condenser LUT's): more ram air is not credited.
        x_fan = min(v_front / par[P_FAN_VMAX], 1.0)
        # (b) refrigerant target and filter ---------------------------------------
        n_z = len(SURROGATE_STATES)
        p_comp = 0.0
        if surrogate:
            # The mode model replaces the loop's refrigerant and thermal network: no heat flows, no filter.
            for k in range(N_Y):
                y[k] = np.nan
                s1[S_YF + k] = np.nan
        else:
            for k in range(N_Y):
                y[k] = 0.0
            if speed > 0.0:
                clipped = 0
                rh_in = min(max(relative_humidity(T_in, w_in, p_atm), 0.0), 1.0)
                x[0], x[1] = speed, x_fan
                if circuit == CIRCUIT_CABIN:
                    map_id, nx = MAP_AC, 6
                    x[2], x[3], x[4], x[5] = blower, T_amb, T_in, rh_in
                elif circuit == CIRCUIT_HP:
                    map_id, nx = MAP_HP, 5
                    x[1], x[2], x[3], x[4] = 1.0, T_H_ret, u_pump_e, s0[S_TE]
                elif circuit == CIRCUIT_BOTH:
                    map_id, nx = MAP_ACCH, 7
                    x[2], x[3], x[4], x[5], x[6] = blower, u_pump, T_amb, T_in, Tc
                else:
                    map_id, nx = MAP_CHILLER, 5
                    x[2], x[3], x[4] = u_pump, T_amb, Tc
                if source == SRC_HELD:
                    # Physics: reuse the caller's solved point while every input stays within its tolerance.
                    fresh = held[H_MAP] == map_id
                    for k in range(nx):
                        if abs(x[k] - held[H_X + k]) > tol[map_id, k]:
                            fresh = False
                    if not fresh:
                        held[H_MAP] = map_id
                        for k in range(N_MAP_X):
                            held[H_X + k] = x[k] if k < nx else np.nan
                        return -(n + 1)
                    for k in range(N_Y):
                        y[k] = held[H_Y + k]
                    if held[H_FALLBACK] > 0.0:
                        flag |= F_PHYSICS_FALLBACK
                elif circuit == CIRCUIT_CABIN:
                    clipped = map_interp(ac_knots, ac_starts, ac_table, x[:6], y)
                elif circuit == CIRCUIT_HP:
                    clipped = map_interp(hp_knots, hp_starts, hp_table, x[:5], y)
                elif circuit == CIRCUIT_BOTH:
                    clipped = map_interp(acch_knots, acch_starts, acch_table, x, y)
                else:
                    clipped = map_interp(ch_knots, ch_starts, ch_table, x[:5], y)
                if clipped:
                    flag |= F_REF_CLIPPED
            else:
                T_ref = Tc if (mode == BC or mode == CH_BC or mode == BH) else T_in
                p_eq = _table(T_ref, sat_T, sat_p)
                y[Y_PS] = p_eq
                y[Y_PD] = p_eq
            if key_off:
                # Key off: the compressor stops drawing power at once (no filter tail in a soak); the
                # targets already close, so the loop's ledger does too.
                for k in range(N_Y):
                    s1[S_YF + k] = y[k]
            else:
                _filter(y, s0, s1, dt, par[P_TAU])
            # Frost look-ahead: the relay opens before the air or the suction would cross it within the step.
            if speed > 0.0:
                cab_trip = False
                ch_trip = False
                if circuit == CIRCUIT_CABIN or circuit == CIRCUIT_BOTH:
                    sens_end = s1[S_YF + Y_QEVAP] - s1[S_YF + Y_QLAT]
                    T_ev_end = T_in - sens_end / (mdot_air * _CP_AIR)
                    cab_trip = T_ev_end <= par[P_TFR_OFF] or s1[S_YF + Y_PS] <= par[P_PF_OFF]
                if circuit == CIRCUIT_CHILLER or circuit == CIRCUIT_BOTH:
                    ch_trip = s1[S_YF + Y_PS] <= par[P_PF_OFF]
                if cab_trip or ch_trip:
                    mem[M_FROST_OK] = frost_ok and not cab_trip
                    mem[M_CH_FROST_OK] = ch_frost_ok and not ch_trip
                    mem[M_RETRY_STEP] = n
                    continue
            p_comp = y[Y_W] / par[P_DRIVE_EFF]
        q_evap, q_lat, q_chill = y[Y_QEVAP], y[Y_QLAT], y[Y_QCH]
        # The heat pump's heat flows go to its loops (also the filter's tail after it stops): the chiller's to
        # loop E, the water-cooled condenser's to loop H; the front condenser is shut.
        ran = circuit if speed > 0.0 else int(mem[M_LAST_CIRCUIT])
        q_wcc = 0.0
        q_ch_e = 0.0
        q_cond = y[Y_QCOND]
        if ran == CIRCUIT_HP and not surrogate:
            q_wcc, q_ch_e = q_cond, q_chill
            q_cond = 0.0
            q_chill = 0.0
        # Air after the evaporator over the step (interval-mean duty), then heat after it.
        if surrogate:
            T_ev_mean = T_ev
        else:
            T_ev_mean = T_in - (q_evap - q_lat) / (mdot_air * _CP_AIR) if mdot_air > 0.0 else T_in
        reheat_ok = rh_active and u_cab > 0.0
        heating_now = (cab_heat or reheat_ok) and mdot_air > 0.0
        c_air = mdot_air * _CP_AIR
        tv_prev = T_ev_mean if math.isnan(mem[M_TV]) else mem[M_TV]
        e_v = T_vs - tv_prev
        p_ptc = 0.0
        i_ptc, i_ptcw, i_blend = mem[M_I_PTC], mem[M_I_PTCW], mem[M_I_BLEND]
        heater_sat_up = False
        heater_sat_dn = False
        if heating_now and heating_opt == HEATING_PTC_AIR and tv_prev <= par[P_TV_MAX]:
            ff = c_air * (T_vs - T_ev_mean)
            kp, ki = par[P_PTC_KP] * par[P_PTC_MAX], par[P_PTC_KI] * par[P_PTC_MAX]
            u = ff + kp * e_v + i_ptc
            p_ptc = min(max(u, 0.0), par[P_PTC_MAX])
            blocked = (u >= par[P_PTC_MAX] and e_v > 0.0) or (u <= 0.0 and e_v < 0.0)
            if not blocked:
                i_ptc += ki * e_v * dt
            i_ptc = min(max(i_ptc, -par[P_PTC_MAX]), par[P_PTC_MAX])
            heater_sat_up = u >= par[P_PTC_MAX]
            heater_sat_dn = u <= 0.0
        else:
            i_ptc = 0.0
        # Coolant PTC and heater core (loop H): the coolant PTC holds T_H*, the air-mix door the vent air.
        p_ptcw = 0.0
        beta = 0.0
        mdot_h = 0.0
        eps_hc = 0.0
        backup, t_backup, t_release = mem[M_BACKUP] > 0.0, mem[M_T_BACKUP], mem[M_T_RELEASE]
        if heating_now and heating_opt != HEATING_PTC_AIR:
            mdot_h = par[P_MDOT_H]
            if math.isnan(T_H_t):  # reheat under an RH request: the target of this step's vent air
                sp_cohx = ext[n, X_SP_COHX]
                T_H_t = heating_loop_target(
                    par, T_in, T_vs, T_H, mdot_air, rho_in, sp_cohx, hc_knots, hc_starts, hc_table, x_hc, ua_hc
                )
            e_h = T_H_t - T_H
            pmax = par[P_PTCW_MAX]
            kp_w, ki_w = par[P_PTCW_KP] * pmax, par[P_PTCW_KI] * pmax
            if u_hp > 0.0:
                # The coolant PTC backs the heat pump up (split range): on once the HP has run flat out with the
                # loop 2 K short for hp_backup_delay (or at once when it restarts behind a PTC carrying the load),
                # holding 1 K below the target so the HP stays at full speed; off once it has given nothing, or
                # the HP has had margin, for as long.
                flat_out = u_hp >= 1.0 or hp_limited
                if backup_restart:
                    backup = True
                    t_backup = 0.0
                if not backup:
                    short = flat_out and T_H < T_H_t - 2.0
                    t_backup = t_backup + dt if short else 0.0
                    # Released within the last delay, the pump has just shown what it gives: short again, the
                    # backup returns at once (waiting the delay again let a 5 kW heater core cool the loop 20 K).
                    if t_backup >= par[P_HP_BACKUP_DELAY] or (short and t - t_release < par[P_HP_BACKUP_DELAY]):
                        backup = True
                        t_backup = 0.0
                        i_ptcw = 0.0
                if backup:
                    flag |= F_HP_BACKUP
                    u, i_ptcw, _ = _pi(e_h - 1.0, i_ptcw, kp_w, ki_w, dt, 0.0, pmax)
                    if T_H < par[P_TH_MAX]:
                        p_ptcw = u
                    t_backup = t_backup + dt if (p_ptcw <= 0.0 or not flat_out) else 0.0
                    if t_backup >= par[P_HP_BACKUP_DELAY]:
                        backup = False
                        t_backup = 0.0
                else:
                    i_ptcw = 0.0
            elif hp_wanted:  # the heat pump between its on phases holds the loop: no resistive heat
                backup = False
                t_backup = 0.0
                i_ptcw = 0.0
            else:
                backup = False
                t_backup = 0.0
                u, i_ptcw, _ = _pi(e_h, i_ptcw, kp_w, ki_w, dt, 0.0, pmax)
                if T_H < par[P_TH_MAX]:
                    p_ptcw = u
            i_ptcw = min(max(i_ptcw, -pmax), pmax)
            beta, i_blend, blk = _pi(e_v, i_blend, par[P_BLEND_KP], par[P_BLEND_KI], dt, 0.0, 1.0)
            heater_sat_up = blk and e_v > 0.0
            heater_sat_dn = blk and e_v < 0.0
        else:
            i_ptcw = 0.0
            i_blend = 0.0
            backup = False
            t_backup = 0.0
        # Heater core: backward Euler in T_H with the air's inlet (the evaporator outlet) held.
        c_hc_air = beta * c_air
        g_hc = 0.0
        if beta > 0.0 and mdot_h > 0.0:
            x_hc[0], x_hc[1], x_hc[2] = mdot_h, T_H, beta * mdot_air / rho_in
            map_interp(hc_knots, hc_starts, hc_table, x_hc, ua_hc)
            eps_hc = crossflow_effectiveness(c_hc_air, mdot_h * par[P_CP_H], ua_hc[0])
            g_hc = eps_hc * min(c_hc_air, mdot_h * par[P_CP_H])
        c_hh = par[P_C_H] / dt
        T_H_new = (c_hh * T_H + p_ptcw + q_wcc + g_hc * T_ev_mean) / (c_hh + g_hc)
        q_hc = g_hc * (T_H_new - T_ev_mean)
        s1[S_TH] = T_H_new
        p_pump_h = par[P_PUMP_H_POWER] if mdot_h > 0.0 else 0.0
        if reheat_ok and p_ptc + q_hc > 100.0:
            flag |= F_REHEAT
        # Vent-target anti-windup for the next step: what saturates downstream, by direction.
        # In cooling only a compressor cycled off gives no less cooling: at its minimum speed, or with its target
        # at the evaporator's highest setting, a warmer vent target is what makes it cycle.
        sat_up = (cab_heat and heater_sat_up) or (cab_cool and u_cab <= 0.0)
        sat_dn = (cab_cool and u_cab >= 1.0) or (cab_heat and heater_sat_dn and not cab_cool)
        if surrogate:
            # The power head, once the step's heater power is known (the features it was trained on).
            for k in range(n_z):
                feat[k] = s0[SURROGATE_STATES[k]]
            feat[n_z], feat[n_z + 1], feat[n_z + 2] = speed, blower, u_pump
            feat[n_z + 3], feat[n_z + 4], feat[n_z + 5], feat[n_z + 6] = p_ptc, p_heater, T_amb, w_amb
            feat[n_z + 7] = par[P_Q_SUN]
            at = net_index[mode, 0]
            if at < 0:
                flag |= F_SURROGATE_OOR
            else:
                if mlp_eval(net, at, feat, pred, h0, h1):
                    flag |= F_SURROGATE_OOR
                if speed > 0.0:
                    p_comp = max(pred[0], 0.0)
        p_fan = par[P_FAN_PNOM] * (v_fan / par[P_FAN_VNOM]) ** 3
        p_blower = par[P_BLOWER_POWER] * blower**3
        p_pump = par[P_PUMP_REF] * (u_pump * par[P_PUMP_NMAX] / 1000.0) ** 3
        p_pump_e = par[P_PUMP_E_POWER] * u_pump_e**3
        # Low-voltage loads through the DC-DC converter: the pack gives p_lv / eta_dc, the rest heats it.
        p_lv = p_blower + p_fan + p_pump + p_pump_h + p_pump_e
        # (c) battery ---------------------------------------------------------------
        regen = soc < par[P_SOC_MAX]
        if not regen:
            flag |= F_REGEN_CUT
        p_mel = p_motor_el[n, 0] if regen else p_motor_el[n, 1]
        p_aux = par[P_AUX]
        if key_off:
            flag |= F_KEY_OFF
            p_mel = 0.0
            p_aux = 0.0
        ns = par[P_NS]
        E = ns * _table(soc, soc_ocv, cell_ocv)
        R = _bilinear(soc_ocv, cell_T, cell_r0, soc, Tb) * par[P_R_SCALE]
        # RC branch: its interval mean is a + b i (exact exponential solution with i held).
        a_rc = 0.0
        b_rc = 0.0
        decay_rc = 0.0
        r2 = par[P_R2]
        if r2 > 0.0:
            tau_rc = r2 * par[P_C2]
            decay_rc = math.exp(-dt / tau_rc)
            m_rc = tau_rc / dt * (1.0 - decay_rc)
            a_rc = v_rc * m_rc
            b_rc = r2 * (1.0 - m_rc)
        r_eff = R + b_rc
        src = E - a_rc
        v_min = ns * par[P_VMIN]
        cap = v_min * (src - v_min) / r_eff
        p_loads = p_aux + p_comp + p_ptc + p_ptcw + p_heater + p_lv / eta_dc
        p_grid = 0.0
        if p_motor_el[n, 2] > 0.0:  # preconditioning, plugged in: the grid feeds the loads
            p_grid = p_loads
            p_loads = 0.0
        p_batt = p_mel + p_loads
        deficit = 0.0
        if p_batt > cap:
            flag |= F_POWER_LIMITED
            excess = p_batt - cap
            cut = min(excess, p_ptc)
            p_ptc -= cut
            excess -= cut
            cut_w = min(excess, p_ptcw)
            if cut_w > 0.0:  # the coolant PTC too, and the heater-core loop solved again with what it gets
                p_ptcw -= cut_w
                excess -= cut_w
                T_H_new = (c_hh * T_H + p_ptcw + q_wcc + g_hc * T_ev_mean) / (c_hh + g_hc)
                q_hc = g_hc * (T_H_new - T_ev_mean)
                s1[S_TH] = T_H_new
            if (cut > 0.0 or cut_w > 0.0) and cab_heat:
                sat_up = True  # the battery caps the heater: the vent target's integral must not climb
            cut = min(excess, p_heater)
            p_heater -= cut
            excess -= cut
            if excess > 0.0:
                flag |= F_TRACTION_CUT
                deficit = excess
            p_batt = cap
        current = (src - math.sqrt(max(src * src - 4.0 * r_eff * p_batt, 0.0))) / (2.0 * r_eff)
        v_rc_mean = a_rc + b_rc * current
        volt = E - R * current - v_rc_mean
        v_rc_new = 0.0
        e_rc = 0.0
        if r2 > 0.0:
            v_rc_new = r2 * current + (v_rc - r2 * current) * decay_rc
            e_rc = 0.5 * par[P_C2] * (v_rc_new * v_rc_new - v_rc * v_rc)
        q_gen = R * current * current + v_rc_mean * current - e_rc / dt
        s1[S_SOC] = soc - current * dt / par[P_CAP_AS]
        s1[S_VRC] = v_rc_new
        # (d) thermal network: the mode model, or backward Euler ---------------------
        q_air = np.nan
        q_sun_int = np.nan
        if surrogate:
            feat[n_z + 3], feat[n_z + 4], feat[n_z + 8] = p_ptc, p_heater, q_gen
            at = net_index[mode, 1]
            if at >= 0 and mlp_eval(net, at, feat, pred, h0, h1):
                flag |= F_SURROGATE_OOR
            x_min = x_max = 0
            if at >= 0:
                x_mean, n_in = _input_block(net, at)
                x_min, x_max = x_mean + 2 * n_in, x_mean + 3 * n_in
            for k in range(n_z):
                rate = 0.0
                # A state constant throughout the mode's training is held: the data say nothing of its rate.
                if at >= 0 and net[x_min + k] != net[x_max + k]:
                    rate = pred[k]
                s1[SURROGATE_STATES[k]] = s0[SURROGATE_STATES[k]] + dt * rate
            # Physical bounds the networks do not know: humidity, pressure and the loop's cooling flows are >= 0.
            for k in (S_W, S_YF + Y_PS, S_YF + Y_QEVAP, S_YF + Y_QCH):
                s1[k] = max(s1[k], 0.0)
            if not surrogate_state_ok(s1):
                # A model that ran away: the next step's controls would take its state as real (and divide by
                # a saturation pressure of 0). The run ends before this step, with the reason in ``mem``.
                mem[M_STOP] = STOP_SURROGATE_RANGE
                return n
            if at < 0:
                flag |= F_SURROGATE_OOR
            # Filtered suction pressure and heat flows: the step's mean of the model's states.
            for k in (Y_PS, Y_QEVAP, Y_QCH):
                y[k] = 0.5 * (s0[S_YF + k] + s1[S_YF + k])
            q_evap, q_chill = y[Y_QEVAP], y[Y_QCH]
        else:
            cb, cc_ = par[P_C_BAT] / dt, par[P_C_COOL] / dt
            gba = par[P_G_BA]
            a11 = cb + g_bc + gba
            a22 = cc_ + g_bc
            # Solved for the changes (not the temperatures): smaller numbers, ledgers closer to round-off.
            r1 = q_gen + q_ext - g_bc * (Tb - Tc) - gba * (Tb - T_amb)
            r2_ = g_bc * (Tb - Tc) + p_heater - q_chill
            det = a11 * a22 - g_bc * g_bc
            s1[S_TB] = Tb + (r1 * a22 + g_bc * r2_) / det
            s1[S_TC] = Tc + (a11 * r2_ + g_bc * r1) / det
            # Cabin: wall w and interior eliminated, T_w' = alpha_w + beta_w T_air'.
            q_sun = par[P_Q_SUN]
            c_int = par[P_C_INT]
            q_sun_int = q_sun if c_int > 0.0 else 0.0
            q_air = par[P_Q_OCC] + (q_sun - q_sun_int) + p_ptc + q_hc - (q_evap - q_lat)
            lhs = par[P_C_AIR] / dt + g_in
            rhs = par[P_C_AIR] / dt * Ta + g_in * T_src + q_air
            for k in range(3):
                cw = c_w[k] / dt
                den = cw + 2.0 * g_w[k]
                alphas[k] = (cw * s0[S_TGLASS + k] + g_w[k] * T_amb) / den
                betas[k] = g_w[k] / den
                lhs += g_w[k] * (1.0 - betas[k])
                rhs += g_w[k] * alphas[k]
            alpha_i = 0.0
            beta_i = 0.0
            if c_int > 0.0:
                ci = c_int / dt
                g_i = par[P_G_INT]
                alpha_i = (ci * s0[S_TINT] + q_sun_int) / (ci + g_i)
                beta_i = g_i / (ci + g_i)
                lhs += g_i * (1.0 - beta_i)
                rhs += g_i * alpha_i
            Ta_new = rhs / lhs
            s1[S_TA] = Ta_new
            for k in range(3):
                s1[S_TGLASS + k] = alphas[k] + betas[k] * Ta_new
            s1[S_TINT] = alpha_i + beta_i * Ta_new if c_int > 0.0 else Ta_new
            # Cabin humidity ratio: inflow, occupants, condensate.
            m_air = par[P_M_AIR] / dt
            g_w_in = mdot_air * (1.0 - r)
            w_new = (m_air * w_cab + g_w_in * w_src + par[P_MOIST] - q_lat / _H_FG) / (m_air + g_w_in)
            s1[S_W] = max(w_new, 0.0)
        if surrogate:
            s1[S_TH] = T_H
        # E-drive loop E: motor, inverter and DC-DC eliminated onto the loop, the radiator implicit in it.
        p_loss = 0.0 if key_off else (p_motor_el[n, 5] if regen else p_motor_el[n, 6])
        q_drive = p_loss if edrive_loop else 0.0
        q_dcdc = p_lv * (1.0 / eta_dc - 1.0)
        rad_in = mem[M_RAD_IN]
        q_rad = 0.0
        T_air_rad = T_amb
        if edrive_loop:
            T_E = s0[S_TE]
            if circuit == CIRCUIT_HP:
                # The heat pump's source: the radiator draws on the ambient while the loop is colder than it,
                # and is bypassed while the loop is warmer (it keeps the drive's waste heat), unless the loop
                # passes the radiator's own switch-on temperature (the drive's cooling comes first).
                band_hp = par[P_HP_RAD_BAND]
                rad_in = _relay(rad_in, T_amb - T_E, -band_hp, 2.0 * band_hp)
                if T_E > par[P_RAD_ON]:
                    rad_in = 1.0
            else:
                rad_in = _relay(rad_in, T_E, par[P_RAD_OFF], par[P_RAD_ON] - par[P_RAD_OFF])
            mdot_e = u_pump_e * par[P_MDOT_E_MAX]
            g_m, g_d = jacket_conductances(par, u_pump_e)
            g_rad = 0.0
            if rad_in > 0.0 and mdot_e > 0.0:
                # Stacked front end: the condenser's heat warms the radiator's air.
                c_front = p_atm / (_R_AIR * T_amb) * v_front * _CP_AIR
                if math.isfinite(q_cond) and q_cond > 0.0:
                    T_air_rad = T_amb + q_cond / c_front
                x_rad[0], x_rad[1], x_rad[2] = mdot_e, T_E, v_front
                map_interp(rad_knots, rad_starts, rad_table, x_rad, ua_rad)
                c_e = mdot_e * par[P_CP_H]
                g_rad = crossflow_effectiveness(c_front, c_e, ua_rad[0]) * min(c_front, c_e)
            q_rad = edrive_network(par, s0, s1, dt, T_amb, p_loss, q_dcdc, g_m, g_d, g_rad, T_air_rad, q_ch_e)
            # Frost on the radiator: it is the source, its cold end below 0 degC and the ambient's frost point.
            if rad_in > 0.0 and mdot_e > 0.0 and T_E < 273.15 and T_E < frost_point(w_amb, p_atm):
                flag |= F_FROST_OUTSIDE
        else:
            for k in (S_TM, S_TI, S_TD, S_TE):
                s1[k] = s0[k]
        # Vent air (the air node's inflow temperature) over the step.
        T_v = T_ev_mean + (p_ptc + q_hc) / c_air if mdot_air > 0.0 else np.nan
        # Controller memory for the next step ---------------------------------------
        mem[M_MODE] = mode
        mem[M_BC], mem[M_CRIT], mem[M_BH] = bc, crit, bh
        mem[M_COOL], mem[M_HEAT], mem[M_ECON], mem[M_RHQ], mem[M_WARM] = cool, heat, econ, rhq, warm
        mem[M_T_COOL], mem[M_T_HEAT], mem[M_CLR_COOL], mem[M_CLR_HEAT] = t_cool, t_heat, clr_cool, clr_heat
        mem[M_TCAB_F], mem[M_TVS_F], mem[M_I_VENT] = tcab_f, tvs_f, i_vent
        mem[M_SAT_UP], mem[M_SAT_DN] = sat_up, sat_dn
        mem[M_COMP_ON], mem[M_T_COMP], mem[M_I_EV] = comp_on, t_comp, i_ev
        mem[M_FROST_OK], mem[M_CH_FROST_OK], mem[M_I_CH] = frost_ok, ch_frost_ok, i_ch
        mem[M_I_PTC], mem[M_I_PTCW], mem[M_I_BLEND] = i_ptc, i_ptcw, i_blend
        mem[M_BLOWER], mem[M_MDOT], mem[M_TV] = blower, mdot_air, T_v
        mem[M_HEATER_OK], mem[M_HEATER_BAT_OK], mem[M_CHILL_OK] = heater_ok, heater_bat_ok, chill_ok
        mem[M_Q_HEAT] = p_ptc + q_hc
        mem[M_CAB_OFF] = u_cab <= 0.0
        mem[M_RETRY_STEP] = -1.0
        mem[M_FAN_1], mem[M_FAN_2], mem[M_FAN_3] = fan_1, fan_2, fan_3
        mem[M_RAD_IN] = rad_in
        mem[M_HP_ON], mem[M_T_HP], mem[M_I_HP], mem[M_U_PS] = hp_on, t_hp, i_hp, i_ps
        mem[M_PS_LOW], mem[M_HP_UNTIL] = ps_low, hp_until
        if mem[M_BACKUP] > 0.0 and not backup:  # released, by whichever path (the pump's own stop included)
            t_release = t
        mem[M_BACKUP], mem[M_T_BACKUP], mem[M_P_PTCW], mem[M_T_RELEASE] = backup, t_backup, p_ptcw, t_release
        mem[M_TRIP_1], mem[M_TRIP_2], mem[M_TRIP_3] = trip_1, trip_2, trip_3
        mem[M_SRC_1], mem[M_SRC_2], mem[M_SRC_3] = src_1, src_2, src_3
        if speed > 0.0:
            mem[M_LAST_CIRCUIT] = circuit
        mem[M_T] = t + dt
        # Per-step record --------------------------------------------------------
        p_hvac = p_comp + p_ptc + p_ptcw + p_heater + (p_blower + p_fan + p_pump + p_pump_h) / eta_dc
        o[O_P_MOTOR_EL] = p_mel
        o[O_P_BATTERY] = volt * current
        o[O_P_HVAC] = p_hvac
        o[O_P_COMPRESSOR] = p_comp
        o[O_P_PTC] = p_ptc
        o[O_P_HEATER] = p_heater
        o[O_P_BLOWER] = p_blower
        o[O_P_FAN] = p_fan
        o[O_P_PUMP] = p_pump
        o[O_Q_EVAP] = q_evap
        o[O_Q_LATENT] = q_lat
        o[O_Q_CHILLER] = q_chill
        o[O_Q_COND] = q_cond
        o[O_W] = y[Y_W]
        o[O_W_FLUID] = y[Y_WFLUID]
        o[O_P_SUCTION] = y[Y_PS]
        o[O_P_DISCHARGE] = y[Y_PD]
        o[O_MDOT_REF] = y[Y_MDOT]
        o[O_Q_GEN] = q_gen
        o[O_EMF] = E
        o[O_V] = volt
        o[O_I] = current
        o[O_E_RC] = e_rc
        o[O_SPEED_CMD] = speed
        o[O_BLOWER] = blower
        o[O_U_PUMP] = u_pump
        o[O_MDOT_AIR] = mdot_air
        o[O_Q_HEATER] = p_heater
        o[O_Q_AIR_SOURCES] = q_air
        o[O_Q_SUN_INT] = q_sun_int
        o[O_T_SUPPLY] = T_v
        o[O_P_DEFICIT] = deficit
        o[O_REGEN] = 1.0 if regen else 0.0
        o[O_P_GRID] = p_grid
        o[O_T_EVAP_AIR] = T_ev_mean if mdot_air > 0.0 else np.nan
        o[O_T_VENT_TARGET] = T_vs
        o[O_T_EVAP_TARGET] = T_ev_t if cab_coil else np.nan
        o[O_RECIRC] = r
        o[O_G_IN] = g_in
        o[O_T_IN_SRC] = T_src
        o[O_W_IN_SRC] = w_src
        o[O_G_BC] = g_bc
        o[O_Q_EXT] = q_ext
        o[O_Q_HC] = q_hc
        o[O_P_PTCW] = p_ptcw
        o[O_P_PUMP_H] = p_pump_h
        o[O_BLEND] = beta
        o[O_T_H_TARGET] = T_H_t
        o[O_COMP_ON] = 1.0 if speed > 0.0 else 0.0
        o[O_CIRCUIT] = circuit
        o[O_P_AUX] = p_aux
        o[O_FAN] = u_fan
        o[O_V_FRONT] = v_front
        o[O_P_PUMP_E] = p_pump_e
        o[O_P_EDRIVE_AUX] = p_pump_e / eta_dc
        o[O_Q_DRIVE] = q_drive
        o[O_Q_DCDC] = q_dcdc
        o[O_Q_RAD] = q_rad
        o[O_T_AIR_RAD] = T_air_rad
        o[O_U_PUMP_E] = u_pump_e
        o[O_RAD_IN] = rad_in
        o[O_Q_WCC] = q_wcc
        o[O_Q_CH_E] = q_ch_e
        o[O_HP_CEILING] = u_ps
        modes[n] = mode
        flags[n] = flag
        n += 1
        if s1[S_SOC] < par[P_SOC_MIN]:
            mem[M_STOP] = STOP_SOC_MIN
            return n
    return n_steps
