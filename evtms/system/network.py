"""Lumped thermal network stepped by backward Euler, with exact per-step ledgers.

Nodes ``i`` of heat capacity ``C_i`` [J/K] exchange heat through
conductances ``G_ij`` [W/K] with each other and ``G_i0`` with boundaries at
given temperatures (the ambient); sources ``Q_i`` [W] are held over a step.
One step of length ``dt`` [s] solves

.. math:: (C/dt + K)\\, T_{n+1} = C\\, T_n / dt + Q + G_0 T_{boundary}

with ``K`` the conductance (Laplacian) matrix plus the boundary conductances
on its diagonal. The scheme is unconditionally stable, and the flows taken
from ``T_n+1`` close every node's ledger exactly (to round-off):
``C_i (T_i,n+1 - T_i,n) = dt (Q_i + sum of flows in)``. The matrix depends
only on ``dt`` and the conductances, so it is factorised once per ``dt`` (a
time loop with a fixed step pays one triangular solve per step).

Reference: Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass
Transfer, 6th ed., section 5.10 (implicit finite-difference form).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg


@dataclass
class ThermalNetwork:
    """A linear network of lumped thermal nodes.

    Parameters
    ----------
    names : tuple of str
        Node names.
    capacity : numpy.ndarray
        Heat capacity per node [J/K], > 0.
    links : dict of (str, str) to float
        Conductance [W/K] between two nodes (each pair once).
    boundary : dict of str to float
        Conductance [W/K] from a node to the boundary (ambient).
    """

    names: tuple[str, ...]
    capacity: np.ndarray
    links: dict[tuple[str, str], float] = field(default_factory=dict)
    boundary: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.capacity = np.asarray(self.capacity, float)
        n = len(self.names)
        if self.capacity.shape != (n,) or not np.all(self.capacity > 0):
            raise ValueError("capacity needs one positive value per node")
        index = {name: i for i, name in enumerate(self.names)}
        K = np.zeros((n, n))
        for (a, b), g in self.links.items():
            i, j = index[a], index[b]
            if i == j or g < 0:
                raise ValueError(f"link {a}-{b}: a conductance >= 0 between two different nodes")
            K[i, i] += g
            K[j, j] += g
            K[i, j] -= g
            K[j, i] -= g
        self.g_boundary = np.zeros(n)
        for name, g in self.boundary.items():
            if g < 0:
                raise ValueError(f"boundary conductance of {name} must be >= 0")
            self.g_boundary[index[name]] = g
        self.K = K
        self.index = index
        self._factor: tuple[float, tuple] | None = None

    def step(self, T: np.ndarray, Q: np.ndarray, T_boundary: float, dt: float) -> np.ndarray:
        """Node temperatures [K] after ``dt`` [s] from ``T`` [K] with sources ``Q`` [W] held."""
        if self._factor is None or self._factor[0] != dt:
            A = np.diag(self.capacity / dt) + self.K + np.diag(self.g_boundary)
            self._factor = (dt, scipy.linalg.cho_factor(A))  # symmetric positive definite
        rhs = self.capacity * np.asarray(T, float) / dt + np.asarray(Q, float) + self.g_boundary * T_boundary
        return scipy.linalg.cho_solve(self._factor[1], rhs)

    def flows_in(self, T: np.ndarray, T_boundary: float) -> np.ndarray:
        """Net heat flow into each node [W] through the links and the boundary at temperatures ``T``."""
        T = np.asarray(T, float)
        return -self.K @ T + self.g_boundary * (T_boundary - T)
