"""Set shapes are objects: no switch on a shape outside ipcverify.sets, and a new shape is one class.

* The provers ask the shape (:class:`ipcverify.sets.OuterSet`, :class:`ipcverify.sets.FacedSet`)
  instead of switching on its class: an ``isinstance`` on ``Box``, ``Polytope`` or ``Ellipsoid``
  outside :mod:`ipcverify.sets` may only validate an argument, in the form
  ``if not isinstance(x, T) [or ...]: raise ...``. The check is ast-based; a planted switch
  shows that it fails.
* Shapes defined only here -- a half-space and a box given by its centre and half-widths --
  are proved, refuted and re-checked by :func:`ipcverify.decision.containment.prove` through the
  interface alone, with the same answers as the built-in shapes and an exact oracle.
"""

from __future__ import annotations

import ast
import json
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import ipcverify.sets._outer as outer_module
from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._certificate import certificate_from_dict
from ipcverify.decision.containment._io import set_from_dict, set_to_dict
from ipcverify.decision.containment._margin import contained_float
from ipcverify.decision.containment._rounding import support_slack_bounds
from ipcverify.errors import SetError
from ipcverify.sets import Box, Ellipsoid
from ipcverify.sets._exact import exact_matrix, exact_vector, inverse, sqnorm
from ipcverify.sets._faces import FacedSet
from ipcverify.sets._json import json_field, json_number, json_vector
from ipcverify.sets._outer import OuterSet

ROOT = Path(__file__).resolve().parents[3]
SHAPES = {"Box", "Polytope", "Ellipsoid"}
SCANNED = ("ipcverify", "case_studies", "benchmarks", "docgen")


# ---------------------------------------------------------------------------- the switch check
def _shape_names(call: ast.Call) -> set[str]:
    """The shape classes named in the second argument of an ``isinstance`` call."""
    if len(call.args) < 2:
        return set()
    names = {n.id for n in ast.walk(call.args[1]) if isinstance(n, ast.Name)}
    names |= {n.attr for n in ast.walk(call.args[1]) if isinstance(n, ast.Attribute)}
    return names & SHAPES


def _validations(tree: ast.AST) -> set[int]:
    """ids of the ``isinstance`` calls in ``if not isinstance(x, T) [or ...]: raise ...`` (nothing else)."""
    allowed: set[int] = set()
    for node in ast.walk(tree):
        if not (isinstance(node, ast.If) and not node.orelse and len(node.body) == 1):
            continue
        if not isinstance(node.body[0], ast.Raise):
            continue
        test = node.test
        operands = test.values if isinstance(test, ast.BoolOp) and isinstance(test.op, ast.Or) else [test]
        for op in operands:
            if (
                isinstance(op, ast.UnaryOp)
                and isinstance(op.op, ast.Not)
                and isinstance(op.operand, ast.Call)
            ):
                allowed.add(id(op.operand))
    return allowed


def shape_switches(source: str) -> list[int]:
    """Line numbers of the ``isinstance`` calls on a set shape that do more than validate."""
    tree = ast.parse(source)
    allowed = _validations(tree)
    return sorted(
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "isinstance"
        and _shape_names(node)
        and id(node) not in allowed
    )


def _library_files() -> list[Path]:
    files = [p for d in SCANNED for p in sorted((ROOT / d).rglob("*.py"))]
    return [p for p in files if (ROOT / "ipcverify" / "sets") not in p.parents]


def test_no_switch_on_a_set_shape_outside_the_sets_package():
    files = _library_files()
    assert len(files) > 50  # the scan sees the library, not an empty directory
    bad = {
        str(p.relative_to(ROOT)): lines
        for p in files
        if (lines := shape_switches(p.read_text(encoding="utf-8")))
    }
    assert not bad, f"isinstance on a set shape selects behaviour in {bad}: ask the shape (OuterSet) instead"


PLANTED = """
def slack(outer, inner):
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid")
    if not isinstance(outer, Box) or outer.dim != 3:
        raise SetError("a 3-D box")
    if isinstance(outer, Box):                                   # line 7: a switch
        return outer.upper
    kind = "box" if isinstance(outer, sets.Box) else "other"    # line 9: a switch
    if not isinstance(outer, (Box, Polytope)):                   # line 10: not a raise
        outer = Box(outer.lower, outer.upper)
    return [isinstance(outer, Polytope)]                         # line 12: a switch
"""


def test_the_switch_check_finds_planted_switches_and_passes_validations():
    assert shape_switches(PLANTED) == [7, 9, 10, 12]
    assert shape_switches("if not isinstance(x, Box):\n    raise SetError('x')\n") == []
    assert shape_switches("if isinstance(x, Fraction):\n    y = x\n") == []  # not a shape


# ----------------------------------------------------------------------- shapes defined only here
@dataclass(frozen=True, eq=False)
class HalfSpace(FacedSet):
    """``{y : normal . y <= offset}``: one face; all the arithmetic is FacedSet's default."""

    kind: ClassVar[str] = "halfspace"

    normal: np.ndarray
    offset: float

    def __post_init__(self) -> None:
        a = np.array(self.normal, dtype=np.float64)
        if a.ndim != 1 or not np.isfinite(a).all() or not np.isfinite(self.offset):
            raise SetError("a half-space needs a finite normal vector and offset")
        object.__setattr__(self, "normal", a)
        object.__setattr__(self, "offset", float(self.offset))

    @property
    def dim(self) -> int:
        return int(self.normal.shape[0])

    def faces(self) -> tuple[np.ndarray, np.ndarray]:
        return self.normal[None, :], np.array([self.offset])

    def to_set_dict(self) -> dict[str, Any]:
        return {"type": self.kind, "normal": self.normal.tolist(), "offset": self.offset}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> HalfSpace:
        normal = json_vector(json_field(d, "normal", where), f"{where}normal")
        return cls(np.array(normal), json_number(json_field(d, "offset", where), f"{where}offset"))


@dataclass(frozen=True, eq=False)
class CentredBox(FacedSet):
    """A box given by its centre and half-widths, faces ``+e_i`` then ``-e_i`` (the dense default)."""

    kind: ClassVar[str] = "centred-box"

    centre: np.ndarray
    half_widths: np.ndarray

    @property
    def dim(self) -> int:
        return int(self.centre.shape[0])

    def faces(self) -> tuple[np.ndarray, np.ndarray]:
        eye = np.eye(self.dim)
        return np.vstack([eye, -eye]), np.concatenate(
            [self.centre + self.half_widths, self.half_widths - self.centre]
        )

    def to_set_dict(self) -> dict[str, Any]:
        return {"type": self.kind, "centre": self.centre.tolist(), "half_widths": self.half_widths.tolist()}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> CentredBox:
        raise NotImplementedError  # not registered: never read


@dataclass(frozen=True, eq=False)
class Cone(OuterSet):
    """A shape with a proof form no prover handles: prove must say so, not guess."""

    kind: ClassVar[str] = "cone"
    proof_form: ClassVar[str] = "second-order-cone"
    methods: ClassVar[tuple[str, ...]] = ("sdp",)

    n: int

    @property
    def dim(self) -> int:
        return self.n

    def to_set_dict(self) -> dict[str, Any]:
        return {"type": self.kind, "n": self.n}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> Cone:
        return cls(int(d["n"]))

    def outside_exact(self, y: Any) -> bool:
        return False


def _exactly_inside_halfspace(e: Ellipsoid, h: HalfSpace) -> bool:
    """Oracle, independent of the provers: ``b - a.c >= 0`` and ``(b - a.c)^2 >= ||C^-T a||^2`` exactly."""
    c, C = exact_vector(e.centers[0]), exact_matrix(e.shapes[0])
    a, b = exact_vector(h.normal), Fraction(h.offset)
    ci = inverse(C)
    z = [sum((a[k] * ci[k][i] for k in range(len(a))), Fraction(0)) for i in range(len(a))]
    s = b - sum((x * y for x, y in zip(a, c, strict=True)), Fraction(0))
    return s >= 0 and s * s >= sqnorm(z)


def _random_case(rng: np.random.Generator, n: int) -> tuple[Ellipsoid, HalfSpace]:
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    e = Ellipsoid(rng.standard_normal(n), q * np.exp(rng.uniform(-1.0, 2.0, n)))
    a = rng.standard_normal(n)
    support = float(a @ e.centers[0] + np.linalg.norm(np.linalg.solve(e.shapes[0].T, a)))
    return e, HalfSpace(a, support + float(rng.choice([-1e-3, -1e-12, 0.0, 1e-12, 1e-3])))


@pytest.mark.parametrize("method", ["closed-form", "socp", "sdp"])
def test_a_half_space_defined_only_here_is_proved_through_the_interface(method):
    rng = np.random.default_rng(28)
    statuses = []
    for _ in range(25):
        e, h = _random_case(rng, int(rng.integers(1, 5)))
        cert = prove(e, h, method=method)
        check = verify(cert)
        assert check.ok and check.status is cert.status
        if cert.status is not Status.UNKNOWN:  # the exact oracle agrees with every decided answer
            assert (cert.status is Status.PROVEN) == _exactly_inside_halfspace(e, h)
        if cert.status is Status.REFUTED:
            assert h.outside_exact(list(cert.witness or ()))
        statuses.append(cert.status)
    assert statuses.count(Status.PROVEN) >= 5 and statuses.count(Status.REFUTED) >= 5
    if method == "closed-form":  # exact: never UNKNOWN
        assert Status.UNKNOWN not in statuses


def test_the_float_margins_and_their_rounding_bounds_work_for_a_new_shape():
    rng = np.random.default_rng(7)
    e, h = _random_case(rng, 3)
    batch = Ellipsoid(np.stack([e.centers[0], e.centers[0] + 10.0]), np.stack([e.shapes[0]] * 2))
    sb = support_slack_bounds(batch, h)
    assert sb.slack.shape == (2, 1) and np.isfinite(sb.bound).all()
    assert contained_float(batch, h).tolist() == (sb.slack[:, 0] >= 0).tolist()
    # the rigorous bound covers the exact slack
    exact = [_exactly_inside_halfspace(Ellipsoid(batch.centers[i], batch.shapes[i]), h) for i in range(2)]
    for i in range(2):
        if sb.proven()[i]:
            assert exact[i]
        if sb.refuted()[i]:
            assert not exact[i]


def test_a_centred_box_gets_the_same_answers_as_the_box():
    rng = np.random.default_rng(3)
    for k in range(30):
        n = int(rng.integers(1, 4))
        e = Ellipsoid(rng.standard_normal(n) / 8, np.diag(rng.uniform(1.0, 4.0, n)))
        # dyadic centre and half-widths: centre +- half-width is exact, so the two boxes are one set
        centre = np.round(rng.standard_normal(n) * 64) / 1024
        half = np.round(e.half_widths()[0] * 1024 + rng.choice([-2.0, 0.0, 2.0], n)) / 1024 + np.abs(centre)
        box = Box(centre - half, centre + half)
        toy = CentredBox(centre, half)
        for method in ("closed-form", "sdp"):
            mine, theirs = prove(e, toy, method=method), prove(e, box, method=method)
            assert mine.status is theirs.status, (k, method)
            assert verify(mine).status is mine.status


def test_a_new_shape_round_trips_through_json_once_registered(monkeypatch):
    h = HalfSpace(np.array([1.0, 2.0]), 3.5)
    e = Ellipsoid(np.zeros(2), np.eye(2))
    cert = prove(e, h)
    assert set_to_dict(h) == {"type": "halfspace", "normal": [1.0, 2.0], "offset": 3.5}
    with pytest.raises(Exception, match="is not one of 'box', 'polytope', 'ellipsoid'$"):
        set_from_dict(set_to_dict(h))
    monkeypatch.setitem(outer_module._REGISTRY, "halfspace", HalfSpace)
    back = certificate_from_dict(json.loads(json.dumps(cert.to_dict())))
    assert isinstance(back.outer, HalfSpace) and back.outer.offset == 3.5
    assert back.status is cert.status is Status.PROVEN and verify(back).ok


def test_a_shape_without_a_prover_is_refused():
    e = Ellipsoid(np.zeros(2), np.eye(2))
    with pytest.raises(SetError, match="no sdp prover for sets of proof form 'second-order-cone'"):
        prove(e, Cone(2))
    with pytest.raises(SetError, match="outer must be"):
        prove(e, object())  # type: ignore[arg-type]
