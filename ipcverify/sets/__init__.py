"""Set shapes.

The ellipsoid an IPC predicts, the targets it is checked against (boxes, polytopes), and their exact
rational forms.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.sets._exact import (
        ExactMatrix,
        ExactVector,
        decode_exact,
        dyadic,
        encode_exact,
        exact_matrix,
        exact_vector,
        float_down,
        float_up,
        inverse,
        is_positive_definite,
        is_positive_semidefinite,
        matmul,
        matvec,
        sqnorm,
        sqrt_lower,
        sqrt_upper,
    )
    from ipcverify.sets._shapes import (
        Box,
        Ellipsoid,
        OuterSet,
        Polytope,
        single_ellipsoid,
        unit_ball_log_volume,
    )

__all__ = [
    "Box",
    "Ellipsoid",
    "ExactMatrix",
    "ExactVector",
    "OuterSet",
    "Polytope",
    "decode_exact",
    "dyadic",
    "encode_exact",
    "exact_matrix",
    "exact_vector",
    "float_down",
    "float_up",
    "inverse",
    "is_positive_definite",
    "is_positive_semidefinite",
    "matmul",
    "matvec",
    "single_ellipsoid",
    "sqnorm",
    "sqrt_lower",
    "sqrt_upper",
    "unit_ball_log_volume",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
