"""Data-driven mode models: what the time loop evaluates with ``--model surrogate`` (inference only).

A mode model replaces the thermal plant of one operating mode (the
refrigerant loop and the thermal network: battery, coolant, cabin air, walls,
interior, humidity) by two small feed-forward networks, trained by
:mod:`evtms.surrogates` on the LUT simulator's steps:

- ``power``: the state at ``t_n`` (temperatures of battery, coolant, cabin
  air, walls and interior, cabin humidity, and the refrigerant loop's
  filtered suction pressure, evaporator and chiller heat flows) and the
  step's actuator commands, ambient and solar gain -> the compressor's
  electrical power over the step [W];
- ``dynamics``: the same plus the battery's heat generation of the step ->
  the state's mean rate of change over the step, ``(z_n+1 - z_n)/dt`` [unit/s].

The controllers, the drive and the battery's electrical model stay physics:
they are cheap and exact, and the battery current needs the HVAC power the
``power`` network gives. Only quantities known at the step are inputs (no
measured response), so a mode model predicts forward. The loop integrates
``z_n+1 = z_n + dt f(z_n, u_n)`` (explicit Euler with the trained step's
mean rate); a feature outside the training range of its mode flags the step
``surrogate_out_of_range``.

Networks are multilayer perceptrons ``y = W_L g(... g(W_1 x + b_1)) + b_L``
with ``g`` = ReLU or tanh on standardised inputs and outputs (Goodfellow,
Bengio, Courville (2016), Deep Learning, MIT Press, ch. 6).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evtms.system import loop as L  # noqa: N812 - the loop's constants, read as L.*

#: Mode codes of the loop (``mode`` variable of the output) by the names training and ``--mode`` use.
MODE_CODES = {
    "off": L.OFF, "bh": L.BH, "bc": L.BC, "cc": L.CC, "ch": L.CH, "ch+bh": L.CH_BH, "ch+bc": L.CH_BC, "cc+bc": L.CC_BC,
}  # fmt: skip
#: The loop's state columns a mode model carries, with units.
STATE_NAMES = (
    "T_battery", "T_coolant", "T_cabin", "T_glass", "T_doors", "T_roof", "T_interior", "w_cabin", "p_suction",
    "Q_evaporator", "Q_chiller",
)  # fmt: skip
STATE_COLUMNS = L.SURROGATE_STATES
COMMAND_NAMES = ("compressor_speed", "blower", "u_pump", "P_ptc", "P_heater")
AMBIENT_NAMES = ("T_amb", "w_amb", "Q_sun")
POWER_FEATURES = STATE_NAMES + COMMAND_NAMES + AMBIENT_NAMES
DYNAMICS_FEATURES = POWER_FEATURES + ("Q_battery_gen",)
POWER_TARGETS = ("P_compressor",)
DYNAMICS_TARGETS = tuple(f"d{s}_dt" for s in STATE_NAMES)
UNITS = {
    **{s: "K" for s in STATE_NAMES[:7]},
    "w_cabin": "kg kg-1",
    "p_suction": "Pa",
    "Q_evaporator": "W",
    "Q_chiller": "W",
    "Q_sun": "W",
    "compressor_speed": "1",
    "blower": "1",
    "u_pump": "1",
    "P_ptc": "W",
    "P_heater": "W",
    "T_amb": "K",
    "w_amb": "kg kg-1",
    "Q_battery_gen": "W",
    "P_compressor": "W",
    **{f"d{s}_dt": "K s-1" for s in STATE_NAMES[:7]},
    "dw_cabin_dt": "kg kg-1 s-1",
    "dp_suction_dt": "Pa s-1",
    "dQ_evaporator_dt": "W s-1",
    "dQ_chiller_dt": "W s-1",
}
ACTIVATIONS = {"relu": 0, "tanh": 1}
HEADS = ("power", "dynamics")
#: Widest layer the loop's kernel evaluates (scratch size).
MAX_WIDTH = L._MLP_WIDTH


@dataclass(frozen=True)
class Network:
    """One feed-forward network on standardised inputs and outputs.

    Attributes
    ----------
    activation : str
        Hidden-layer activation, ``relu`` or ``tanh``; the output layer is linear.
    weights, biases : list of numpy.ndarray
        Layer ``k`` maps ``h_k`` (width ``n_k``) to ``h_k @ weights[k] + biases[k]`` (``weights[k]``: ``(n_k, n_k+1)``).
    x_mean, x_scale : numpy.ndarray
        Input standardisation, ``(x - x_mean) / x_scale`` [feature units].
    y_mean, y_scale : numpy.ndarray
        Output de-standardisation, ``y = y_mean + y_scale y_n`` [target units].
    x_min, x_max : numpy.ndarray
        Training range of each input [feature units]; a step with an input
        further than ``1e-6 x_scale`` outside it is flagged.
    """

    activation: str
    weights: list[np.ndarray]
    biases: list[np.ndarray]
    x_mean: np.ndarray
    x_scale: np.ndarray
    y_mean: np.ndarray
    y_scale: np.ndarray
    x_min: np.ndarray
    x_max: np.ndarray

    def __post_init__(self) -> None:
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation {self.activation!r}; allowed: {', '.join(ACTIVATIONS)}")
        widths = [self.weights[0].shape[0]] + [w.shape[1] for w in self.weights]
        if max(widths) > MAX_WIDTH:
            raise ValueError(f"layer of width {max(widths)}; at most {MAX_WIDTH}")

    @property
    def n_in(self) -> int:
        return int(self.weights[0].shape[0])

    @property
    def n_out(self) -> int:
        return int(self.weights[-1].shape[1])

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Outputs ``(n, n_out)`` of inputs ``(n, n_in)`` in physical units (plain NumPy)."""
        h = (np.atleast_2d(np.asarray(X, float)) - self.x_mean) / self.x_scale
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w + b
            if k < len(self.weights) - 1:
                h = np.maximum(h, 0.0) if self.activation == "relu" else np.tanh(h)
        return self.y_mean + self.y_scale * h

    def packed(self) -> np.ndarray:
        """Flat layout the loop's kernel reads (:func:`evtms.system.loop.mlp_eval`).

        ``[n_layers, activation, n_0 .. n_L, x_mean, x_scale, x_min, x_max, y_mean, y_scale, W_1, b_1, ...]``
        """
        widths = [self.n_in] + [w.shape[1] for w in self.weights]
        parts = [np.array([len(self.weights), ACTIVATIONS[self.activation], *widths], float)]
        parts += [self.x_mean, self.x_scale, self.x_min, self.x_max, self.y_mean, self.y_scale]
        for w, b in zip(self.weights, self.biases, strict=True):
            parts += [np.ascontiguousarray(w, float).ravel(), np.asarray(b, float)]
        return np.concatenate([np.asarray(p, float).ravel() for p in parts])


@dataclass
class ModeModels:
    """The mode models of one vehicle: per mode code, a ``power`` and a ``dynamics`` network.

    Attributes
    ----------
    power, dynamics : dict of int to Network
        By mode code (:data:`MODE_CODES`).
    attrs : dict
        Provenance: evtms version, training scenarios, metrics.
    """

    power: dict[int, Network]
    dynamics: dict[int, Network]
    attrs: dict = field(default_factory=dict)

    def codes(self) -> list[int]:
        """Mode codes with both networks."""
        return sorted(set(self.power) & set(self.dynamics))

    def packed(self) -> tuple[np.ndarray, np.ndarray]:
        """``(net, index)``: every network's :meth:`Network.packed` end to end, and ``index[code, head]``
        its offset in ``net`` (-1: none)."""
        index = np.full((8, 2), -1, np.int64)
        parts: list[np.ndarray] = []
        offset = 0
        for h, nets in enumerate((self.power, self.dynamics)):
            for code, net in sorted(nets.items()):
                p = net.packed()
                index[code, h] = offset
                parts.append(p)
                offset += p.size
        return (np.concatenate(parts) if parts else np.zeros(1)), index


def training_pairs(trace: dict) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Features and targets of every step of a simulation, by the step's mode code.

    ``trace`` is :attr:`evtms.system.simulate.SimulationResult.trace` (a run
    with ``keep_trace=True``). Returns ``{code: (X_power, Y_power,
    X_dynamics, Y_dynamics)}`` with columns in :data:`POWER_FEATURES`,
    :data:`POWER_TARGETS`, :data:`DYNAMICS_FEATURES`, :data:`DYNAMICS_TARGETS`
    order, exactly as the loop assembles them.
    """
    states, out, modes, dts, par = trace["states"], trace["out"], trace["modes"], trace["dts"], trace["par"]
    n = dts.size
    z0 = states[:n][:, STATE_COLUMNS]
    z1 = states[1 : n + 1][:, STATE_COLUMNS]
    commands = out[:, [L.O_SPEED_CMD, L.O_BLOWER, L.O_U_PUMP, L.O_P_PTC, L.O_P_HEATER]]
    ambient = np.broadcast_to([par[L.P_T_AMB], par[L.P_W_AMB], par[L.P_Q_SUN]], (n, 3))
    x_power = np.column_stack([z0, commands, ambient])
    x_dyn = np.column_stack([x_power, out[:, L.O_Q_GEN]])
    y_power = out[:, [L.O_P_COMPRESSOR]]
    y_dyn = (z1 - z0) / dts[:, None]
    pairs = {}
    for code in np.unique(modes):
        sel = modes == code
        pairs[int(code)] = (x_power[sel], y_power[sel], x_dyn[sel], y_dyn[sel])
    return pairs
