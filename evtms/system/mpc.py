"""A model-predictive cabin controller: the supervisory layer above the climate control's local loops.

Every ``step`` seconds :class:`CabinMpc` solves, over a receding horizon of
``horizon`` seconds, for the blower command and the sensible cooling and
heating duties that hold the cabin air within ``comfort_band`` of its
setpoint for the least electrical energy, and hands the first step's vent-air
target and blower to the plant (:mod:`evtms.system.controllers`). The plant
is always the full simulator: the relays, frost cutoffs and actuator ranges
below the vent target are the rules' own.

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
  for the heat pump); the blower ``P_b b^3``.

Objective [kJ]: sum_k h (W_k + q_h,k / eta + P_b b_k^3) + w_c (h/60) s_k^2
+ w_t (h/60) (T_a,k - T_set)^2 + w_s (Delta u_k)^2, with ``s_k >= |T_a,k -
T_set| - comfort_band`` (minutes outside the band, squared), a weak pull
to the setpoint and smooth commands. Constraints: blower within its range,
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
Eckstein, L. et al. (2024). World Electric Vehicle Journal 15, 224
(predictive cabin conditioning against a rule-based strategy).
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
_N_X = 5  # cabin air, interior, three walls


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
        Weight [kJ / (K^2 min)] pulling the air to the setpoint inside it.
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
    w_track: float = 2.0
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


class CabinMpc:
    """Receding-horizon cabin controller (see the module docstring for the model and the problem).

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
        self.caps = np.array([par[L.P_C_AIR], par[L.P_C_INT], par[L.P_C_GLASS], par[L.P_C_DOORS], par[L.P_C_ROOF]])
        self.g_walls = np.array([par[L.P_G_GLASS], par[L.P_G_DOORS], par[L.P_G_ROOF]])
        q_sun = float(par[L.P_Q_SUN])
        self.q_sun_int = q_sun if par[L.P_C_INT] > 0.0 else 0.0
        self.q_sun_air = q_sun - self.q_sun_int
        self.speed = self._preview_speed(context)
        self._warm = None
        self._build()

    def _preview_speed(self, context: ControlContext) -> np.ndarray:
        speed = np.asarray(context.speed, float)
        if self.options.preview == "noisy":
            rng = np.random.default_rng(self.options.seed)
            speed = np.maximum(speed * (1.0 + self.options.noise * rng.standard_normal(speed.size)), 0.0)
        return speed

    def _build(self) -> None:
        ca = self._ca
        o, N = self.options, self.options.steps
        h = o.step
        U = ca.SX.sym("U", 4, N)  # blower [1], sensible cooling [kW], heating [kW], comfort slack [K]
        X = ca.SX.sym("X", _N_X, N)  # states at the ends of the steps [K]
        # Parameters: initial state, ambient, sources [kW], recirculation, full flow G_v [kW/K], inlet limits,
        # the compressor's fit (a1 per step, a2, a3), heating efficiency, blower power [kW], last commands.
        P = ca.SX.sym("P", _N_X + 10 + N + 3 + 3 + 3)
        x0 = P[:_N_X]
        T_amb, q_air, q_int, r, g_v, t_ev_min, t_v_max, qc_max, qh_max, eta = (P[_N_X + i] for i in range(10))
        a1 = P[_N_X + 10 : _N_X + 10 + N]
        a2, a3, p_bl = (P[_N_X + 10 + N + i] for i in range(3))
        u_last = P[_N_X + 13 + N : _N_X + 16 + N]
        cooling, t_ev_max, cool_season = P[_N_X + 16 + N], P[_N_X + 17 + N], P[_N_X + 18 + N]
        C = self.caps / 1e3  # [kJ/K]
        G = self.g_walls / 1e3
        g_i = float(self.ctx.par[L.P_G_INT]) / 1e3
        w_set = self.T_set
        J = 0.0
        g, lbg, ubg = [], [], []
        x_prev, u_prev = x0, u_last
        for k in range(N):
            b, qc, qh, s = U[0, k], U[1, k], U[2, k], U[3, k]
            x = X[:, k]
            Ta, Ti = x[0], x[1]
            walls = x[2:5]
            f_air = b * g_v * (1.0 - r) * (T_amb - Ta) + qh - qc + q_air + g_i * (Ti - Ta)
            for w in range(3):
                f_air += G[w] * (walls[w] - Ta)
            g.append(C[0] * (Ta - x_prev[0]) - h * f_air)
            g.append(C[1] * (Ti - x_prev[1]) - h * (g_i * (Ta - Ti) + q_int))
            for w in range(3):
                g.append(C[2 + w] * (walls[w] - x_prev[2 + w]) - h * G[w] * (Ta + T_amb - 2.0 * walls[w]))
            lbg += [0.0] * _N_X
            ubg += [0.0] * _N_X
            # Supply air between the evaporator's lowest setting and the vent's highest, at the step's inlet.
            T_in = r * x_prev[0] + (1.0 - r) * T_amb
            # (the cooling limit only in the cooling season: cold inlet air below the evaporator's lowest setting
            # would otherwise ask for negative cooling)
            g += [qc - cool_season * b * g_v * (T_in - t_ev_min), qh - b * g_v * (t_v_max - T_in)]
            g += [s - (Ta - w_set) + self.band]
            g += [s + (Ta - w_set) + self.band]
            lbg += [-ca.inf, -ca.inf, 0.0, 0.0]
            ubg += [0.0, 0.0, ca.inf, ca.inf]
            g += [qc - qc_max, qh - qh_max]
            lbg += [-ca.inf, -ca.inf]
            ubg += [0.0, 0.0]
            # Cooling: the evaporator air at most its highest setting, as the rules hold it (the coil keeps
            # drying the air, and the compressor's minimum speed is not asked for less than it gives).
            g.append(cooling * (b * g_v * (T_in - t_ev_max) - qc))
            lbg.append(-ca.inf)
            ubg.append(0.0)
            power = qc * (a1[k] + a2 * qc + a3 * b) + qh / eta + p_bl * b**3  # [kW]
            J += h * power + h / 60.0 * (o.w_comfort * s**2 + o.w_track * (Ta - w_set) ** 2)
            du = U[:3, k] - u_prev
            J += o.w_smooth * ca.sumsqr(du)
            x_prev, u_prev = x, U[:3, k]
        w = ca.vertcat(ca.vec(U), ca.vec(X))
        nlp = {"x": w, "p": P, "f": J, "g": ca.vertcat(*g)}
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
        self._n_u, self._n = 4 * N, 4 * N + _N_X * N

    # -- decisions ------------------------------------------------------------------------------------------
    def decide(self, n: int, state: np.ndarray, last: np.ndarray | None) -> Decision:
        """The vent-air target and blower for the period starting at step ``n``."""
        wall0 = time.perf_counter()
        N = self.options.steps
        x0 = state[[L.S_TA, L.S_TINT, L.S_TGLASS, L.S_TDOORS, L.S_TROOF]]
        if self.ctx.key_off[n] or not np.all(np.isfinite(x0)):
            return Decision(math.nan, math.nan, time.perf_counter() - wall0, True)
        problem = self._problem(n, state, last)
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
        U = w[: self._n_u].reshape(N, 4)
        self._warm = {
            "w": w,
            "lam_x": np.asarray(sol["lam_x"]).ravel(),
            "lam_g": np.asarray(sol["lam_g"]).ravel(),
            "u0": U[0, :3].copy(),
        }
        b, qc, qh = U[0, :3]
        # The interior point ends within its tolerance of a bound, on either side: the commands are clipped to
        # the actuators' ranges (a blower 1e-8 under its minimum is not one the car has).
        par = self.ctx.par
        b = min(max(float(b), problem["b_min"]), 1.0)
        T_vent = problem["T_in"] + (qh - qc) / (b * problem["g_v"])
        T_vent = min(max(float(T_vent), float(par[L.P_TV_MIN])), float(par[L.P_TV_MAX]))
        return Decision(T_vent, b, time.perf_counter() - wall0, True)

    def predict(
        self, n: int, state: np.ndarray, last: np.ndarray | None, blower: np.ndarray, q_cool: np.ndarray,
        q_heat: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """The prediction model's cabin air [K] at the ends of the horizon's steps under given commands.

        The same program as :meth:`decide` with the commands fixed (blower [1], sensible cooling and heating
        duties [W] per step) and no limits on them: what the MPC believes those commands would do.
        """
        N = self.options.steps
        problem = self._problem(n, state, last, free=True)
        lbx, ubx = problem["lbx"].copy(), problem["ubx"].copy()
        fixed = np.column_stack((blower, np.asarray(q_cool) / 1e3, np.asarray(q_heat) / 1e3)).ravel()
        for k in range(3):
            lbx[k : 4 * N : 4] = ubx[k : 4 * N : 4] = fixed[k::3]
        x0 = state[[L.S_TA, L.S_TINT, L.S_TGLASS, L.S_TDOORS, L.S_TROOF]]
        sol = self._solver(x0=self._guess(x0, 0.5)["x"], p=problem["p"], lbx=lbx, ubx=ubx, lbg=self._lbg, ubg=self._ubg)
        return np.asarray(sol["x"]).ravel()[self._n_u :].reshape(N, _N_X)[:, 0]

    def _problem(self, n: int, state: np.ndarray, last: np.ndarray | None, free: bool = False) -> dict:
        """Parameters and bounds of the program at step ``n``; ``free`` lifts the duty and inlet limits."""
        par, N = self.ctx.par, self.options.steps
        x0 = state[[L.S_TA, L.S_TINT, L.S_TGLASS, L.S_TDOORS, L.S_TROOF]]
        T_amb, p_atm = float(par[L.P_T_AMB]), float(par[L.P_P_ATM])
        r = float(last[L.O_RECIRC]) if last is not None and math.isfinite(last[L.O_RECIRC]) else float(par[L.P_RC_COOL])
        T_in = r * float(x0[0]) + (1.0 - r) * T_amb
        g_v = par[L.P_BLOWER_FLOW] * p_atm / (_R * T_in) * _CP / 1e3  # the blower's full flow [kW/K]
        b_min = float(par[L.P_BLOWER_MIN])
        w_in = r * state[L.S_W] + (1.0 - r) * par[L.P_W_AMB]
        rh_in = min(max(L.relative_humidity(T_in, w_in, p_atm), 0.0), 1.0)
        x_front = self._front_air(n, last)
        fit, qc_max = self._compressor_fit(T_amb, T_in, rh_in, b_min, x_front)
        heating = int(par[L.P_HEATING])
        qh_max = (par[L.P_PTC_MAX] if heating == L.HEATING_PTC_AIR else par[L.P_PTCW_MAX]) / 1e3
        # One season per decision, by the ambient against the setpoint: cooling (no heat; reheat for drying stays
        # the rules') or heating (no compressor on the cabin coil).
        cooling = T_amb > self.T_set
        if cooling:
            qh_max = 0.0
        else:
            qc_max = 0.0
        t_ev_min, t_v_max = par[L.P_TEV_MIN] + 1.0, par[L.P_TV_MAX]
        season = float(cooling)
        if free:
            cooling, season, qc_max, qh_max, t_ev_min, t_v_max = False, 1.0, 1e3, 1e3, 0.0, 1e3
        b_last = float(last[L.O_BLOWER]) if last is not None and math.isfinite(last[L.O_BLOWER]) else b_min
        u_last = self._warm["u0"] if self._warm is not None else np.array([max(b_last, b_min), 0.0, 0.0])
        p = np.concatenate(
            (
                x0,
                [T_amb, (par[L.P_Q_OCC] + self.q_sun_air) / 1e3, self.q_sun_int / 1e3, r, g_v],
                [t_ev_min, t_v_max, qc_max, qh_max, self._heating_efficiency(heating, state)],
                fit[0] + fit[3] * x_front,
                [fit[1], fit[2], par[L.P_BLOWER_POWER] / 1e3],
                u_last,
                [float(cooling), self._evap_ceiling(), season],
            )
        )
        lbx = np.concatenate((np.tile([b_min, 0.0, 0.0, 0.0], N), np.full(_N_X * N, 150.0)))
        ubx = np.concatenate((np.tile([1.0, max(qc_max, 0.0), qh_max, np.inf], N), np.full(_N_X * N, 450.0)))
        return {"p": p, "lbx": lbx, "ubx": ubx, "T_in": T_in, "g_v": g_v, "b_min": b_min}

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
            U = np.tile([b_min, 0.0, 0.0, 0.0], N)
            X = np.tile(x0, N)
            return {"x": np.concatenate((U, X))}
        w = self._warm["w"]
        U = w[: self._n_u].reshape(N, 4)
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
    from evtms.system.controllers import CONTROLLERS

    if name not in CONTROLLERS:
        raise EvtmsInputError(f"controller {name!r} is not allowed; allowed: {', '.join(CONTROLLERS)}")
    return None if name == "rules" else CabinMpc(options)
