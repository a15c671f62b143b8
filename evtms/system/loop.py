"""The system simulator's time loop: one compiled function over flat arrays.

Per step ``n`` (length ``dt_n`` [s]), as the project's system spec 2.6 says:

(a) controls from the states at ``t_n``: hysteresis flags, the mode (auto
    with a minimum hold, or forced), the blower, compressor and PTC PI
    controllers (parallel form, saturated to [0, 1], conditional
    integration: the integrator is frozen while its output is saturated in
    the direction of the error, so it cannot wind up at any step), heater
    relay and pump;
(b) the refrigerant loop: the steady cycle map's target ``y(u)``
    (:mod:`evtms.system.maps`, multilinear) or, with the compressor off,
    zero flows and equalised pressures; every output follows the same
    first-order lag ``tau`` exactly, ``y_f,n+1 = y + (y_f,n - y) e^(-dt/tau)``,
    and the step's sources are the interval means
    ``y + (y_f,n - y) (tau/dt)(1 - e^(-dt/tau))``: a linear filter common to
    every output keeps the map's closure ``Q_condenser = Q_evaporator +
    Q_chiller + W_fluid`` at every step;
(c) the battery: terminal power of motor, auxiliaries and HVAC (PTC and
    heater cut first above the voltage cap), current from the quadratic
    ``v i = P`` with the RC branch's exact interval mean, Joule heat, SOC;
(d) the thermal network by backward Euler with the sources of (b)-(c) held:
    battery and coolant as one 2 x 2 system; cabin air with the walls and
    the interior eliminated in closed form (each wall mass sees only the air
    and the ambient), so no matrix is factorised; the cabin humidity ratio
    likewise. Flows computed from the new temperatures close every node's
    ledger to round-off.

Everything is float64 scalars and arrays so that :func:`evtms._jit.jit`
compiles it (numba); with ``EVTMS_NO_NUMBA=1`` the same code runs as Python.
Parameters travel packed in one array (``P_*`` indices), per-step outputs in
one 2-D array (``O_*`` columns), states in another (``S_*`` columns).

References
----------
Astrom, K. J., Hagglund, T. (2006). Advanced PID Control. ISA, section 3.5
(integrator windup, conditional integration).
Alduchov, O. A., Eskridge, R. E. (1996). Improved Magnus form approximation
of saturation vapor pressure. J. Appl. Meteorol. 35, 601-609.
"""

from __future__ import annotations

import math

import numpy as np

from evtms._jit import jit
from evtms.system.maps import map_interp

# Modes (T section 4.6 order).
OFF, BH, BC, CC, CH, CH_BH, CH_BC, CC_BC = range(8)
MODE_NAMES = ("off", "BH", "BC", "CC", "CH", "CH+BH", "CH+BC", "CC+BC")

# Flag bits of the output's ``flags``.
F_POWER_LIMITED, F_REF_CLIPPED, F_SURROGATE_OOR, F_REGEN_CUT, F_FREEZE_CUTOFF, F_TRACTION_CUT, F_PHYSICS_FALLBACK = (
    1,
    2,
    4,
    8,
    16,
    32,
    64,
)
FLAG_NAMES = (
    "power_limited",
    "ref_clipped",
    "surrogate_out_of_range",
    "regen_cut",
    "freeze_cutoff",
    "traction_cut",
    "physics_fallback",
)

# Where the refrigerant loop's steady targets come from (``source``).
SRC_MAPS, SRC_HELD, SRC_SURROGATE = 0, 1, 2
# Map ids of ``held`` (and of the physics requests).
MAP_AC, MAP_CHILLER, MAP_ACCH = 0, 1, 2

# ``held``: the last refrigerant point the caller solved (SRC_HELD): map id, inputs, targets, fallback.
H_MAP, H_X, H_Y, H_FALLBACK = 0, 1, 7, 16
N_H = 17

# ``mem``: controller memory at the start of the step the loop stopped at (resumable runs).
(
    M_SET, M_MODE, M_T_MODE, M_BC, M_CRIT, M_BH, M_CC, M_CH, M_BLOWER_AT_MIN, M_I_BLOWER, M_I_COMP, M_I_PTC,
    M_BLOWER_WAS_ON, M_COMP_WAS_ON, M_PTC_WAS_ON, M_Q_PTC_PREV, M_T,
    N_M,
) = range(18)  # fmt: skip

# Map output slots (evtms.system.maps.MAP_OUTPUTS order).
Y_PS, Y_PD, Y_MDOT, Y_QEVAP, Y_QLAT, Y_QCH, Y_QCOND, Y_W, Y_WFLUID = range(9)
N_Y = 9

# Packed parameters.
(
    P_T_AMB, P_W_AMB, P_P_ATM, P_FORCED_MODE, P_AUX,
    P_NS, P_R_SCALE, P_R2, P_C2, P_VMIN, P_CAP_AS, P_SOC_MIN, P_SOC_MAX,
    P_C_BAT, P_G_BC, P_G_BA, P_C_COOL, P_HEATER_MAX, P_PUMP_REF, P_PUMP_NMAX,
    P_C_AIR, P_M_AIR, P_C_INT, P_G_INT, P_RECIRC, P_Q_OCC, P_MOIST, P_Q_SUN,
    P_BLOWER_FLOW, P_BLOWER_POWER, P_T_SET,
    P_BL_KP, P_BL_KI, P_CP_KP, P_CP_KI, P_PS_TARGET, P_CUT_LO, P_CUT_HI,
    P_PTC_KP, P_PTC_KI, P_PTC_TOUT, P_PTC_MAX, P_SPEED_MIN, P_BLOWER_MIN,
    P_FAN, P_FAN_POWER, P_DRIVE_EFF, P_TAU,
    P_BC_ON, P_BC_OFF, P_CRIT_ON, P_CRIT_OFF, P_BH_ON, P_BH_OFF, P_BH_AMB_MAX, P_DEADBAND,
    P_PUMP_IDLE, P_PUMP_BC, P_PUMP_CRIT, P_HOLD, P_COOLANT_MDOT_MAX,
    P_G_GLASS, P_G_DOORS, P_G_ROOF, P_C_GLASS, P_C_DOORS, P_C_ROOF,
    N_P,
) = range(68)  # fmt: skip

# States at the step boundaries.
(
    S_SOC, S_VRC, S_TB, S_TC, S_TA, S_TGLASS, S_TDOORS, S_TROOF, S_TINT, S_W,
    S_YF,
) = range(11)  # fmt: skip
N_S = S_YF + N_Y

# Per-step outputs (means over the step; commands as held over the step).
(
    O_P_MOTOR_EL, O_P_BATTERY, O_P_HVAC, O_P_COMPRESSOR, O_P_PTC, O_P_HEATER, O_P_BLOWER, O_P_FAN, O_P_PUMP,
    O_Q_EVAP, O_Q_LATENT, O_Q_CHILLER, O_Q_COND, O_W, O_W_FLUID, O_P_SUCTION, O_P_DISCHARGE, O_MDOT_REF,
    O_Q_GEN, O_EMF, O_V, O_I, O_E_RC, O_SPEED_CMD, O_BLOWER, O_U_PUMP, O_MDOT_AIR, O_Q_HEATER,
    O_Q_AIR_SOURCES, O_Q_SUN_INT, O_T_SUPPLY, O_P_DEFICIT, O_REGEN, O_P_GRID,
    N_O,
) = range(35)  # fmt: skip

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

_H_FG = 2.45e6  # latent heat of condensing water at cabin conditions [J/kg]
_CP_AIR = 1006.0  # dry air [J/(kg K)]
_R_AIR = 287.05  # [J/(kg K)]


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
def _pi(e, integral, kp, ki, dt):
    """Parallel PI saturated to [0, 1]; the integral advances unless the output is saturated in e's direction."""
    u = kp * e + integral
    out = min(max(u, 0.0), 1.0)
    if not ((u >= 1.0 and e > 0.0) or (u <= 0.0 and e < 0.0)):
        integral += ki * e * dt
    return out, integral


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
def run_loop(
    par, dts, p_motor_el, soc_ocv, cell_T, cell_ocv, cell_r0, sat_T, sat_p,
    ac_knots, ac_starts, ac_table, ch_knots, ch_starts, ch_table, acch_knots, acch_starts, acch_table,
    states, out, modes, flags, ext, start, source, mem, held, tol, net, net_index,
):  # fmt: skip
    """Run the loop from step ``start`` to ``dts.size``; returns the number of steps done (fewer when SOC hits
    its floor), or ``-(n + 1)`` when step ``n`` needs a refrigerant point solved (``source`` SRC_HELD).

    ``states`` (steps + 1, N_S) holds the initial state in row 0 and is filled
    row by row; ``out`` (steps, N_O), ``modes`` and ``flags`` (steps) per step.
    ``p_motor_el`` (steps, 3): the step's mean motor electrical power [W]
    with regeneration and with it cut, and 1 where the car is plugged in
    (preconditioning: the grid, not the battery, feeds auxiliaries and HVAC).

    ``source`` says where the refrigerant targets come from: SRC_MAPS the
    cycle maps; SRC_HELD the caller's solved point in ``held``, reused while
    every map input stays within ``tol`` of the point's inputs (else the loop
    returns a request with the inputs in ``held``; the caller solves, fills
    ``held[H_Y:]`` and calls again from that step); SRC_SURROGATE the mode
    models packed in ``net`` (``net_index[mode, head]``: offset, -1 none)
    replace the refrigerant loop and the thermal network. ``mem`` (N_M)
    carries the controllers' memory between calls.
    """
    T_amb = par[P_T_AMB]
    w_amb = par[P_W_AMB]
    p_atm = par[P_P_ATM]
    forced = int(par[P_FORCED_MODE])
    recirc = par[P_RECIRC]
    y = np.zeros(N_Y)
    x = np.zeros(6)
    g_w = np.array([par[P_G_GLASS], par[P_G_DOORS], par[P_G_ROOF]])
    c_w = np.array([par[P_C_GLASS], par[P_C_DOORS], par[P_C_ROOF]])
    alphas = np.empty(3)  # per step: wall temperature T_w' = alpha_w + beta_w T_air'
    betas = np.empty(3)
    # Surrogate features, outputs and scratch.
    feat = np.zeros(len(SURROGATE_STATES) + 9)
    pred = np.zeros(len(SURROGATE_STATES))
    h0 = np.empty(_MLP_WIDTH)
    h1 = np.empty(_MLP_WIDTH)
    # Controller and mode memory.
    if mem[M_SET] > 0.0:
        mode = int(mem[M_MODE])
        t_mode = mem[M_T_MODE]
        bc, crit, bh, cc, ch = mem[M_BC] > 0.0, mem[M_CRIT] > 0.0, mem[M_BH] > 0.0, mem[M_CC] > 0.0, mem[M_CH] > 0.0
        blower_at_min = mem[M_BLOWER_AT_MIN] > 0.0
        i_blower, i_comp, i_ptc = mem[M_I_BLOWER], mem[M_I_COMP], mem[M_I_PTC]
        blower_was_on, comp_was_on = mem[M_BLOWER_WAS_ON] > 0.0, mem[M_COMP_WAS_ON] > 0.0
        ptc_was_on = mem[M_PTC_WAS_ON] > 0.0
        q_ptc_prev = mem[M_Q_PTC_PREV]
        t = mem[M_T]
    else:
        mode = OFF if forced < 0 else forced
        t_mode = -1e300
        bc = crit = bh = cc = ch = False
        blower_at_min = True
        i_blower = i_comp = i_ptc = 0.0
        blower_was_on = comp_was_on = ptc_was_on = False
        q_ptc_prev = 0.0
        t = 0.0
    n_steps = dts.size
    for n in range(start, n_steps):
        dt = dts[n]
        # The step's starting memory: a request returns here, and the step reruns from it.
        mem[M_SET] = 1.0
        mem[M_MODE] = mode
        mem[M_T_MODE] = t_mode
        mem[M_BC], mem[M_CRIT], mem[M_BH], mem[M_CC], mem[M_CH] = bc, crit, bh, cc, ch
        mem[M_BLOWER_AT_MIN] = blower_at_min
        mem[M_I_BLOWER], mem[M_I_COMP], mem[M_I_PTC] = i_blower, i_comp, i_ptc
        mem[M_BLOWER_WAS_ON], mem[M_COMP_WAS_ON], mem[M_PTC_WAS_ON] = blower_was_on, comp_was_on, ptc_was_on
        mem[M_Q_PTC_PREV] = q_ptc_prev
        mem[M_T] = t
        s0 = states[n]
        soc, v_rc, Tb, Tc, Ta = s0[S_SOC], s0[S_VRC], s0[S_TB], s0[S_TC], s0[S_TA]
        w_cab = s0[S_W]
        flag = 0
        # (a) controls ------------------------------------------------------------
        if Tb > par[P_BC_ON]:
            bc = True
        elif Tb < par[P_BC_OFF]:
            bc = False
        if Tb > par[P_CRIT_ON]:
            crit = True
        elif Tb < par[P_CRIT_OFF]:
            crit = False
        if Tc < par[P_BH_ON] and T_amb <= par[P_BH_AMB_MAX]:
            bh = True
        elif Tc > par[P_BH_OFF]:
            bh = False
        T_set, band = par[P_T_SET], par[P_DEADBAND]
        # A cabin request ends past the far side of the band only once the blower PI has
        # wound down to its minimum: ending it earlier (the integrator still high after a
        # pull-down) stops the blower for the mode hold while sun and walls reheat the
        # 3.4 kJ/K air by several kelvin a minute, a limit cycle of +-7 K (hot soak, 40 degC).
        if T_amb > T_set and Ta > T_set + band:
            cc = True
        elif Ta < T_set - band and (blower_at_min or not cc):
            cc = False
        if T_amb < T_set and Ta < T_set - band:
            ch = True
        elif Ta > T_set + band and (blower_at_min or not ch):
            ch = False
        if forced >= 0:
            mode = forced
        else:
            want = _pick_mode(bc, crit, bh, cc, ch)
            if want != mode and t - t_mode >= par[P_HOLD]:
                mode = want
                t_mode = t
        cab_cool = mode == CC or mode == CC_BC
        cab_heat = mode == CH or mode == CH_BH or mode == CH_BC
        chill = mode == BC or mode == CH_BC or mode == CC_BC
        heat_bat = mode == BH or mode == CH_BH
        T_mix = recirc * Ta + (1.0 - recirc) * T_amb
        w_mix = recirc * w_cab + (1.0 - recirc) * w_amb
        rho_mix = p_atm / (_R_AIR * T_mix)
        # Blower.
        blower = 0.0
        if cab_cool or cab_heat:
            if not blower_was_on:
                i_blower = 0.0
            e = (Ta - T_set) if cab_cool else (T_set - Ta)
            u, i_blower = _pi(e, i_blower, par[P_BL_KP], par[P_BL_KI], dt)
            blower = max(u, par[P_BLOWER_MIN])
            blower_at_min = u <= par[P_BLOWER_MIN]
        else:
            blower_at_min = True
        blower_was_on = blower > 0.0
        mdot_air = blower * par[P_BLOWER_FLOW] * rho_mix
        # Compressor: PI on the filtered suction pressure, freeze cutoff, speed floor.
        speed = 0.0
        p_suction_f = s0[S_YF + Y_PS]
        if cab_cool or chill:
            cut_lo, cut_hi = par[P_CUT_LO], par[P_CUT_HI]
            cutoff = min(max((p_suction_f - cut_lo) / (cut_hi - cut_lo), 0.0), 1.0)
            if not comp_was_on:
                i_comp = 0.0
            e = (p_suction_f - par[P_PS_TARGET]) * 1e-6
            u, i_comp = _pi(e, i_comp, par[P_CP_KP], par[P_CP_KI], dt)
            if cutoff > 0.0:
                speed = max(u * cutoff, par[P_SPEED_MIN])
            else:
                flag |= F_FREEZE_CUTOFF
            comp_was_on = True
        else:
            comp_was_on = False
        # PTC: PI on its outlet air temperature; off when the ambient is warmer than the setpoint.
        p_ptc = 0.0
        if cab_heat and T_amb <= T_set and mdot_air > 0.0:
            if not ptc_was_on:
                i_ptc = 0.0
            T_out = T_mix + q_ptc_prev / (mdot_air * _CP_AIR)
            u, i_ptc = _pi(par[P_PTC_TOUT] - T_out, i_ptc, par[P_PTC_KP], par[P_PTC_KI], dt)
            p_ptc = u * par[P_PTC_MAX]
            ptc_was_on = True
        else:
            ptc_was_on = False
        p_heater = par[P_HEATER_MAX] if heat_bat else 0.0
        u_pump = 0.0
        if crit:
            u_pump = par[P_PUMP_CRIT]
        elif chill:
            u_pump = par[P_PUMP_BC]
        elif mode != OFF:
            u_pump = par[P_PUMP_IDLE]
        # (b) refrigerant target and filter ---------------------------------------
        s1 = states[n + 1]
        o = out[n]
        surrogate = source == SRC_SURROGATE
        n_z = len(SURROGATE_STATES)
        if surrogate:
            # The mode model replaces the loop's refrigerant and thermal network: no heat flows, no filter.
            for k in range(N_Y):
                y[k] = np.nan
                s1[S_YF + k] = np.nan
            for k in range(n_z):
                feat[k] = s0[SURROGATE_STATES[k]]
            feat[n_z], feat[n_z + 1], feat[n_z + 2] = speed, blower, u_pump
            feat[n_z + 3], feat[n_z + 4], feat[n_z + 5], feat[n_z + 6] = p_ptc, p_heater, T_amb, w_amb
            feat[n_z + 7] = par[P_Q_SUN]
            p_comp = 0.0
            at = net_index[mode, 0]
            if at < 0:
                flag |= F_SURROGATE_OOR
            else:
                if mlp_eval(net, at, feat, pred, h0, h1):
                    flag |= F_SURROGATE_OOR
                if speed > 0.0:
                    p_comp = max(pred[0], 0.0)
        else:
            for k in range(N_Y):
                y[k] = 0.0
            if speed > 0.0:
                clipped = 0
                if mode == CC:
                    map_id, nx = MAP_AC, 5
                    rh_mix = min(max(relative_humidity(T_mix, w_mix, p_atm), 0.0), 1.0)
                    x[0], x[1], x[2], x[3], x[4] = speed, blower, T_amb, T_mix, rh_mix
                elif mode == CC_BC:
                    map_id, nx = MAP_ACCH, 6
                    x[0], x[1], x[2], x[3], x[4], x[5] = speed, blower, u_pump, T_amb, T_mix, Tc
                else:
                    map_id, nx = MAP_CHILLER, 4
                    x[0], x[1], x[2], x[3] = speed, u_pump, T_amb, Tc
                if source == SRC_HELD:
                    # Physics: reuse the caller's solved point while every input stays within its tolerance.
                    fresh = held[H_MAP] == map_id
                    for k in range(nx):
                        if abs(x[k] - held[H_X + k]) > tol[map_id, k]:
                            fresh = False
                    if not fresh:
                        held[H_MAP] = map_id
                        for k in range(6):
                            held[H_X + k] = x[k] if k < nx else np.nan
                        return -(n + 1)
                    for k in range(N_Y):
                        y[k] = held[H_Y + k]
                    if held[H_FALLBACK] > 0.0:
                        flag |= F_PHYSICS_FALLBACK
                elif mode == CC:
                    clipped = map_interp(ac_knots, ac_starts, ac_table, x[:5], y)
                elif mode == CC_BC:
                    clipped = map_interp(acch_knots, acch_starts, acch_table, x, y)
                else:
                    clipped = map_interp(ch_knots, ch_starts, ch_table, x[:4], y)
                if clipped:
                    flag |= F_REF_CLIPPED
            else:
                T_ref = Tc if (mode == BC or mode == CH_BC or mode == BH) else T_mix
                p_eq = np.interp(T_ref, sat_T, sat_p)
                y[Y_PS] = p_eq
                y[Y_PD] = p_eq
            decay = math.exp(-dt / par[P_TAU])
            mean_f = par[P_TAU] / dt * (1.0 - decay)
            for k in range(N_Y):
                yf = s0[S_YF + k]
                s1[S_YF + k] = y[k] + (yf - y[k]) * decay
                y[k] = y[k] + (yf - y[k]) * mean_f  # from here on: the interval mean
            p_comp = y[Y_W] / par[P_DRIVE_EFF]
        q_evap, q_lat, q_chill = y[Y_QEVAP], y[Y_QLAT], y[Y_QCH]
        p_fan = par[P_FAN_POWER] if speed > 0.0 else 0.0
        p_blower = par[P_BLOWER_POWER] * blower**3
        p_pump = par[P_PUMP_REF] * (u_pump * par[P_PUMP_NMAX] / 1000.0) ** 3
        # (c) battery ---------------------------------------------------------------
        regen = soc < par[P_SOC_MAX]
        if not regen:
            flag |= F_REGEN_CUT
        p_mel = p_motor_el[n, 0] if regen else p_motor_el[n, 1]
        ns = par[P_NS]
        E = ns * np.interp(soc, soc_ocv, cell_ocv)
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
        p_loads = par[P_AUX] + p_comp + p_ptc + p_heater + p_blower + p_fan + p_pump
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
            if at < 0:
                flag |= F_SURROGATE_OOR
            q_air = np.nan
            q_sun_int = np.nan
            # Filtered suction pressure and heat flows: the step's mean of the model's states.
            for k in (Y_PS, Y_QEVAP, Y_QCH):
                y[k] = 0.5 * (s0[S_YF + k] + s1[S_YF + k])
            q_evap, q_chill = y[Y_QEVAP], y[Y_QCH]
        else:
            cb, cc_ = par[P_C_BAT] / dt, par[P_C_COOL] / dt
            gbc, gba = par[P_G_BC], par[P_G_BA]
            a11 = cb + gbc + gba
            a22 = cc_ + gbc
            # Solved for the changes (not the temperatures): smaller numbers, ledgers closer to round-off.
            r1 = q_gen - gbc * (Tb - Tc) - gba * (Tb - T_amb)
            r2_ = gbc * (Tb - Tc) + p_heater - q_chill
            det = a11 * a22 - gbc * gbc
            Tb_new = Tb + (r1 * a22 + gbc * r2_) / det
            Tc_new = Tc + (a11 * r2_ + gbc * r1) / det
            s1[S_TB] = Tb_new
            s1[S_TC] = Tc_new
            # Cabin: wall w and interior eliminated, T_w' = alpha_w + beta_w T_air'.
            q_sun = par[P_Q_SUN]
            c_int = par[P_C_INT]
            q_sun_int = q_sun if c_int > 0.0 else 0.0
            q_air = par[P_Q_OCC] + (q_sun - q_sun_int) + p_ptc - (q_evap - q_lat)
            g_fresh = mdot_air * _CP_AIR * (1.0 - recirc)
            lhs = par[P_C_AIR] / dt + g_fresh
            rhs = par[P_C_AIR] / dt * Ta + g_fresh * T_amb + q_air
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
            # Cabin humidity ratio: fresh air, occupants, condensate.
            m_air = par[P_M_AIR] / dt
            g_w_fresh = mdot_air * (1.0 - recirc)
            w_new = (m_air * w_cab + g_w_fresh * w_amb + par[P_MOIST] - q_lat / _H_FG) / (m_air + g_w_fresh)
            s1[S_W] = max(w_new, 0.0)
        # Supply air (diagnostic), no colder than the evaporating refrigerant.
        T_supply = np.nan
        if mdot_air > 0.0 and not surrogate:
            T_supply = T_mix + (p_ptc - (q_evap - q_lat)) / (mdot_air * _CP_AIR)
            T_floor = np.interp(y[Y_PS], sat_p, sat_T)
            if speed > 0.0 and T_supply < T_floor:
                T_supply = T_floor
        q_ptc_prev = p_ptc
        # Per-step record --------------------------------------------------------
        p_hvac = p_comp + p_ptc + p_heater + p_blower + p_fan + p_pump
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
        o[O_Q_COND] = y[Y_QCOND]
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
        o[O_T_SUPPLY] = T_supply
        o[O_P_DEFICIT] = deficit
        o[O_REGEN] = 1.0 if regen else 0.0
        o[O_P_GRID] = p_grid
        modes[n] = mode
        flags[n] = flag
        t += dt
        if s1[S_SOC] < par[P_SOC_MIN]:
            return n + 1
    return n_steps
