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
        LOGDIAG_CLAMP,
        MAX_MEMBERS,
        RECIPES,
        ModelConfig,
    )
    from ipcverify.network._engine import (
        CACHE_BYTES,
        CHUNK,
        InferenceEngine,
        activate,
        chunk_rows,
        float64_array,
    )
    from ipcverify.network._interface import (
        Engine,
        engine_for,
        is_network,
    )
    from ipcverify.network._kernels import (
        ACTIVATION_CODES,
        bias_activate,
        bias_skip_add,
        clamped_exp2,
        compiled,
        lowrank_one,
        lowrank_sets,
        rcond_lower_3,
        standardise,
    )
    from ipcverify.network._lipschitz_ball import (
        DEFAULT_RADIUS,
        FLOAT_MARGIN,
        ROUND_UP,
        SVD_MARGIN,
        DataBox,
        LipschitzBound,
        check_radius,
        hidden_norm_bounds,
        jacobian_bound,
        operator_norm,
    )
    from ipcverify.network._lipschitz_lowrank import (
        ensemble_gradient_norms,
        ensemble_scores,
        score_gradient_bound,
        sound_lipschitz_lowrank,
    )
    from ipcverify.network._lipschitz_mlp import (
        mlp_gradient_norms,
        sound_lipschitz_mlp,
    )
    from ipcverify.network._lowrank import (
        SIGMA_FLOOR,
        LowRankEnsemble,
        StackedLinear,
        StackedMLP,
        fit_linear_stage,
        member_covariances,
        moment_match,
    )
    from ipcverify.network._lowrank_engine import (
        LowRankEngine,
        cholesky_lower,
        lower_inverse,
    )
    from ipcverify.network._modules import (
        IPCNetwork,
        Network,
        build_network,
    )
    from ipcverify.network._nonsingular import (
        CheckedEllipsoid,
        checked_ellipsoid,
        nonsingular,
        svd_rcond,
    )
    from ipcverify.network._onnx_lowrank import (
        lowrank_nodes,
    )
    from ipcverify.network._onnx_mlp import (
        mlp_nodes,
    )
    from ipcverify.network._scoring import (
        ScoredNetwork,
    )
    from ipcverify.network._weights import (
        NetworkWeights,
        state_layout,
        weights_and_network,
    )

__all__ = [
    "ACTIVATIONS",
    "ACTIVATION_CODES",
    "CACHE_BYTES",
    "CHUNK",
    "DEFAULT_RADIUS",
    "DEFAULT_RECIPE",
    "FLOAT_MARGIN",
    "LOGDIAG_CLAMP",
    "MAX_MEMBERS",
    "RECIPES",
    "ROUND_UP",
    "SIGMA_FLOOR",
    "SVD_MARGIN",
    "CheckedEllipsoid",
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
    "check_radius",
    "checked_ellipsoid",
    "cholesky_lower",
    "chunk_rows",
    "clamped_exp2",
    "compiled",
    "engine_for",
    "ensemble_gradient_norms",
    "ensemble_scores",
    "fit_linear_stage",
    "float64_array",
    "hidden_norm_bounds",
    "is_network",
    "jacobian_bound",
    "lower_inverse",
    "lowrank_nodes",
    "lowrank_one",
    "lowrank_sets",
    "member_covariances",
    "mlp_gradient_norms",
    "mlp_nodes",
    "moment_match",
    "nonsingular",
    "operator_norm",
    "rcond_lower_3",
    "score_gradient_bound",
    "sound_lipschitz_lowrank",
    "sound_lipschitz_mlp",
    "standardise",
    "state_layout",
    "svd_rcond",
    "weights_and_network",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
