"""A model-predictive climate controller: the supervisory layer above the climate control's local loops.

Every ``step`` seconds :class:`CabinMpc` solves, over a receding horizon of
``horizon`` seconds, for the blower command, the sensible cooling and
heating duties and (in the cooling season) the chiller's duty that hold the
cabin air within ``comfort_band`` of its setpoint and the battery below its
cooling relay's switch-on for the least electrical energy, and hands the
first step's vent-air target, blower and battery-cooling request to the
plant (:mod:`evtms.system.controllers`). The plant is always the full
simulator: the relays, frost cutoffs and actuator ranges below those set
points are the rules' own.

Prediction model, per horizon step ``k`` of length ``h`` [s], backward Euler
(stable at any ``h``):

- the cabin as the loop has it: air ``C_a``, interior ``C_i`` behind
  ``G_i``, three walls ``C_w`` each with ``G_w`` to the air and to the
  ambient (:mod:`evtms.system.loop`, section (d))::

      C_a dT_a/dt = b G_v (1 - r)(T_amb - T_a) + q_h - q_c + Q_occ + Q_sun,air
                    + sum_w G_w (T_w - T_a) + G_i (T_i - T_a)
      C_w dT_w/dt = G_w (T_a - T_w) + G_w (T_amb - T_w)
      C_i dT_i/dt = G_i (T_a - T_i) + Q_sun,int

  with ``G_v = V_blower rho c_p`` the blower's full flow [W/K], ``b`` the
  blower command and ``r`` the recirculated share (the rules' current);
- the compressor's power from the cycle maps as a smooth interpolant, fitted
  afresh at every decision by least squares to the ``ac`` map at the
  current inlet air, ambient and condenser air::

      W = q_c (a_1 + a_4 x_f,k + a_2 q_c + a_3 b)

  where ``q_c`` is the evaporator's sensible duty [kW] and ``x_f,k`` the
  condenser's front-air fraction from the previewed speed (ram air), so the
  speed preview moves cooling to where the condenser runs cooler;
- heating at the heater's efficiency (1 for the PTCs, the ``hp`` map's COP
  for the heat pump); the blower ``P_b b^3``;
- the battery and its coolant as the loop has them (section (d))::

      C_b dT_b/dt = R_eff P_k^2 - G_bc (T_b - T_c) - G_ba (T_b - T_amb)
      C_c dT_c/dt = G_bc (T_b - T_c) + P_heater - q_ch

  with ``P_k`` the previewed motor power plus the other loads as they are,
  ``R_eff`` identified on the last two minutes (Joule heat over squared
  terminal power), ``G_bc`` the plate at the pump's command, and the
  chiller's power ``W_ch = q_ch (c_1 + c_2 q_ch)`` fitted to the
  ``chiller`` map. The plant's chiller runs at its own suction PI, not at a
  duty: it is asked for when the plan's first step wants a quarter of its
  capacity and released below a twentieth, each held a minute.

Objective [kJ]: sum_k h (W_k + W_ch,k + q_h,k / eta + P_b b_k^3) + w_c (h/60)
(s_k^2 + s_b,k^2) + w_t (h/60) (T_a,k - T_set)^2 + w_s (Delta u_k)^2, with
``s_k >= |T_a,k - T_set| - comfort_band`` (beyond the band, squared),
``s_b,k >= T_b,k - (T_bc,on - 0.5 K)``, a weak pull to the setpoint and
smooth commands. Constraints: blower within its range,
the supply air between the evaporator's lowest setting and the vent's
highest (``q_c <= b G_v (T_in - T_evap,min)``, ``q_h <= b G_v (T_vent,max
- T_in)``), duties within the map's and the heater's capacity.

Solved by IPOPT (Wachter and Biegler 2006) through CasADi (Andersson et al.
2019), warm-started from the previous solution shifted by one step; a
solve that fails or exceeds ``time_budget`` hands the period to the rules.

References
----------
Rawlings, J. B., Mayne, D. Q., Diehl, M. (2017). Model Predictive Control:
Theory, Computation, and Design, 2nd ed. Nob Hill: ch. 1-2 (receding
horizon, soft constraints), ch. 8 (multiple shooting, warm starts).
Wachter, A., Biegler, L. T. (2006). On the implementation of an
interior-point filter line-search algorithm for large-scale nonlinear
programming. Math. Program. 106, 25-57.
Andersson, J. A. E. et al. (2019). CasADi: a software framework for
nonlinear optimization and optimal control. Math. Prog. Comp. 11, 1-36.
World Electric Vehicle Journal 15 (2024) 224 (RWTH Aachen and FEV:
predictive cabin conditioning against a rule-based strategy in the loop).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from evtms.errors import EvtmsInputError
from evtms.system import loop as L  # noqa: N812 - the loop's index constants
from evtms.system.controllers import ControlContext, Decision

#: Preview of the speed trace: the trace itself, none (today's speed held), or the trace with noise.
PREVIEWS = ("perfect", "none", "noisy")
_CP = L._CP_AIR
_R = L._R_AIR


@dataclass(frozen=True)
class MpcOptions:
    """Settings of :class:`CabinMpc`.

    Attributes
    ----------
    horizon : float
        Prediction horizon [s] (30 to 1800).
    step : float
        Control and prediction step [s] (1 to 60; at most the horizon).
    preview : str
        ``perfect``, ``none`` or ``noisy`` (:data:`PREVIEWS`).
    noise : float
        Relative standard deviation of the ``noisy`` preview's speed [1].
    comfort_band : float or None
        Half width [K] of the band the cabin air is held in; None: the
        climate's ``cabin_band``.
    w_comfort : float
        Weight [kJ / (K^2 min)] on the squared excursion beyond the band.
    w_track : float
        Weight [kJ / (K^2 min)] pulling the air to the setpoint inside the band. At 30 the MPC holds the cabin
        closer than the rules do (RMS 0.1-0.3 K against 0.25-0.8 K on WLTC and UDDS at -10, 30 and 40 degC);
        at 2 it rides the band's cheap edge (0.3-0.55 K) for 1-3 % more saving.
    w_smooth : float
        Weight [kJ] on squared command changes (blower [1], duties [kW]).
    time_budget : float
        Wall time [s] a solve may take before the rules run its period.
    seed : int
        Seed of the ``noisy`` preview.
    """

    horizon: float = 180.0
    step: float = 10.0
    preview: str = "perfect"
    noise: float = 0.3
    comfort_band: float | None = None
    w_comfort: float = 200.0
    w_track: float = 30.0
    w_smooth: float = 2.0
    time_budget: float = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        checks = (
            ("horizon", self.horizon, 30.0, 1800.0),
            ("step", self.step, 1.0, 60.0),
            ("noise", self.noise, 0.0, 2.0),
            ("w_comfort", self.w_comfort, 0.0, 1e6),
            ("w_track", self.w_track, 0.0, 1e6),
            ("w_smooth", self.w_smooth, 0.0, 1e6),
            ("time_budget", self.time_budget, 1e-3, 60.0),
        )
        for name, value, lo, hi in checks:
            if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
                raise EvtmsInputError(f"MPC {name} {value!r} is not allowed; allowed: {lo:g} to {hi:g}")
        if self.step > self.horizon:
            raise EvtmsInputError(f"MPC step {self.step:g} s is longer than its horizon {self.horizon:g} s")
        if self.preview not in PREVIEWS:
            raise EvtmsInputError(f"MPC preview {self.preview!r} is not allowed; allowed: {', '.join(PREVIEWS)}")
        band = self.comfort_band
        if band is not None and not (math.isfinite(band) and 0.0 <= band <= 5.0):
            raise EvtmsInputError(f"MPC comfort_band {band!r} K is not allowed; allowed: 0 to 5")

    @property
    def steps(self) -> int:
        """Horizon steps."""
        return max(1, round(self.horizon / self.step))


def casadi_module():
    """The optional ``casadi`` package, or one line saying how to install it."""
    try:
        import casadi
    except ImportError:  # the optional extra
        raise EvtmsInputError(
            "controller mpc needs the optional extra 'mpc' (CasADi with IPOPT); allowed: install it with "
            "pip install 'evtms[mpc]', or use controller rules"
        ) from None
    return casadi


class _Layout:
    """Named slices of one flat vector (the program's parameters): declared once, read by name."""

    def __init__(self, sizes: dict[str, int]) -> None:
        self.slices, at = {}, 0
        for name, size in sizes.items():
            self.slices[name] = slice(at, at + size)
            at += size
        self.size = at

    def split(self, vector) -> dict:
        return {k: (vector[s] if s.stop - s.start > 1 else vector[s.start]) for k, s in self.slices.items()}

    def pack(self, values: dict) -> np.ndarray:
        out = np.empty(self.size)
        for k, s in self.slices.items():
            out[s] = values[k]
        return out


#: Rows of a horizon step's commands and slacks.
_COMMANDS = ("blower", "q_cool", "q_heat", "q_chill")  # [1], [kW], [kW], [kW]
_N_U = len(_COMMANDS) + 2  # and the cabin's and the battery's slack [K]
#: Prediction states: cabin air, interior, three walls, battery, its coolant [K], and the heat the heater
#: delivers to the air [kW] (behind the heater-core loop's lag where the heater heats coolant).
_STATES = ("T_air", "T_int", "T_glass", "T_doors", "T_roof", "T_battery", "T_coolant", "q_heat_delivered")
_STATE_COLUMNS = [L.S_TA, L.S_TINT, L.S_TGLASS, L.S_TDOORS, L.S_TROOF, L.S_TB, L.S_TC]
_N_X = len(_STATES)
_X_LOW = np.array([150.0] * len(_STATE_COLUMNS) + [-np.inf])  # the states' bounds [K], [kW]
_X_HIGH = np.array([450.0] * len(_STATE_COLUMNS) + [np.inf])


class CabinMpc:
    """Receding-horizon cabin (and, in the cooling season, battery) controller; the module docstring has the
    model and the problem.

    Parameters
    ----------
    options : MpcOptions, optional
        Horizon, step, preview, weights and time budget.
    """

    name = "mpc"

    def __init__(self, options: MpcOptions | None = None) -> None:
        self.options = options or MpcOptions()
        self.period = self.options.step
        self._ca = casadi_module()
        self._solver = None
        self._warm: dict | None = None

    # -- set-up ---------------------------------------------------------------------------------------------
    def start(self, context: ControlContext) -> None:
        """Take the run's parameters and preview, and build the solver once."""
        self.ctx = context
        par = context.par
        self.T_set = float(par[L.P_T_SET])
        band = self.options.comfort_band
        self.band = float(par[L.P_BAND]) if band is None else float(band)
        # The battery's band: below its cooling relay's switch-on, with a margin the relay never reaches.
        self.T_battery_max = float(par[L.P_BC_ON]) - 0.5
        self.caps = np.array(
            [par[k] for k in (L.P_C_AIR, L.P_C_INT, L.P_C_GLASS, L.P_C_DOORS, L.P_C_ROOF, L.P_C_BAT, L.P_C_COOL)]
        )
        self.g_walls = np.array([par[L.P_G_GLASS], par[L.P_G_DOORS], par[L.P_G_ROOF]])
        q_sun = float(par[L.P_Q_SUN])
        self.q_sun_int = q_sun if par[L.P_C_INT] > 0.0 else 0.0
        self.q_sun_air = q_sun - self.q_sun_int
        self.g_plate = self._plate_conductance()
        self.speed, self.motor_power = self._preview(context)
        self._warm = None
        self._chilling, self._chill_since = False, -math.inf
        self._build()

    def _plate_conductance(self) -> float:
        """Pack-to-coolant conductance [W/K] with the pump at its battery-cooling command (the loop's)."""
        par = self.ctx.par
        if par[L.P_G_BC_FIXED] >= 0.0:
            return float(par[L.P_G_BC_FIXED])
        args = (par[L.P_PLATE_RE1], par[L.P_PLATE_PR], par[L.P_PLATE_DL], par[L.P_PLATE_KA], par[L.P_G_CP])
        return float(L.plate_conductance(par[L.P_PUMP_BC], *args))

    def _preview(self, context: ControlContext) -> tuple[np.ndarray, np.ndarray]:
        """The speed [m/s] and motor power [W] the controller sees ahead: the trace's, or with the ``noisy``
        preview each times ``1 + noise e`` (e standard normal, one draw a step, the same for both)."""
        speed = np.asarray(context.speed, float)
        motor = np.asarray(context.motor_power, float)
        if self.options.preview == "noisy":
            factor = 1.0 + self.options.noise * np.random.default_rng(self.options.seed).standard_normal(speed.size)
            speed, motor = np.maximum(speed * factor, 0.0), motor * factor
        return speed, motor

    def _build(self) -> None:
        ca = self._ca
        o, N = self.options, self.options.steps
        h = o.step
        U = ca.SX.sym("U", _N_U, N)
        X = ca.SX.sym("X", _N_X, N)  # states at the ends of the steps [K]
        self._layout = _Layout(
            {
                "x0": _N_X, "T_amb": 1, "q_air": 1, "q_int": 1, "r": 1, "g_v": 1, "t_ev_min": 1, "t_v_max": 1,
                "qc_max": 1, "qh_max": 1, "qch_max": 1, "eta": 1, "a1": N, "a2": 1, "a3": 1, "p_blower": 1,
                "c1": 1, "c2": 1, "q_gen": N, "u_last": len(_COMMANDS), "cooling": 1, "t_ev_max": 1,
                "cool_season": 1, "g_bc": 1, "p_heater": 1, "tau_heat": 1,
            }
        )  # fmt: skip
        P = ca.SX.sym("P", self._layout.size)
        q = self._layout.split(P)
        C = self.caps / 1e3  # [kJ/K]
        G = self.g_walls / 1e3  # [kW/K]
        par = self.ctx.par
        g_i, g_ba, g_bc = float(par[L.P_G_INT]) / 1e3, float(par[L.P_G_BA]) / 1e3, q["g_bc"]
        T_amb, r, g_v = q["T_amb"], q["r"], q["g_v"]
        J = 0.0
        g, lbg, ubg = [], [], []

        def at_most(expr) -> None:  # expr <= 0
            g.append(expr)
            lbg.append(-ca.inf)
            ubg.append(0.0)

        x_prev, u_prev = q["x0"], q["u_last"]
        for k in range(N):
            b, qc, qh, qch, s, s_b = (U[i, k] for i in range(_N_U))
            x = X[:, k]
            Ta, Ti, walls, Tb, Tc, q_del = x[0], x[1], x[2:5], x[5], x[6], x[7]
            f_air = b * g_v * (1.0 - r) * (T_amb - Ta) + q_del - qc + q["q_air"] + g_i * (Ti - Ta)
            for w in range(3):
                f_air += G[w] * (walls[w] - Ta)
            residuals = [
                C[0] * (Ta - x_prev[0]) - h * f_air,
                C[1] * (Ti - x_prev[1]) - h * (g_i * (Ta - Ti) + q["q_int"]),
                *(C[2 + w] * (walls[w] - x_prev[2 + w]) - h * G[w] * (Ta + T_amb - 2.0 * walls[w]) for w in range(3)),
                C[5] * (Tb - x_prev[5]) - h * (q["q_gen"][k] - g_bc * (Tb - Tc) - g_ba * (Tb - T_amb)),
                C[6] * (Tc - x_prev[6]) - h * (g_bc * (Tb - Tc) + q["p_heater"] - qch),
                q["tau_heat"] * (q_del - x_prev[7]) - h * (qh - q_del),
            ]
            g += residuals
            lbg += [0.0] * _N_X
            ubg += [0.0] * _N_X
            # Supply air between the evaporator's lowest setting and the vent's highest, at the step's inlet (the
            # cooling limit only in the cooling season: cold inlet air below the evaporator's lowest setting would
            # otherwise ask for negative cooling).
            T_in = r * x_prev[0] + (1.0 - r) * T_amb
            at_most(qc - q["cool_season"] * b * g_v * (T_in - q["t_ev_min"]))
            at_most(qh - b * g_v * (q["t_v_max"] - T_in))
            # Cooling: the evaporator air at most its highest setting, as the rules hold it (the coil keeps
            # drying the air, and the compressor's minimum speed is not asked for less than it gives).
            at_most(q["cooling"] * (b * g_v * (T_in - q["t_ev_max"]) - qc))
            at_most(qc - q["qc_max"])
            at_most(qh - q["qh_max"])
            at_most(qch - q["qch_max"])
            at_most(Ta - self.T_set - self.band - s)  # the slacks: beyond the comfort band, above the battery's
            at_most(self.T_set - self.band - Ta - s)
            at_most(Tb - self.T_battery_max - s_b)
            power = (
                qc * (q["a1"][k] + q["a2"] * qc + q["a3"] * b)
                + qch * (q["c1"] + q["c2"] * qch)
                + qh / q["eta"]
                + q["p_blower"] * b**3
            )  # [kW]
            J += h * power + h / 60.0 * (o.w_comfort * (s**2 + s_b**2) + o.w_track * (Ta - self.T_set) ** 2)
            J += o.w_smooth * ca.sumsqr(U[: len(_COMMANDS), k] - u_prev)
            x_prev, u_prev = x, U[: len(_COMMANDS), k]
        nlp = {"x": ca.vertcat(ca.vec(U), ca.vec(X)), "p": P, "f": J, "g": ca.vertcat(*g)}
        opts = {
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "print_time": False,
            "ipopt.max_iter": 200,
            "ipopt.tol": 1e-6,
            "ipopt.acceptable_tol": 1e-4,
            "ipopt.max_wall_time": o.time_budget,
            "ipopt.warm_start_init_point": "yes",
            "ipopt.mu_init": 1e-2,
        }
        self._solver = ca.nlpsol("cabin_mpc", "ipopt", nlp, opts)
        self._lbg, self._ubg = np.array(lbg), np.array(ubg)
        self._n_u = _N_U * N

    # -- decisions ------------------------------------------------------------------------------------------
    def decide(self, n: int, state: np.ndarray, history: np.ndarray) -> Decision:
        """The set points for the period starting at step ``n`` (``history``: the loop's outputs before it)."""
        wall0 = time.perf_counter()
        N = self.options.steps
        x0 = self._initial_state(state, history)
        if self.ctx.key_off[n]:  # nothing to decide: no climate with the key off
            return Decision(math.nan, math.nan, math.nan, True)
        if not np.all(np.isfinite(x0)):  # a state the model cannot start from: the rules run, flagged
            return Decision(math.nan, math.nan, time.perf_counter() - wall0, False)
        problem = self._problem(n, state, history)
        if problem["regime"] == "rules":  # outside the model's regime: the rules' cabin loop, not flagged
            self._warm = None
            return Decision(math.nan, math.nan, math.nan, True)
        guess = self._guess(x0, problem["b_min"])
        args = {"x0": guess["x"], "p": problem["p"], "lbx": problem["lbx"], "ubx": problem["ubx"]}
        args.update(lbg=self._lbg, ubg=self._ubg)
        if "lam_x" in guess:
            args["lam_x0"], args["lam_g0"] = guess["lam_x"], guess["lam_g"]
        sol = self._solver(**args)
        status = self._solver.stats()["return_status"]
        elapsed = time.perf_counter() - wall0
        ok = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level") and elapsed <= self.options.time_budget
        if not ok:
            self._warm = None
            return Decision(math.nan, math.nan, elapsed, False)
        w = np.asarray(sol["x"]).ravel()
        U = w[: self._n_u].reshape(N, _N_U)
        self._warm = {
            "w": w,
            "lam_x": np.asarray(sol["lam_x"]).ravel(),
            "lam_g": np.asarray(sol["lam_g"]).ravel(),
            "u0": U[0, : len(_COMMANDS)].copy(),
        }
        b, qc, qh, qch = U[0, : len(_COMMANDS)]
        # The interior point ends within its tolerance of a bound, on either side: the commands are clipped to
        # the actuators' ranges (a blower 1e-8 under its minimum is not one the car has).
        par = self.ctx.par
        b = min(max(float(b), problem["b_min"]), 1.0)
        T_vent = problem["T_in"] + (qh - qc) / (b * problem["g_v"])
        T_vent = min(max(float(T_vent), float(par[L.P_TV_MIN])), float(par[L.P_TV_MAX]))
        chill = self._chill_request(n, float(qch), problem["qch_max"]) if problem["cooling"] else math.nan
        return Decision(T_vent, b, time.perf_counter() - wall0, True, chill)

    def _chill_request(self, n: int, q_chill: float, q_max: float) -> float:
        """The battery-cooling request from the planned chiller duty: on above a quarter of its capacity, off
        below a twentieth, each held at least a minute (the chiller runs at its own suction PI, not at a duty).
        With no chiller to plan with (no map, or none of its points cools) the relay decides (NaN)."""
        if not q_max > 0.0:
            self._chilling, self._chill_since = False, -math.inf
            return math.nan
        t = float(self.ctx.edges[n])
        held = t - self._chill_since >= 60.0
        want = q_chill >= 0.25 * q_max if not self._chilling else q_chill > 0.05 * q_max
        if want != self._chilling and held:
            self._chilling, self._chill_since = want, t
        return 1.0 if self._chilling else 0.0

    def predict(
        self, n: int, state: np.ndarray, history: np.ndarray, blower: np.ndarray, q_cool: np.ndarray,
        q_heat: np.ndarray, q_chill: np.ndarray | None = None,
    ) -> np.ndarray:  # fmt: skip
        """The prediction model's states (``(steps, 8)``: :data:`_STATES`, [K] and [kW]) under given commands.

        The same program as :meth:`decide` with the commands fixed (blower [1], sensible cooling, heating and
        chiller duties [W] per step) and no limits on them: what the MPC believes those commands would do.
        """
        N = self.options.steps
        problem = self._problem(n, state, history, free=True)
        lbx, ubx = problem["lbx"].copy(), problem["ubx"].copy()
        q_chill = np.zeros(N) if q_chill is None else np.asarray(q_chill)
        fixed = np.column_stack((blower, np.asarray(q_cool) / 1e3, np.asarray(q_heat) / 1e3, q_chill / 1e3))
        for k in range(len(_COMMANDS)):
            lbx[k : _N_U * N : _N_U] = ubx[k : _N_U * N : _N_U] = fixed[:, k]
        x0 = self._initial_state(state, history)
        sol = self._solver(x0=self._guess(x0, 0.5)["x"], p=problem["p"], lbx=lbx, ubx=ubx, lbg=self._lbg, ubg=self._ubg)
        return np.asarray(sol["x"]).ravel()[self._n_u :].reshape(N, _N_X)

    def _problem(self, n: int, state: np.ndarray, history: np.ndarray, free: bool = False) -> dict:
        """Parameters and bounds of the program at step ``n``; ``free`` lifts the duty and inlet limits."""
        par, N = self.ctx.par, self.options.steps
        last = history[-1] if len(history) else None
        x0 = self._initial_state(state, history)
        T_amb, p_atm = float(par[L.P_T_AMB]), float(par[L.P_P_ATM])
        r = float(last[L.O_RECIRC]) if last is not None and math.isfinite(last[L.O_RECIRC]) else float(par[L.P_RC_COOL])
        T_in = r * float(x0[0]) + (1.0 - r) * T_amb
        g_v = par[L.P_BLOWER_FLOW] * p_atm / (_R * T_in) * _CP / 1e3  # the blower's full flow [kW/K]
        b_min = float(par[L.P_BLOWER_MIN])
        w_in = r * state[L.S_W] + (1.0 - r) * par[L.P_W_AMB]
        rh_in = min(max(L.relative_humidity(T_in, w_in, p_atm), 0.0), 1.0)
        x_front = self._front_air(n, last)
        fit, qc_max = self._compressor_fit(T_amb, T_in, rh_in, b_min, x_front)
        chill_fit, qch_max = self._chiller_fit(T_amb, float(state[L.S_TC]), float(x_front.mean()))
        heating = int(par[L.P_HEATING])
        qh_max = (par[L.P_PTC_MAX] if heating == L.HEATING_PTC_AIR else par[L.P_PTCW_MAX]) / 1e3
        regime = self._regime(b_min, g_v)
        cooling = regime == "cooling"
        if cooling:
            qh_max = 0.0
        else:
            qc_max = qch_max = 0.0
        t_ev_min, t_v_max = par[L.P_TEV_MIN] + 1.0, par[L.P_TV_MAX]
        season = float(cooling)
        if free:
            cooling, season, qc_max, qh_max, qch_max, t_ev_min, t_v_max = False, 1.0, 1e3, 1e3, 1e3, 0.0, 1e3
        b_last = float(last[L.O_BLOWER]) if last is not None and math.isfinite(last[L.O_BLOWER]) else b_min
        u_last = self._warm["u0"] if self._warm is not None else np.array([max(b_last, b_min), 0.0, 0.0, 0.0])
        values = {
            "x0": x0, "T_amb": T_amb, "q_air": (par[L.P_Q_OCC] + self.q_sun_air) / 1e3,
            "q_int": self.q_sun_int / 1e3, "r": r, "g_v": g_v, "t_ev_min": t_ev_min, "t_v_max": t_v_max,
            "qc_max": qc_max, "qh_max": qh_max, "qch_max": qch_max, "eta": self._heating_efficiency(heating, state),
            "a1": fit[0] + fit[3] * x_front, "a2": fit[1], "a3": fit[2], "p_blower": par[L.P_BLOWER_POWER] / 1e3,
            "c1": chill_fit[0], "c2": chill_fit[1], "q_gen": self._battery_heat(n, history) / 1e3, "u_last": u_last,
            "cooling": float(cooling and x0[0] >= self.T_set - self.band), "t_ev_max": self._evap_ceiling(),
            "cool_season": season,
            **self._battery_loop(last),
            "tau_heat": self._heat_lag(heating, state, last, T_in),
        }  # fmt: skip
        lo = np.tile([b_min, 0.0, 0.0, 0.0, 0.0, 0.0], N)
        hi = np.tile([1.0, max(qc_max, 0.0), qh_max, qch_max, np.inf, np.inf], N)
        lbx = np.concatenate((lo, np.tile(_X_LOW, N)))
        ubx = np.concatenate((hi, np.tile(_X_HIGH, N)))
        return {
            "p": self._layout.pack(values), "lbx": lbx, "ubx": ubx, "T_in": T_in, "g_v": g_v, "b_min": b_min,
            "qch_max": qch_max, "cooling": cooling, "regime": regime,
        }  # fmt: skip

    @staticmethod
    def _initial_state(state: np.ndarray, history: np.ndarray) -> np.ndarray:
        """The prediction's start: the plant's temperatures and the heat its heater gave the air last step [kW]."""
        last = history[-1] if len(history) else None
        q = 0.0
        if last is not None:
            q = sum(v for v in (last[L.O_P_PTC], last[L.O_Q_HC]) if math.isfinite(v)) / 1e3
        return np.append(state[_STATE_COLUMNS], q)

    def _heat_lag(self, heating: int, state: np.ndarray, last: np.ndarray | None, T_in: float) -> float:
        """Time constant [s] of the heat the air gets behind the heater: none for the air PTC; for a heater on
        the heater-core loop the loop's capacity over its conductance to the air, ``C_H (T_H - T_in) / Q_hc``
        as the last step had them (0.7 of the air's capacity rate before the core carries heat)."""
        if heating == L.HEATING_PTC_AIR or last is None:
            return 0.0
        par = self.ctx.par
        q_hc, T_H = float(last[L.O_Q_HC]), float(state[L.S_TH])
        if math.isfinite(q_hc) and q_hc > 100.0 and T_H > T_in + 1.0:
            g = q_hc / (T_H - T_in)
        else:
            mdot = float(last[L.O_MDOT_AIR]) if math.isfinite(last[L.O_MDOT_AIR]) else 0.0
            g = 0.7 * max(mdot, 0.05) * _CP
        return float(par[L.P_C_H]) / g

    def _battery_loop(self, last: np.ndarray | None) -> dict:
        """The pack-to-coolant conductance [kW/K] and the coolant heater [kW] as the last step had them (the
        rules' relays run the pump and the heater; in the cooling season the chiller's pump command)."""
        if last is None or not math.isfinite(last[L.O_G_BC]):
            return {"g_bc": self.g_plate / 1e3, "p_heater": 0.0}
        g = self.g_plate if self._chilling else float(last[L.O_G_BC])
        return {"g_bc": g / 1e3, "p_heater": float(last[L.O_P_HEATER]) / 1e3}

    def _battery_heat(self, n: int, history: np.ndarray) -> np.ndarray:
        """The battery's Joule heat [W] per horizon step: the mean over the step of ``R_eff P^2``, with ``P``
        the previewed motor power plus the other loads as they are now, sampled every second, and ``R_eff``
        identified on the last two minutes (Joule heat over squared terminal power, step by step)."""
        N, o = self.options.steps, self.options
        edges = self.ctx.edges
        t0 = edges[n]
        recent = history[edges[:n] >= t0 - 120.0]
        if not len(recent):
            return np.zeros(N)
        p_bat = recent[:, L.O_P_BATTERY]
        denom = float(np.sum(p_bat**2))
        r_eff = float(np.sum(recent[:, L.O_Q_GEN]) / denom) if denom > 0.0 else 0.0
        last10 = recent[-10:]
        others = float(np.mean(last10[:, L.O_P_BATTERY] - last10[:, L.O_P_MOTOR_EL]))
        m = max(1, round(o.step))  # samples per horizon step
        t = t0 + o.step * (np.arange(N)[:, None] + (np.arange(m)[None, :] + 0.5) / m)
        if o.preview == "none":
            motor = np.full(t.shape, float(np.mean(last10[:, L.O_P_MOTOR_EL])))
        else:
            idx = np.clip(np.searchsorted(edges, t) - 1, 0, self.motor_power.size - 1)
            motor = self.motor_power[idx]
        return r_eff * np.mean((motor + others) ** 2, axis=1)

    def _regime(self, b_min: float, g_v: float) -> str:
        """Where the prediction model holds, by the cabin's steady load at its setpoint (the loop's
        feed-forward: shell, sun, occupants) and the ambient.

        - ``heating``: the cabin loses heat: no compressor on the cabin coil, the battery stays the rules';
        - ``cooling``: the outside is warmer than the setpoint (no free cooling with outside air), the
          compressor may run and the load needs vent air within 2 K of the evaporator's ceiling or colder at
          the minimum blower: no heat (reheat for drying stays the rules'), the coil at most at its ceiling
          while the cabin is not below its band, the battery's cooling is the MPC's;
        - ``rules``: otherwise, a light cooling load that the compressor meets only by cycling at its minimum
          speed, or that outside air takes (the rules' fresh-air economy), or that warms a cold cabin by
          itself (the rules wait for the sun, the model would heat); none of it is in the model, and the rules'
          cabin loop runs.
        """
        par = self.ctx.par
        T_amb = float(par[L.P_T_AMB])
        load = par[L.P_UA_SHELL] * (T_amb - self.T_set) + par[L.P_Q_SUN] + par[L.P_Q_OCC]
        if load <= 0.0:
            return "heating"
        T_vent = self.T_set - load / 1e3 / (b_min * g_v)
        if T_amb > self.T_set and T_amb >= par[L.P_AC_TAMB_MIN] and T_vent < self._evap_ceiling() + 2.0:
            return "cooling"
        return "rules"

    def _evap_ceiling(self) -> float:
        """Warmest evaporator air [K] the MPC asks for: the evaporator's highest setting, and no warmer than
        the dew point of cabin air at the setpoint and 0.1 below the dehumidifying threshold, so the coil keeps
        drying the air and the rules' reheat (which answers a humid cabin) stays off."""
        par = self.ctx.par
        p_atm = float(par[L.P_P_ATM])
        w_dry = L.humidity_ratio(self.T_set, max(float(par[L.P_RH_DEHUM]) - 0.1, 0.05), p_atm)
        return float(min(par[L.P_TEV_MAX], L.dew_point(w_dry, p_atm)))

    def _guess(self, x0: np.ndarray, b_min: float) -> dict:
        """The previous solution shifted by one step, or a cold start at the present state."""
        N = self.options.steps
        if self._warm is None:
            U = np.tile([b_min, 0.0, 0.0, 0.0, 0.0, 0.0], N)
            X = np.tile(x0, N)
            return {"x": np.concatenate((U, X))}
        w = self._warm["w"]
        U = w[: self._n_u].reshape(N, _N_U)
        X = w[self._n_u :].reshape(N, _N_X)
        U = np.vstack((U[1:], U[-1:]))
        X = np.vstack((X[1:], X[-1:]))
        return {
            "x": np.concatenate((U.ravel(), X.ravel())),
            "lam_x": self._warm["lam_x"],
            "lam_g": self._warm["lam_g"],
        }

    def _front_air(self, n: int, last: np.ndarray | None) -> np.ndarray:
        """Condenser front-air fraction per horizon step: the fan as it runs now plus the previewed ram air."""
        par, o, N = self.ctx.par, self.options, self.options.steps
        edges = self.ctx.edges
        t0 = edges[n]
        u_fan = float(last[L.O_FAN]) if last is not None and math.isfinite(last[L.O_FAN]) else 1.0 / 3.0
        v_fan = max(u_fan, 1.0 / 3.0) * par[L.P_FAN_VMAX]
        mids = t0 + (np.arange(N) + 0.5) * o.step
        if o.preview == "none":
            v = np.full(N, self.speed[n - 1] if n > 0 else self.speed[0])
        else:
            idx = np.clip(np.searchsorted(edges, mids) - 1, 0, self.speed.size - 1)
            v = self.speed[idx]
        v_ram = par[L.P_RAM_AREA] * v
        front = np.maximum(np.sqrt(v_fan**2 + v_ram**2), par[L.P_V_FRONT_MIN])
        return np.minimum(front / par[L.P_FAN_VMAX], 1.0)

    def _compressor_fit(
        self, T_amb: float, T_in: float, rh_in: float, b_min: float, x_front: np.ndarray
    ) -> tuple[np.ndarray, float]:
        """Least-squares ``W = q (a1 + a2 q + a3 b + a4 x_f)`` [kW] on the ``ac`` map; and the largest duty."""
        maps = getattr(self.ctx.refrigerant, "maps", {})
        if "ac" not in maps:
            return np.array([1.0 / 3.0, 0.0, 0.0, 0.0]), 6.0
        knots, starts, table = maps["ac"].packed()
        y = np.empty(L.N_Y)
        rows, target = [], []
        qc_max = 0.0
        fronts = (float(x_front.min()), float(x_front.max()))
        for xf in sorted(set(fronts)):
            for b in (b_min, 0.5 * (b_min + 1.0), 1.0):
                for u in (0.25, 0.5, 0.75, 1.0):
                    L.map_interp(knots, starts, table, np.array([u, xf, b, T_amb, T_in, rh_in]), y)
                    q = (y[L.Y_QEVAP] - y[L.Y_QLAT]) / 1e3
                    if not (math.isfinite(q) and math.isfinite(y[L.Y_W]) and q > 0.05):
                        continue
                    rows.append([q, q * q, q * b, q * xf])
                    target.append(y[L.Y_W] / 1e3)
                    qc_max = max(qc_max, q)
        if len(rows) < 6:
            return np.array([1.0 / 3.0, 0.0, 0.0, 0.0]), max(qc_max, 1.0)
        A = np.array(rows)
        if fronts[0] == fronts[1]:
            A[:, 3] = 0.0
        coef = np.linalg.lstsq(A, np.array(target), rcond=None)[0]
        return coef, qc_max

    def _chiller_fit(self, T_amb: float, T_coolant: float, x_front: float) -> tuple[np.ndarray, float]:
        """Least-squares ``W = q (c1 + c2 q)`` [kW] of the chiller alone on the ``chiller`` map at the battery
        pump's command; and its largest duty [kW]."""
        maps = getattr(self.ctx.refrigerant, "maps", {})
        if "chiller" not in maps:
            return np.array([1.0 / 3.0, 0.0]), 0.0
        knots, starts, table = maps["chiller"].packed()
        y = np.empty(L.N_Y)
        rows, target = [], []
        u_pump = float(self.ctx.par[L.P_PUMP_BC])
        for u in (0.25, 0.5, 0.75, 1.0):
            L.map_interp(knots, starts, table, np.array([u, x_front, u_pump, T_amb, T_coolant]), y)
            q = y[L.Y_QCH] / 1e3
            if math.isfinite(q) and math.isfinite(y[L.Y_W]) and q > 0.05:
                rows.append([q, q * q])
                target.append(y[L.Y_W] / 1e3)
        if len(rows) < 3:
            return np.array([1.0 / 3.0, 0.0]), 0.0
        coef = np.linalg.lstsq(np.array(rows), np.array(target), rcond=None)[0]
        return coef, max(r[0] for r in rows)

    def _heating_efficiency(self, heating: int, state: np.ndarray) -> float:
        """Heat per electrical power [1]: 1 for the PTCs, the ``hp`` map's COP at half speed for the heat pump."""
        maps = getattr(self.ctx.refrigerant, "maps", {})
        if heating != L.HEATING_HEAT_PUMP or "hp" not in maps:
            return 1.0
        knots, starts, table = maps["hp"].packed()
        y = np.empty(L.N_Y)
        L.map_interp(knots, starts, table, np.array([0.5, 1.0, state[L.S_TH], 0.5, state[L.S_TE]]), y)
        cop = y[L.Y_QCOND] / y[L.Y_W] if y[L.Y_W] > 0.0 else math.nan
        return float(min(max(cop, 1.0), 5.0)) if math.isfinite(cop) else 1.0


def make_controller(name: str, options: MpcOptions | None = None) -> CabinMpc | None:
    """The supervisory controller called ``name`` (:data:`evtms.system.controllers.CONTROLLERS`): None for
    ``rules`` (the loop's own cabin control), a :class:`CabinMpc` for ``mpc``."""
    from evtms.system.controllers import check_controller

    check_controller(name)
    return None if name == "rules" else CabinMpc(options)
