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
    from ipcverify.sets._ellipsoid import Ellipsoid
    from ipcverify.sets._polytope import Polytope

__all__ = [
    "Box",
    "Ellipsoid",
    "Polytope",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
