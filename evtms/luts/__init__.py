"""LUT files: format schema, writing, opening with validation, interpolation, export, diff."""

from evtms.luts.interp import Interpolator
from evtms.luts.io import LutStorage, write_lut
from evtms.luts.validate import LutFormatError, LutMetadata, open_lut, read_lut_metadata

__all__ = ["Interpolator", "LutFormatError", "LutMetadata", "LutStorage", "open_lut", "read_lut_metadata", "write_lut"]
