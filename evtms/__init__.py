"""evtms: R134a refrigerant-circuit benches, N-D lookup tables and cycle models.

Importing the package is cheap on purpose: CoolProp, xarray and matplotlib
load only inside the functions that need them, so ``evtms --help`` is fast.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
