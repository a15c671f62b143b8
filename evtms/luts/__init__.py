"""LUT files: format schema, writing, opening with validation, interpolation, export, diff, the store."""

from evtms.luts.interp import Interpolator
from evtms.luts.io import LutStorage, MapTable, write_lut, write_map_lut
from evtms.luts.store import LutStore
from evtms.luts.validate import LutFormatError, LutMetadata, open_lut, read_lut_metadata, read_map_lut

__all__ = [
    "Interpolator",
    "LutFormatError",
    "LutMetadata",
    "LutStorage",
    "LutStore",
    "MapTable",
    "open_lut",
    "read_lut_metadata",
    "read_map_lut",
    "write_lut",
    "write_map_lut",
]
