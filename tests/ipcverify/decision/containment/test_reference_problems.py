"""Reference problems, certificates and error handling of ipcverify.decision.containment."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

import ipcverify.decision.containment._sdp as sdp_module
import ipcverify.decision.containment._socp as socp_module
from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._certificate import ContainmentCertificate, certificate_from_dict
from ipcverify.decision.containment._io import problem_from_dict, set_from_dict
from ipcverify.decision.containment._margin import contained_float, support_slack
from ipcverify.decision.containment._prove import prove_batch
from ipcverify.decision.containment._status import Method
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._polytope import Polytope

F = Fraction


def _inside_exact(e: Ellipsoid, y) -> bool:
    c = [F(float(v)) for v in e.centers[0]]
    d = [F(v) - ci for v, ci in zip(y, c, strict=True)]
    rows = [[F(float(v)) for v in r] for r in e.shapes[0]]
    return sum(sum(a * b for a, b in zip(r, d, strict=True)) ** 2 for r in rows) <= 1


# ------------------------------------------------------------ reference problems
def test_axis_aligned_ellipsoid_touching_box_is_proven_with_zero_margin():
    c = np.array([1.0, -2.0, 0.5])
    e = Ellipsoid(c, np.diag([2.0, 4.0, 8.0]))  # semi-axes 0.5, 0.25, 0.125 exactly
    h = np.array([0.5, 0.25, 0.125])
    cert = prove(e, Box(c - h, c + h))
    assert cert.status is Status.PROVEN
    assert cert.margin == 0.0
    assert verify(cert).status is Status.PROVEN


@pytest.mark.parametrize("method", ["closed-form", "sdp"])
@pytest.mark.parametrize("coord", [0, 1, 2])
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_box_one_ulp_too_small_is_refuted_with_exact_touching_witness(coord, side, method):
    c = np.array([1.0, -2.0, 0.5])
    e = Ellipsoid(c, np.diag([2.0, 4.0, 8.0]))
    h = np.array([0.5, 0.25, 0.125])
    lo, up = c - h, c + h
    if side == "upper":
        up[coord] = math.nextafter(up[coord], -math.inf)
    else:
        lo[coord] = math.nextafter(lo[coord], math.inf)
    cert = prove(e, Box(lo, up), method=method)
    assert cert.status is Status.REFUTED
    expected = c.copy()
    expected[coord] += h[coord] if side == "upper" else -h[coord]
    assert cert.witness_floats() == tuple(expected)  # the touching point, exactly
    assert verify(cert).status is Status.REFUTED


@pytest.mark.parametrize("method", ["closed-form", "sdp"])
def test_halfspace_at_rounded_sqrt2(method):
    # float(sqrt 2) > sqrt 2, so the unit disc lies in x + y <= fl(sqrt 2); one ulp less, not
    disc = Ellipsoid(np.zeros(2), np.eye(2))
    s = math.sqrt(2.0)
    assert F(s) ** 2 > 2
    assert prove(disc, Polytope([[1.0, 1.0]], [s]), method=method).status is Status.PROVEN
    cert = prove(disc, Polytope([[1.0, 1.0]], [math.nextafter(s, 0.0)]), method=method)
    assert cert.status is Status.REFUTED
    assert verify(cert).status is Status.REFUTED
    assert _inside_exact(disc, cert.witness)


@pytest.mark.parametrize(
    ("r_in", "r_out", "expected"),
    [
        (0.5, 1.0, Status.PROVEN),
        (1.0, 1.0, Status.PROVEN),  # identical balls: tight, still proven exactly
        (0.25, 4.0, Status.PROVEN),
        (1.0, 0.5, Status.REFUTED),
        (1.0, math.nextafter(1.0, 0.0), Status.REFUTED),  # one ulp too small
    ],
    ids=["half", "identical", "quarter-in-4", "larger", "one-ulp-larger"],
)
def test_concentric_balls(r_in, r_out, expected):
    c = np.array([0.3, -1.0, 2.0])
    inner = Ellipsoid(c, np.eye(3) / r_in)
    outer = Ellipsoid(c, np.eye(3) / r_out)
    cert = prove(inner, outer)
    assert cert.status is expected
    v = verify(cert)
    assert v.ok and v.status is expected


def test_identical_shapes_three_is_tight_and_proven():
    e = Ellipsoid(np.zeros(3), 3.0 * np.eye(3))
    assert prove(e, e).status is Status.PROVEN
    smaller = Ellipsoid(np.zeros(3), math.nextafter(3.0, 4.0) * np.eye(3))
    assert prove(e, smaller).status is Status.REFUTED


def test_internally_tangent_balls_are_proven():
    inner = Ellipsoid([0.5, 0.0], 2.0 * np.eye(2))  # radius 1/2 at (1/2, 0)
    outer = Ellipsoid([0.0, 0.0], np.eye(2))
    cert = prove(inner, outer)
    assert cert.status is Status.PROVEN
    assert verify(cert).status is Status.PROVEN


def test_sdp_multipliers_for_concentric_balls_are_the_known_optimum():
    # max_{|y| <= 1/2} |y|^2 = 1/4: tau* = lambda* = 1/4
    cert = prove(Ellipsoid(np.zeros(2), 2 * np.eye(2)), Ellipsoid(np.zeros(2), np.eye(2)))
    assert cert.method is Method.SDP
    assert abs(cert.margin - 0.75) < 1e-7
    assert cert.multipliers["tau"][0] <= 1
    assert abs(float(cert.multipliers["lambda"][0]) - 0.25) < 1e-6


def test_socp_agrees_on_reference_problems():
    c = np.array([1.0, -2.0, 0.5])
    e = Ellipsoid(c, np.diag([2.0, 4.0, 8.0]))
    h = np.array([0.5, 0.25, 0.125])
    cert = prove(e, Box(c - 1.01 * h, c + 1.01 * h), method="socp")
    assert cert.status is Status.PROVEN and cert.method is Method.SOCP
    assert verify(cert).status is Status.PROVEN
    cert = prove(e, Box(c - 0.9 * h, c + 0.9 * h), method=Method.SOCP)
    assert cert.status is Status.REFUTED
    assert verify(cert).status is Status.REFUTED


# ------------------------------------------------------------------- batches
def test_batch_float_slack_matches_exact_certificates():
    rng = np.random.default_rng(3)
    b = 200
    shapes = rng.standard_normal((b, 3, 3)) + 3 * np.eye(3)
    e = Ellipsoid(rng.normal(scale=0.2, size=(b, 3)), shapes)
    box = Box([-0.6, -0.6, -0.6], [0.6, 0.6, 0.6])
    slack = support_slack(e, box)
    a, bb = box.faces()
    np.testing.assert_allclose(slack, support_slack(e, Polytope(a, bb)), atol=1e-12)
    certs = prove_batch(e, box)
    exact = np.array([c.status is Status.PROVEN for c in certs])
    assert not any(c.status is Status.UNKNOWN for c in certs)
    decisive = np.abs(slack).min(axis=1) > 1e-9
    assert decisive.sum() > 150
    np.testing.assert_array_equal(contained_float(e, box)[decisive], exact[decisive])
    assert 0 < exact.sum() < b  # both outcomes occur


def test_support_slack_large_batch_shape():
    rng = np.random.default_rng(4)
    e = Ellipsoid(rng.normal(size=(1000, 3)), np.tile(np.eye(3) * 10, (1000, 1, 1)))
    s = support_slack(e, Box(-np.ones(3), np.ones(3)))
    assert s.shape == (1000, 6)


# --------------------------------------------------------------- certificates
def _json_round_trip(cert: ContainmentCertificate) -> ContainmentCertificate:
    return certificate_from_dict(json.loads(json.dumps(cert.to_dict())))


@pytest.mark.parametrize("method", [None, "socp"])
def test_certificate_round_trips_exactly(method):
    rng = np.random.default_rng(5)
    e = Ellipsoid(rng.normal(size=3), rng.normal(size=(3, 3)) + 4 * np.eye(3))
    for outer in (Box(-np.ones(3), np.ones(3)), Polytope(rng.normal(size=(5, 3)), np.ones(5))):
        cert = prove(e, outer, method=method)
        back = _json_round_trip(cert)
        assert back.to_dict() == cert.to_dict()
        np.testing.assert_array_equal(back.inner.shapes, cert.inner.shapes)
        assert verify(back).status is verify(cert).status


def test_rational_witness_round_trips():
    disc = Ellipsoid(np.zeros(2), np.eye(2))
    cert = prove(disc, Polytope([[1.0, 1.0]], [math.nextafter(math.sqrt(2), 0.0)]))
    d = cert.to_dict()
    assert all(isinstance(v, str) and "/" in v for v in d["witness"])
    back = _json_round_trip(cert)
    assert back.witness == cert.witness
    assert verify(back).status is Status.REFUTED


def test_sdp_certificate_round_trips():
    cert = prove(Ellipsoid(np.zeros(3), 2 * np.eye(3)), Ellipsoid(np.ones(3) * 0.1, np.eye(3)))
    back = _json_round_trip(cert)
    assert back.multipliers == cert.multipliers
    assert verify(back).status is Status.PROVEN


def test_status_text_says_what_to_do():
    assert "witness" in str(Status.REFUTED)
    assert str(Status.UNKNOWN).startswith("UNKNOWN: ")
    assert "NOT established" in Status.UNKNOWN.advice


# ------------------------------------------------------------------- tampering
def _proven_box_cert() -> ContainmentCertificate:
    c = np.zeros(2)
    return prove(Ellipsoid(c, np.diag([2.0, 4.0])), Box([-0.5, -0.25], [0.5, 0.25]))


def test_tampered_closed_form_certificate_fails_verification():
    d = _proven_box_cert().to_dict()
    d["outer"]["upper"][1] = 0.24
    v = verify(certificate_from_dict(d))
    assert v.status is Status.UNKNOWN and not v.ok
    assert "face" in v.reason


def test_tampered_sdp_certificate_fails_verification():
    cert = prove(Ellipsoid(np.zeros(2), 2 * np.eye(2)), Ellipsoid(np.zeros(2), np.eye(2)))
    d = cert.to_dict()
    d["multipliers"]["tau"] = [0.2]  # below the true optimum 1/4
    assert not verify(certificate_from_dict(d)).ok
    d["multipliers"]["tau"] = [1.5]
    assert "tau" in verify(certificate_from_dict(d)).reason
    d["multipliers"] = {"lambda": [-1.0], "tau": [1.0]}
    assert "lambda" in verify(certificate_from_dict(d)).reason


def test_tampered_witness_fails_verification():
    cert = prove(Ellipsoid(np.zeros(2), np.eye(2)), Box([-0.5, -0.5], [0.5, 0.5]))
    assert cert.status is Status.REFUTED
    d = cert.to_dict()
    d["witness"] = [0.0, 0.0]  # inside both sets
    v = verify(certificate_from_dict(d))
    assert v.status is Status.UNKNOWN and "outside" in v.reason
    d["witness"] = [5.0, 0.0]  # outside the inner set
    assert "inside the inner" in verify(certificate_from_dict(d)).reason


def test_unknown_claims_are_always_consistent():
    cert = _proven_box_cert()
    unknown = ContainmentCertificate(cert.inner, cert.outer, cert.method, Status.UNKNOWN)
    v = verify(unknown)
    assert v.ok and v.status is Status.UNKNOWN


# ---------------------------------------------------- solver status is respected
class _FakeValue:
    def __init__(self, value):
        self.value = value


class _FakeProblem:
    """Mimics a cvxpy problem whose solve returns a fixed status."""

    def __init__(self, status):
        self.status = status

    def solve(self, **kwargs):
        return None


def test_sdp_not_optimal_is_never_proven(monkeypatch):
    # a valid proof exists (lam = tau = 1/4), but the solver says optimal_inaccurate
    def fake(n):
        return (
            _FakeProblem("optimal_inaccurate"),
            _FakeValue(0.25),
            _FakeValue(0.25),
            _FakeValue(None),
        )

    monkeypatch.setattr(sdp_module, "sdp_problem", fake)
    cert = prove(Ellipsoid(np.zeros(2), 2 * np.eye(2)), Ellipsoid(np.zeros(2), np.eye(2)))
    assert cert.status is Status.UNKNOWN
    assert "optimal_inaccurate" in cert.detail


def test_sdp_not_optimal_may_still_refute_with_exact_witness(monkeypatch):
    def fake(n):
        return _FakeProblem("infeasible"), _FakeValue(None), _FakeValue(None), _FakeValue(None)

    monkeypatch.setattr(sdp_module, "sdp_problem", fake)
    cert = prove(Ellipsoid(np.zeros(2), np.eye(2)), Ellipsoid(np.zeros(2), 2 * np.eye(2)))
    assert cert.status is Status.REFUTED
    assert verify(cert).status is Status.REFUTED


def test_socp_not_optimal_is_unknown(monkeypatch):
    def fake(n, m):
        # problem, variable, two parameters (the prover only assigns .value to those)
        return (
            _FakeProblem("optimal_inaccurate"),
            _FakeValue(np.zeros((m, n))),
            _FakeValue(None),
            _FakeValue(None),
        )

    monkeypatch.setattr(socp_module, "socp_problem", fake)
    box = Box([-2.0, -2.0], [2.0, 2.0])
    cert = prove(Ellipsoid(np.zeros(2), np.eye(2)), box, method="socp")
    assert cert.status is Status.UNKNOWN
    assert "optimal_inaccurate" in cert.detail


# ------------------------------------------------------------------ bad input
def test_constructor_validation():
    e = Ellipsoid(np.zeros(2), np.eye(2))
    box = Box([-1.0, -1.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError, match="witness"):
        ContainmentCertificate(e, box, Method.CLOSED_FORM, Status.REFUTED)
    with pytest.raises(InvalidInputError, match="only a REFUTED"):
        ContainmentCertificate(e, box, Method.CLOSED_FORM, Status.PROVEN, witness=(F(0), F(0)))
    with pytest.raises(InvalidInputError, match="does not apply to an ellipsoid"):
        ContainmentCertificate(e, e, Method.CLOSED_FORM, Status.UNKNOWN)
    with pytest.raises(InvalidInputError, match="lambda"):
        ContainmentCertificate(e, e, Method.SDP, Status.PROVEN)
    with pytest.raises(InvalidInputError, match=r"one 'lambda' multiplier per face \(4\)"):
        ContainmentCertificate(e, box, Method.SDP, Status.PROVEN, {"lambda": [F(1, 2)] * 3})
    with pytest.raises(SetError, match="dimension"):
        ContainmentCertificate(e, Box([0.0], [1.0]), Method.CLOSED_FORM, Status.UNKNOWN)


def test_set_validation():
    with pytest.raises(SetError, match="lower"):
        Box([1.0], [0.0])
    with pytest.raises(SetError, match="non-finite"):
        Box([np.nan], [0.0])
    with pytest.raises(SetError, match="shape"):
        Polytope([[1.0, 0.0]], [1.0, 2.0])


def test_prove_rejects_batches_and_mismatches():
    e2 = Ellipsoid(np.zeros((2, 2)), np.stack([np.eye(2)] * 2))
    with pytest.raises(SetError, match="prove_batch"):
        prove(e2, Box([-1.0, -1.0], [1.0, 1.0]))
    e = e2[0]
    with pytest.raises(SetError, match="dimension"):
        prove(e, Box([-1.0], [1.0]))
    with pytest.raises(InvalidInputError, match="use 'sdp' for ellipsoids"):
        prove(e, e, method="closed-form")
    with pytest.raises(InvalidInputError, match="use 'sdp' for ellipsoids"):
        prove(e, e, method=Method.SOCP)
    with pytest.raises(InvalidInputError, match="not one of"):
        prove(e, Box([-1.0, -1.0], [1.0, 1.0]), method="magic")


@pytest.mark.parametrize(
    ("problem", "match"),
    [
        (
            {"inner": {"type": "ellipsoid", "center": [0.0]}, "outer": {}},
            "'inner.shape' is missing",
        ),
        ({"inner": {"type": "ball"}, "outer": {}}, "'inner.type'"),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "outer": {"type": "box", "lower": [0.0, 1.0], "upper": [1.0]},
            },
            "'outer.upper'",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "outer": {"type": "box", "lower": [0.0], "upper": [True]},
            },
            r"'outer.upper\[0\]'",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[0.0]]},
                "outer": {"type": "box", "lower": [0.0], "upper": [1.0]},
            },
            "'inner'.*singular",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [2**53 + 1], "shape": [[1.0]]},
                "outer": {"type": "box", "lower": [0.0], "upper": [1.0]},
            },
            "not exactly a float",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "outer": {"type": "box", "lower": [0.0, 0.0], "upper": [1.0, 1.0]},
            },
            "dimension",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "outer": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "method": "closed-form",
            },
            "does not apply to an ellipsoid",
        ),
        (
            {
                "inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
                "outer": {"type": "box", "lower": [0.0], "upper": [1.0]},
                "extra": 1,
            },
            "'extra'",
        ),
        (
            {
                "inner": {"type": "box", "lower": [0.0], "upper": [1.0]},
                "outer": {"type": "box", "lower": [0.0], "upper": [1.0]},
            },
            "must be an ellipsoid",
        ),
    ],
)
def test_problem_parsing_names_the_field(problem, match):
    with pytest.raises(InvalidInputError, match=match):
        problem_from_dict(problem)


def test_set_from_dict_polytope_and_nan():
    p = set_from_dict({"type": "polytope", "A": [[1.0, 0.0]], "b": [1.0]})
    assert isinstance(p, Polytope) and p.dim == 2
    with pytest.raises(InvalidInputError, match="not finite"):
        set_from_dict({"type": "box", "lower": [float("nan")], "upper": [1.0]})
