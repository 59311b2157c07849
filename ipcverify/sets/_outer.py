"""The interface of an outer set: what the containment provers ask of a shape.

A containment question is ``inner ⊆ outer`` with an :class:`~ipcverify.sets.Ellipsoid` inside.
The provers (:mod:`ipcverify.decision.containment`) never ask which class the outer set is;
they ask the set, through :class:`OuterSet`:

* :attr:`OuterSet.kind` and :meth:`~OuterSet.to_set_dict` / :meth:`~OuterSet.from_set_dict` --
  its JSON form (``{"type": kind, ...}``, ``docs/containment.md``); :func:`register_shape`
  makes ``from_set_dict`` reachable from :func:`ipcverify.decision.containment.set_from_dict`;
* :attr:`OuterSet.proof_form` -- which family of proofs applies: ``"faces"`` (the set is
  ``{y : A y <= b}``: closed form, SOCP and the per-face S-lemma; the shape is a
  :class:`~ipcverify.sets.FacedSet`) or ``"ellipsoid"`` (the S-lemma LMI);
* :attr:`OuterSet.methods` -- the proof methods that apply, the first being the default;
* :meth:`OuterSet.outside_exact` -- exact membership, for refutation witnesses;
* :meth:`OuterSet.as_outer` -- the shape's own check that it can be an outer set.

A new shape is one file: a frozen dataclass that subclasses :class:`~ipcverify.sets.FacedSet`
(it need only give ``faces()``; the face arithmetic has defaults) or :class:`OuterSet`.

Examples
--------
>>> from ipcverify.sets import Box
>>> b = Box([0.0], [1.0])
>>> isinstance(b, OuterSet), b.kind, b.proof_form, b.methods[0]
(True, 'box', 'faces', 'closed-form')
>>> list(registered_shapes())
['box', 'polytope', 'ellipsoid']
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any, ClassVar, TypeVar


class OuterSet(ABC):
    """A set that an ellipsoid's containment is proved against (see the module docstring).

    Subclasses are frozen dataclasses that validate themselves; they set the three class
    attributes and implement the abstract methods.
    """

    #: The ``"type"`` of the set's JSON form (``"box"``, ``"polytope"``, ``"ellipsoid"``, ...).
    kind: ClassVar[str]
    #: The family of proofs that applies: ``"faces"`` or ``"ellipsoid"``.
    proof_form: ClassVar[str]
    #: The values of :class:`~ipcverify.decision.containment.Method` that apply; the first is the default.
    methods: ClassVar[tuple[str, ...]]

    @property
    @abstractmethod
    def dim(self) -> int:
        """Ambient dimension ``n``."""

    @abstractmethod
    def to_set_dict(self) -> dict[str, Any]:
        """JSON-ready form ``{"type": kind, ...}`` (floats round-trip exactly through :mod:`json`)."""

    @classmethod
    @abstractmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> OuterSet:
        """Inverse of :meth:`to_set_dict`; errors name the field (``where`` is its path prefix)."""

    @abstractmethod
    def outside_exact(self, y: Sequence[Fraction]) -> bool:
        """Exactly: the point ``y`` (rationals) is not in the set."""

    def as_outer(self, what: str) -> OuterSet:
        """The set itself if it can be an outer set, else a :class:`~ipcverify.errors.SetError` naming it."""
        return self


_S = TypeVar("_S", bound=type[OuterSet])

# The built-in kinds first, in the order error messages list them; new kinds follow in the order registered.
_REGISTRY: dict[str, type[OuterSet] | None] = dict.fromkeys(("box", "polytope", "ellipsoid"))
_BUILTIN = ("ipcverify.sets._box", "ipcverify.sets._polytope", "ipcverify.sets._ellipsoid")


def register_shape(cls: _S) -> _S:
    """Class decorator: make ``cls.from_set_dict`` the reader of JSON sets of type ``cls.kind``."""
    _REGISTRY[cls.kind] = cls
    return cls


def registered_shapes() -> dict[str, type[OuterSet]]:
    """``{kind: shape class}`` for every registered shape (the built-in ones always)."""
    for name in _BUILTIN:
        importlib.import_module(name)
    return {k: v for k, v in _REGISTRY.items() if v is not None}
