"""ipcverify: learn and certify inverse perception contracts.

An inverse perception contract (IPC) maps a state ``x`` and a perceived value
``yhat`` to an ellipsoid that contains the true value ``y`` with high probability.

The pipeline's stages are packages, each re-exporting its public names (see
docs/architecture.md): :mod:`ipcverify.data`, :mod:`ipcverify.sets`,
:mod:`ipcverify.network`, :mod:`ipcverify.training`, :mod:`ipcverify.calibration`,
:mod:`ipcverify.guard`, :mod:`ipcverify.contract`, :mod:`ipcverify.io`,
:mod:`ipcverify.certification` and :mod:`ipcverify.decision`. The names a user needs
most are also here; they are imported when first used, so ``import ipcverify`` loads
no torch.

Examples
--------
>>> import ipcverify
>>> ipcverify.Box([-1.0, 0.0], [1.0, 2.0]).dim
2
>>> {"train", "calibrate", "certify", "IPCQuery"} <= set(ipcverify.__all__)
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import VERSION, lazy_exports
from ipcverify.errors import (
    DataError,
    InvalidInputError,
    IPCVerifyError,
    ModelFileError,
    SampleSizeError,
    SetError,
)

if TYPE_CHECKING:
    from ipcverify.calibration._global_scale import Global
    from ipcverify.calibration._grouped_spec import Grouped
    from ipcverify.calibration._mondrian import Mondrian
    from ipcverify.certification._certify import certify
    from ipcverify.contract._calibrate import calibrate
    from ipcverify.contract._model import IPCModel
    from ipcverify.data._dataset import PerceptionDataset, load_dataset
    from ipcverify.decision._landing_query import LandingQuery
    from ipcverify.decision._query import IPCQuery
    from ipcverify.demo import Example, example
    from ipcverify.guard._domain_spec import DomainSpec
    from ipcverify.io._modelio import load_model, save_model
    from ipcverify.sets._box import Box
    from ipcverify.sets._ellipsoid import Ellipsoid
    from ipcverify.sets._polytope import Polytope
    from ipcverify.training._train import train

__version__ = VERSION

__all__ = [
    "DomainSpec",
    "Global",
    "Grouped",
    "LandingQuery",
    "Mondrian",
    "Box",
    "DataError",
    "Ellipsoid",
    "Example",
    "IPCModel",
    "IPCQuery",
    "IPCVerifyError",
    "InvalidInputError",
    "ModelFileError",
    "PerceptionDataset",
    "Polytope",
    "SampleSizeError",
    "SetError",
    "__version__",
    "calibrate",
    "certify",
    "example",
    "load_dataset",
    "load_model",
    "save_model",
    "train",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
