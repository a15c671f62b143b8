"""Secondary streams of a refrigerant heat exchanger.

The refrigerant-side zone march (:mod:`evtms.hx.counterflow`) sees the other
stream only through a small protocol, :class:`SecondaryStream`: its mass
flow, its inlet state, its enthalpy-temperature relation and its thermal
resistance over the whole exchanger area. :class:`CoolantSide` is the liquid
water-glycol of a chiller.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from evtms.fluid import Coolant


class SecondaryStream(Protocol):
    """What the zone march needs to know of the secondary stream, per point.

    Attributes
    ----------
    mdot : numpy.ndarray
        Mass flow [kg/s], > 0.
    T_in : numpy.ndarray
        Inlet temperature [K].
    h_in : numpy.ndarray
        Inlet specific enthalpy [J/kg].
    R : numpy.ndarray
        Thermal resistance of this side over the whole exchanger area
        (convection and fouling) [K/W].
    """

    mdot: np.ndarray
    T_in: np.ndarray
    h_in: np.ndarray
    R: np.ndarray

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] at specific enthalpy ``h`` [J/kg]."""
        ...

    def capacity_rate(self) -> np.ndarray:
        """Heat capacity rate at the inlet, ``mdot c_p`` [W/K]."""
        ...


@dataclass
class CoolantSide:
    """A liquid coolant stream (water-glycol) through the exchanger.

    Attributes
    ----------
    coolant : Coolant
        Property tables of the coolant.
    mdot : numpy.ndarray
        Coolant mass flow [kg/s].
    T_in : numpy.ndarray
        Coolant inlet temperature [K].
    R : numpy.ndarray
        Coolant-side resistance over the whole area [K/W].
    """

    coolant: Coolant
    mdot: np.ndarray
    T_in: np.ndarray
    R: np.ndarray

    @property
    def h_in(self) -> np.ndarray:
        """Inlet specific enthalpy [J/kg]."""
        return self.coolant.enthalpy(self.T_in)

    def temperature(self, h: np.ndarray) -> np.ndarray:
        """Temperature [K] at specific enthalpy ``h`` [J/kg] (the coolant's table, exact inverse of its enthalpy)."""
        return self.coolant.temperature(h)

    def capacity_rate(self) -> np.ndarray:
        """``mdot c_p(T_in)`` [W/K]."""
        return self.mdot * self.coolant.properties(self.T_in)["CP"]
