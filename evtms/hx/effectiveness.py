"""Effectiveness-NTU relations of two-stream exchangers (Incropera et al. 2007, Table 11.3)."""

from __future__ import annotations

import numpy as np


def crossflow_effectiveness(NTU: np.ndarray, Cr: np.ndarray) -> np.ndarray:
    """Effectiveness [1] of a cross-flow exchanger with both streams unmixed.

    .. math:: \\varepsilon = 1 - \\exp\\left[\\frac{NTU^{0.22}}{C_r}
              \\left(\\exp(-C_r NTU^{0.78}) - 1\\right)\\right]

    tending to ``1 - exp(-NTU)`` as ``Cr -> 0`` (a phase-changing stream).

    References
    ----------
    Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
    Fundamentals of Heat and Mass Transfer, 6th ed., Wiley, Table 11.3, eq. 11.32.
    """
    NTU = np.maximum(np.asarray(NTU, float), 0.0)
    Cr = np.clip(np.asarray(Cr, float), 0.0, 1.0)
    small = Cr < 1e-9
    Cr_safe = np.where(small, 1.0, Cr)
    eps = 1.0 - np.exp(NTU**0.22 / Cr_safe * np.expm1(-Cr_safe * NTU**0.78))
    return np.where(small, -np.expm1(-NTU), eps)


def counterflow_effectiveness(NTU: np.ndarray, Cr: np.ndarray) -> np.ndarray:
    """Effectiveness [1] of a counter-flow exchanger (Incropera et al. 2007, eq. 11.29b; ``Cr = 1``: NTU/(1+NTU))."""
    NTU, Cr = np.broadcast_arrays(np.asarray(NTU, float), np.asarray(Cr, float))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        e = np.exp(-NTU * (1.0 - Cr))
        general = (1.0 - e) / (1.0 - Cr * e)
    return np.where(np.abs(1.0 - Cr) < 1e-9, NTU / (1.0 + NTU), general)


def crossflow_one_mixed_effectiveness(NTU: np.ndarray, Cr: np.ndarray, mixed_is_min: np.ndarray) -> np.ndarray:
    """Effectiveness [1] of a cross-flow exchanger with one stream mixed and the other unmixed.

    With the mixed stream the one of larger capacity rate (``mixed_is_min`` false),

    .. math:: \\varepsilon = \\frac{1}{C_r}\\left(1 - \\exp\\left[-C_r\\left(1 - e^{-NTU}\\right)\\right]\\right),

    and with the mixed stream the one of smaller capacity rate,

    .. math:: \\varepsilon = 1 - \\exp\\left[-\\frac{1}{C_r}\\left(1 - e^{-C_r NTU}\\right)\\right];

    both tend to ``1 - exp(-NTU)`` as ``Cr -> 0`` and coincide at ``Cr = 1``, so the
    choice of form is continuous where the two capacity rates cross.

    Parameters
    ----------
    NTU : array_like
        ``UA / C_min`` [1], >= 0.
    Cr : array_like
        ``C_min / C_max`` [1], in [0, 1].
    mixed_is_min : array_like of bool
        The mixed stream is the one of smaller capacity rate.

    References
    ----------
    Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007).
    Fundamentals of Heat and Mass Transfer, 6th ed., Wiley, Table 11.3, eqs. 11.33 and 11.34.
    """
    NTU = np.maximum(np.asarray(NTU, float), 0.0)
    Cr = np.clip(np.asarray(Cr, float), 0.0, 1.0)
    small = Cr < 1e-9
    Cr_safe = np.where(small, 1.0, Cr)
    max_mixed = -np.expm1(-Cr_safe * -np.expm1(-NTU)) / Cr_safe
    min_mixed = -np.expm1(np.expm1(-Cr_safe * NTU) / Cr_safe)
    eps = np.where(np.asarray(mixed_is_min, bool), min_mixed, max_mixed)
    return np.where(small, -np.expm1(-NTU), eps)
