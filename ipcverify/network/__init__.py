"""The IPC networks.

Architectures and recipes, the torch modules, their float64 engines of record (one interface,
:class:`Engine`, chosen by :func:`engine_for`: the only switch on the network kind in ipcverify),
compiled kernels, the nonsingularity check, the per-kind Lipschitz bounds and ONNX graphs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.network._architecture import (
        ACTIVATIONS,
        DEFAULT_RECIPE,
        MAX_MEMBERS,
        RECIPES,
        ModelConfig,
    )
    from ipcverify.network._engine import (
        InferenceEngine,
        activate,
        chunk_rows,
    )
    from ipcverify.network._interface import (
        engine_for,
    )
    from ipcverify.network._kernels import (
        bias_activate,
        bias_skip_add,
        clamped_exp2,
        compiled,
        lowrank_one,
        rcond_lower_3,
    )
    from ipcverify.network._kind import (
        Engine,
    )
    from ipcverify.network._lipschitz_ball import (
        DEFAULT_RADIUS,
        ROUND_UP,
        DataBox,
        LipschitzBound,
        hidden_norm_bounds,
        jacobian_bound,
        operator_norm,
    )
    from ipcverify.network._lipschitz_lowrank import (
        ensemble_scores,
        score_gradient_bound,
        sound_lipschitz_lowrank,
    )
    from ipcverify.network._lowrank import (
        LowRankEnsemble,
        StackedLinear,
        StackedMLP,
    )
    from ipcverify.network._lowrank_engine import (
        LowRankEngine,
    )
    from ipcverify.network._modules import (
        IPCNetwork,
        Network,
        build_network,
    )
    from ipcverify.network._nonsingular import (
        nonsingular,
    )
    from ipcverify.network._scoring import (
        ScoredNetwork,
    )
    from ipcverify.network._weights import (
        NetworkWeights,
    )

__all__ = [
    "ACTIVATIONS",
    "DEFAULT_RADIUS",
    "DEFAULT_RECIPE",
    "MAX_MEMBERS",
    "RECIPES",
    "ROUND_UP",
    "DataBox",
    "Engine",
    "IPCNetwork",
    "InferenceEngine",
    "LipschitzBound",
    "LowRankEngine",
    "LowRankEnsemble",
    "ModelConfig",
    "Network",
    "NetworkWeights",
    "ScoredNetwork",
    "StackedLinear",
    "StackedMLP",
    "activate",
    "bias_activate",
    "bias_skip_add",
    "build_network",
    "chunk_rows",
    "clamped_exp2",
    "compiled",
    "engine_for",
    "ensemble_scores",
    "hidden_norm_bounds",
    "jacobian_bound",
    "lowrank_one",
    "nonsingular",
    "operator_norm",
    "rcond_lower_3",
    "score_gradient_bound",
    "sound_lipschitz_lowrank",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
