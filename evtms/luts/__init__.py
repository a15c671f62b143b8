"""LUT files: format schema, writing, opening with validation, interpolation, export, diff."""

from evtms.luts.interp import Interpolator
from evtms.luts.validate import LutFormatError, open_lut

__all__ = ["Interpolator", "LutFormatError", "open_lut"]
