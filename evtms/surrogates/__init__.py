"""Data-driven mode models of the thermal system (issue 16): scenario design, training, the model file.

- :mod:`evtms.surrogates.design`: which LUT simulations give training and held-out steps;
- :mod:`evtms.surrogates.train`: :func:`train_surrogates` (``evtms surrogate train``), :func:`fit_network`;
- :mod:`evtms.surrogates.io`: :func:`save_mode_models`, :func:`load_mode_models` (``docs/surrogate-format.md``).

Training needs scikit-learn (imported only when a network is fitted);
inference is :class:`evtms.system.mode_model.Network` (NumPy) or the loop's
compiled kernel.
"""

from evtms.surrogates.io import FILE_NAME, load_mode_models, save_mode_models
from evtms.surrogates.train import FitSettings, TrainReport, fit_network, train_surrogates

__all__ = [
    "FILE_NAME",
    "FitSettings",
    "TrainReport",
    "fit_network",
    "load_mode_models",
    "save_mode_models",
    "train_surrogates",
]
