"""The working arrays of a cycle solve: one flat array per result variable, revised in place.

While it solves, the solver keeps the result variables as one dict of
arrays, revised point by point (a valve's limits solved again, a point
marked invalid with :func:`mark_invalid`).
"""

from __future__ import annotations

import numpy as np


def mark_invalid(res: dict, where: np.ndarray, status: int, reasons) -> None:
    """Mark the points ``where`` (mask or indices) of the working arrays ``res`` ``status`` with
    their ``reasons``, their states NaN (in place)."""
    res["status"][where] = status
    res["reason"][where] = reasons
    for v in res.values():
        if v.dtype.kind == "f":
            v[where] = np.nan
