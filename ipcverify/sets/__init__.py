"""Set shapes.

The ellipsoid an IPC predicts, the targets it is checked against (boxes, polytopes), and their exact
rational forms. One module per shape (``_ellipsoid``, ``_box``, ``_polytope``); the interface the
containment provers use is :class:`OuterSet` (``_outer``), and :class:`FacedSet` (``_faces``) for
sets given by faces, so a new shape is one module.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.sets._box import Box
    from ipcverify.sets._ellipsoid import Ellipsoid, single_ellipsoid, unit_ball_log_volume
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
    from ipcverify.sets._faces import FacedSet
    from ipcverify.sets._json import json_field, json_matrix, json_number, json_vector
    from ipcverify.sets._outer import OuterSet, register_shape, registered_shapes
    from ipcverify.sets._polytope import Polytope

__all__ = [
    "Box",
    "Ellipsoid",
    "ExactMatrix",
    "ExactVector",
    "FacedSet",
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
    "json_field",
    "json_matrix",
    "json_number",
    "json_vector",
    "matmul",
    "matvec",
    "register_shape",
    "registered_shapes",
    "single_ellipsoid",
    "sqnorm",
    "sqrt_lower",
    "sqrt_upper",
    "unit_ball_log_volume",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
