"""The S-lemma SDP for boxes and polytopes: exact face LMIs, the prover's policy, forged certificates.

Oracles never come from the code under test: definiteness from all principal minors
(Fractions), containment from the closed form's exact inequalities written out here.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ipcverify.decision.containment._face_sdp as face_sdp
from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._certificate import ContainmentCertificate, certificate_from_dict
from ipcverify.decision.containment._face_lmi import (
    FaceSystem,
    check_face_lmis,
    face_centre,
    integer_definiteness,
)
from ipcverify.decision.containment._face_sdp import FaceSolution, prove_sdp_faces, solve_face_sdp
from ipcverify.decision.containment._prove import prove_batch
from ipcverify.decision.containment._status import Method
from ipcverify.errors import InvalidInputError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import is_positive_semidefinite
from ipcverify.sets._polytope import Polytope

F = Fraction
PROPS = settings(derandomize=True, max_examples=80, deadline=None)


def _face_matrix(e: Ellipsoid, a, b, lam: Fraction):
    """``[[lam A, -a/2], [-a^T/2, b - a^T c - lam]]`` in Fractions, written out independently."""
    c = [F(float(v)) for v in e.centers[0]]
    cm = [[F(float(v)) for v in row] for row in e.shapes[0]]
    n = len(c)
    A = [[sum(cm[k][i] * cm[k][j] for k in range(n)) for j in range(n)] for i in range(n)]
    aq = [F(float(v)) for v in a]
    s = F(float(b)) - sum(x * y for x, y in zip(aq, c, strict=True))
    m = [[lam * A[i][j] for j in range(n)] + [-aq[i] / 2] for i in range(n)]
    m.append([-x / 2 for x in aq] + [s - lam])
    return m


def _holds_exact(e: Ellipsoid, a, b, det) -> bool:
    """Closed form written out: s >= 0 and s^2 >= a^T (C^T C)^{-1} a, via Cramer's rule."""
    c = [F(float(v)) for v in e.centers[0]]
    cm = [[F(float(v)) for v in row] for row in e.shapes[0]]
    n = len(c)
    A = [[sum(cm[k][i] * cm[k][j] for k in range(n)) for j in range(n)] for i in range(n)]
    aq = [F(float(v)) for v in a]
    d = det(A)
    x = [det([[aq[r] if j == i else A[r][j] for j in range(n)] for r in range(n)]) / d for i in range(n)]
    s = F(float(b)) - sum(p * q for p, q in zip(aq, c, strict=True))
    return s >= 0 and s * s >= sum(p * q for p, q in zip(aq, x, strict=True))


# ------------------------------------------------------------ exact face LMIs
@PROPS
@given(
    entries=st.lists(st.integers(-6, 6), min_size=10, max_size=10),
    rank_one=st.booleans(),
)
def test_integer_definiteness_agrees_with_minors(entries, rank_one, minors):
    it = iter(entries)
    m = [[0] * 4 for _ in range(4)]
    for i in range(4):
        for j in range(i + 1):
            m[i][j] = m[j][i] = next(it)
    if rank_one:  # a PSD matrix with zero minors: v v^T plus a diagonal that may vanish
        v = entries[:4]
        m = [[v[i] * v[j] + (entries[4 + i] % 2) * (i == j) for j in range(4)] for i in range(4)]
    verdict = integer_definiteness(m)
    leading = minors.of(m, leading=True)
    if verdict is True:
        assert all(d > 0 for d in leading)
    elif verdict is False:
        assert not minors.psd(m)  # not PSD
    else:
        assert any(d == 0 for d in leading)
        first = next(d for d in leading if d <= 0)
        assert first == 0


seeds = st.integers(0, 2**32 - 1)


@PROPS
@given(
    seed=seeds, n=st.sampled_from([1, 2, 3, 4]), odd=st.booleans(), scale=st.sampled_from([1e-3, 1.0, 1e3])
)
def test_face_system_matrix_is_a_positive_multiple_of_the_lmi(seed, n, odd, scale):
    rng = np.random.default_rng(seed)
    e = Ellipsoid(rng.normal(size=n) * scale, (rng.standard_normal((n, n)) + 3 * np.eye(n)) / scale)
    a, b = rng.standard_normal((2, n)), rng.normal(size=2) * scale
    poly = Polytope(a, b)
    system = FaceSystem(e, poly)
    for j in range(2):
        lam = F(float(abs(rng.normal()) * scale)) + (F(1, 3) if odd else 0)
        exact = _face_matrix(e, a[j], b[j], lam)
        ints = system.matrix(j, lam)
        ratio = F(ints[0][0]) / exact[0][0]
        assert ratio > 0
        assert all(F(ints[r][k]) == ratio * exact[r][k] for r in range(n + 1) for k in range(n + 1))
        assert system.check(j, lam)[0] == is_positive_semidefinite(exact)
        assert system.slack(j) == exact[n][n] + lam


def test_centre_certifies_exactly_the_faces_that_hold(minors):
    rng = np.random.default_rng(3)
    for _ in range(40):
        n = 3
        e = Ellipsoid(rng.normal(size=n), rng.standard_normal((n, n)) + 2 * np.eye(n))
        a = rng.standard_normal((4, n))
        h = np.linalg.norm(np.linalg.solve(e.shapes[0].T, a.T), axis=0)
        b = a @ e.centers[0] + h * (1 + rng.choice([-1e-9, 0.0, 1e-9, 0.3], size=4))
        poly = Polytope(a, b)
        system = FaceSystem(e, poly)
        for j in range(4):
            centre = face_centre(system, j)
            assert system.check(j, max(centre, F(0)))[0] == _holds_exact(e, a[j], b[j], minors.det)


def test_touching_faces_have_one_multiplier_only():
    disc = Ellipsoid(np.zeros(2), np.eye(2))
    box = Box([-1.0, -1.0], [1.0, 1.0])
    assert check_face_lmis(disc, box, [F(1, 2)] * 4)[0]
    for lam in (F(1, 2) - F(1, 2**60), F(1, 2) + F(1, 2**60), F(0)):
        assert not check_face_lmis(disc, box, [lam, F(1, 2), F(1, 2), F(1, 2)])[0]
    ok, why = check_face_lmis(disc, box, [F(1, 2)] * 3)
    assert not ok and "3 multipliers for 4 faces" in why
    ok, why = check_face_lmis(disc, box, [F(-1, 2), F(1, 2), F(1, 2), F(1, 2)])
    assert not ok and "lambda < 0" in why


# --------------------------------------------------------- reference problems
def test_touching_box_is_proven_with_the_centre_multipliers():
    c = np.array([1.0, -2.0, 0.5])
    e = Ellipsoid(c, np.diag([2.0, 4.0, 8.0]))  # semi-axes 0.5, 0.25, 0.125 exactly
    h = np.array([0.5, 0.25, 0.125])
    cert = prove(e, Box(c - h, c + h), method="sdp")
    assert cert.status is Status.PROVEN and cert.method is Method.SDP
    assert list(cert.multipliers["lambda"]) == [F(v) / 2 for v in (*h, *h)]  # s / 2 = h / 2
    assert verify(cert).status is Status.PROVEN


@pytest.mark.parametrize(
    ("b", "expected"), [(0.0, Status.PROVEN), (2.0, Status.PROVEN), (-1.0, Status.REFUTED)]
)
def test_zero_row_means_zero_at_most_b(b, expected):
    e = Ellipsoid([0.3, -0.2], np.eye(2) * 4.0)
    cert = prove(e, Polytope([[0.0, 0.0], [1.0, 0.0]], [b, 10.0]), method="sdp")
    assert cert.status is expected, cert.detail
    assert verify(cert).status is expected


def test_landing_example_of_the_docs_is_proven_by_both_routes():
    from ipcverify.decision._landing_proof import landing_decision

    e = Ellipsoid([1.0, 2.0, 0.3], np.diag([40.0, 40.0, 80.0]))  # the top face touches exactly
    d = landing_decision(e, Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
    cert = prove(e, d.certificate.outer, method="sdp")
    assert d.accept and cert.status is Status.PROVEN, cert.detail
    assert "with the centre" in cert.detail


def test_prove_batch_by_sdp():
    e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    certs = prove_batch(e, Box([-1.0], [1.0]), method="sdp")
    assert [c.status.name for c in certs] == ["PROVEN", "REFUTED"]


def test_solver_slack_estimates_the_closed_form_margin():
    e = Ellipsoid(np.zeros(1), np.eye(1))
    sol = solve_face_sdp(e, Box([-2.0], [3.0]))
    assert sol.solved
    np.testing.assert_allclose(sol.slack, [2.0, 1.0], rtol=1e-6)
    np.testing.assert_allclose(sol.lam, [1.5, 1.0], rtol=1e-4)  # s / 2
    np.testing.assert_allclose(sol.direction[:, 0], [1.0, -1.0], rtol=1e-4)  # the maximisers


# -------------------------------------------------------- the solver's failures
def _fail_first(monkeypatch, statuses):
    """Make Clarabel report ``statuses`` (then solve for real) -- the retry path."""
    import clarabel

    calls = []
    original = clarabel.DefaultSolver

    class Fake:
        def __init__(self, *args):
            self.inner = original(*args)

        def solve(self):
            sol = self.inner.solve()
            if len(calls) < len(statuses):
                calls.append(statuses[len(calls)])

                class Bad:
                    status = calls[-1]
                    x, z = sol.x, sol.z

                return Bad()
            return sol

    monkeypatch.setattr(clarabel, "DefaultSolver", Fake)
    return calls


def test_a_stalled_solve_is_retried_without_chordal_decomposition(monkeypatch):
    calls = _fail_first(monkeypatch, ["AlmostSolved"])
    e = Ellipsoid(np.zeros(2), np.eye(2))
    cert = prove(e, Box([-2.0, -2.0], [2.0, 2.0]), method="sdp")
    assert calls == ["AlmostSolved"]
    assert cert.status is Status.PROVEN


@pytest.mark.parametrize("contained", [True, False])
def test_no_solve_means_unknown_never_proven_nor_refuted(monkeypatch, contained):
    _fail_first(monkeypatch, ["AlmostSolved", "MaxIterations"])
    e = Ellipsoid(np.zeros(2), np.eye(2))
    cert = prove(e, Box([-2.0, -2.0], [2.0 if contained else 0.5, 2.0]), method="sdp")
    assert cert.status is Status.UNKNOWN
    assert "(AlmostSolved then MaxIterations; only 'Solved' is)" in cert.detail
    assert verify(cert).ok


def test_wrong_solver_multipliers_never_prove_a_false_containment(monkeypatch):
    e = Ellipsoid(np.zeros(2), np.eye(2))
    box = Box([-2.0, -2.0], [0.5, 2.0])  # face 0 fails: x reaches 1

    def forged(inner, outer):  # "Solved", multipliers at every face's centre s/2, no useful dual
        s = outer.faces()[1] - outer.faces()[0] @ inner.centers[0]
        m = len(s)
        return FaceSolution("Solved", s / 2, s, np.zeros((m, 2)), np.zeros((m, 2)), np.abs(s))

    monkeypatch.setattr(face_sdp, "solve_face_sdp", forged)
    cert = prove_sdp_faces(e, box)
    assert cert.status is Status.UNKNOWN  # the exact check refuses face 0, and no witness is given
    assert "face(s) [0]" in cert.detail


def test_problem_data_beyond_float64_is_unknown():
    huge = Ellipsoid(np.zeros(1), np.array([[1e-310]]))  # radius 1e310: C^-T a overflows
    cert = prove(huge, Box([-1.0], [1.0]), method="sdp")
    assert cert.status is Status.UNKNOWN
    assert "overflow" in cert.detail


# ------------------------------------------------------- certificates and bad input
def _sdp_box_cert():
    e = Ellipsoid(np.array([0.1, -0.2]), np.array([[3.0, 0.5], [0.0, 2.0]]))
    return prove(e, Box([-1.0, -1.0], [1.0, 1.0]), method="sdp")


def test_sdp_box_certificate_round_trips_and_reverifies():
    cert = _sdp_box_cert()
    assert cert.status is Status.PROVEN
    back = certificate_from_dict(cert.to_dict())
    assert back.multipliers == cert.multipliers and back.method is Method.SDP
    assert verify(back).status is Status.PROVEN


@pytest.mark.parametrize(
    "forge",
    [
        lambda d: d["outer"].update(upper=[0.5, 1.0]),  # the box moved in
        lambda d: d["multipliers"].update(**{"lambda": ["-1/2", *d["multipliers"]["lambda"][1:]]}),
        lambda d: d["multipliers"].update(**{"lambda": [1e-9, *d["multipliers"]["lambda"][1:]]}),
        lambda d: d["inner"].update(center=[0.9, -0.2]),  # the ellipsoid moved out
    ],
)
def test_forged_sdp_box_certificates_fail_verification(forge):
    data = _sdp_box_cert().to_dict()
    forge(data)
    v = verify(certificate_from_dict(data))
    assert not v.ok and v.status is Status.UNKNOWN


def test_a_proven_sdp_box_certificate_needs_one_multiplier_per_face():
    data = _sdp_box_cert().to_dict()
    data["multipliers"]["lambda"] = data["multipliers"]["lambda"][:3]
    with pytest.raises(InvalidInputError, match=r"one 'lambda' multiplier per face \(4\)"):
        certificate_from_dict(data)
    data["multipliers"] = {}
    with pytest.raises(InvalidInputError, match="per face"):
        certificate_from_dict(data)


def test_unknown_method_is_refused():
    e = Ellipsoid(np.zeros(2), np.eye(2))
    with pytest.raises(InvalidInputError, match='"s-lemma" is not one of closed-form, socp, sdp'):
        prove(e, Box([-1.0, -1.0], [1.0, 1.0]), method="s-lemma")
    with pytest.raises(InvalidInputError, match="does not apply to an ellipsoid"):
        ContainmentCertificate(e, e, Method.SOCP, Status.UNKNOWN)
