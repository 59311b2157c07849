"""The float-bound landing decision against the exact rational one (proofs/float_landing.md).

Every case is decided twice: by :func:`ipcverify.decision._landing_bound.landing_by_bound` (float64 with a
rigorous rounding bound, exact integers for an ambiguous turn-off height) and by the exact
:func:`ipcverify.decision._landing.landing_decision` (Fractions). Whenever the fast path answers, its
accept/reject and its turn-off height must be the exact ones; it may decline (None) only near
a tie. Five strategies, 11,000 derandomized examples in all:

* random ellipsoids (rotations, semi-axes 1 mm .. 1 m, condition numbers up to 1e8, camera- and
  world-frame heights, the paper's G and random boxes);
* near ties: the critical face scaled to a relative margin of +-1e-1 .. +-1e-15;
* exact ties built from dyadic numbers (touching faces, ``c_z + h_z`` exactly a float), then
  nudged by one ulp;
* the network's shapes (lower-triangular ``L diag(1/sigma)``) and their world-frame rotations,
  decided end to end by :class:`ipcverify.decision._landing.LandingRule` (fast path plus fallback);
* degenerate and extreme inputs (singular, ``|C_ij|`` up to 1e120 and down to 1e-200).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.decision._landing import DecidedBy, LandingRule
from ipcverify.decision._landing_bound import RANGE, bound_target, landing_by_bound, landing_by_bound_compiled
from ipcverify.decision._landing_proof import check_landing, landing_decision
from ipcverify.decision.containment import Status
from ipcverify.errors import SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid

PAPER_G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
SEEDS = st.integers(0, 2**32 - 1)


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """``low + (high - low) u``, ``u = k 2^-53`` (``Generator.random``): no libm, no BLAS, no LAPACK."""
    return low + (high - low) * float(rng.random())


def _ten(k: int) -> float:
    """``10^k`` correctly rounded (integer arithmetic, not ``pow``)."""
    return float(Fraction(10) ** k)


def _matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A 3x3 product summed left to right in Python floats (BLAS kernels round differently per CPU)."""
    return np.array(
        [[a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j] for j in range(3)] for i in range(3)]
    )


def _rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation from a uniform unit quaternion (rejection from the ball; plain arithmetic only).

    Test inputs must be the same floats on every machine: LAPACK's QR (the earlier construction)
    rounds differently on different CPUs, so one seed drew different ellipsoids on Intel and AMD.
    """
    while True:
        w, x, y, z = (_uniform(rng, -1.0, 1.0) for _ in range(4))
        n2 = w * w + x * x + y * y + z * z
        if 1e-2 < n2 <= 1.0:
            break
    n = math.sqrt(n2)  # IEEE: correctly rounded
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
            [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
            [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


def _target(rng: np.random.Generator, kind: int) -> Box:
    if kind == 0:
        return PAPER_G
    lower = np.array([-_uniform(rng, 0.0, 0.2) for _ in range(3)])
    if kind == 2:
        lower[2] = _uniform(rng, -0.05, 0.05)  # G.lower_z of either sign: the z face is no longer a tie
    return Box(lower, lower + np.array([_uniform(rng, 1e-3, 0.2) for _ in range(3)]))


def _center(rng: np.random.Generator, frame: int) -> np.ndarray:
    scale = [(0.05, 0.05, 0.01), (0.5, 0.5, 1.5), (30.0, 30.0, 30.0)][frame]
    c = np.array([_uniform(rng, -2.0 * s, 2.0 * s) for s in scale])
    if frame == 1:
        c[2] = abs(c[2]) + 0.9  # camera frame: the pad about 1-3 m ahead
    return c


def _semi_axis(rng: np.random.Generator) -> float:
    """Log-uniform-ish in [2^-10, 2^-3] (about 1 mm .. 12 cm), built exactly: ``m 2^k``."""
    return math.ldexp(_uniform(rng, 1.0, 2.0), int(rng.integers(-10, -3)))


def _shape(rng: np.random.Generator, log_cond: int) -> np.ndarray:
    semi = [_semi_axis(rng) for _ in range(3)]
    semi[int(rng.integers(3))] *= _ten(-log_cond)
    return _matmul(_matmul(_rotation(rng), np.diag([1.0 / s for s in semi])), _rotation(rng).T)


def _half_widths(C: np.ndarray) -> list[Fraction]:
    """``h_i^2 = ||row i of C^-1||^2`` exactly (cofactors in Fractions; ``np.linalg.inv`` is LAPACK)."""
    m = [[Fraction(float(v)) for v in row] for row in C]
    cof = [
        [
            m[(r + 1) % 3][(k + 1) % 3] * m[(r + 2) % 3][(k + 2) % 3]
            - m[(r + 1) % 3][(k + 2) % 3] * m[(r + 2) % 3][(k + 1) % 3]
            for k in range(3)
        ]
        for r in range(3)
    ]
    det = sum(m[0][k] * cof[0][k] for k in range(3))
    return [sum(cof[r][i] ** 2 for r in range(3)) / det**2 for i in range(3)]


def _exact(c: np.ndarray, C: np.ndarray, G: Box):
    """The exact decision, or None where the exact path refuses (degenerate set, G too narrow)."""
    try:
        return landing_decision(Ellipsoid(c, C), G)
    except (SetError, OverflowError):  # OverflowError: half-widths beyond float's range (not exact-safe)
        return None


def _check(c: np.ndarray, C: np.ndarray, G: Box):
    """Both decisions; the fast one, if any, must equal the exact one. Returns (fast, exact).

    The compiled float tier (:func:`~ipcverify.decision._landing_bound.landing_by_bound_compiled`) must give
    the Python function's answer on every input.
    """
    fast = landing_by_bound(c.tolist(), C.ravel().tolist(), G.lower.tolist(), G.upper.tolist())
    # the decision of record runs the float tier compiled: the same answer, to the bit
    assert (
        landing_by_bound_compiled(c.tolist(), C.ravel().tolist(), G.lower.tolist(), G.upper.tolist()) == fast
    )
    exact = _exact(c, C, G)
    if fast is not None:
        if exact is None:  # the exact path refuses: the fast path may only reject
            assert not fast.accept
        else:
            assert fast.accept == exact.accept
            assert fast.turnoff_z == exact.turnoff[2]
    return fast, exact


def _critical_scale(c: np.ndarray, C: np.ndarray, G: Box) -> float:
    """The factor s such that E(c, s C) touches its box (float estimate of the tie, machine-independent)."""
    h = [math.sqrt(float(h2)) for h2 in _half_widths(C)]
    w = (G.upper - G.lower).tolist()
    return max(2 * h[0] / w[0], 2 * h[1] / w[1], 2 * h[2] / w[2])


def _float_up(q: Fraction) -> float:
    f = float(q)  # correctly rounded
    return math.nextafter(f, math.inf) if Fraction(f) < q else f


def _sqrt_enclosure(q: Fraction) -> tuple[Fraction, Fraction]:
    """``lo <= sqrt(q) < hi = lo + 2^-k``, with ``2^k sqrt(q)`` about ``2^200``."""
    scale = Fraction(2) ** (200 - (q.numerator.bit_length() - q.denominator.bit_length()) // 2)
    r = math.isqrt(math.floor(q * scale * scale))
    return r / scale, (r + 1) / scale


# --------------------------------------------------------------------- strategies
@settings(derandomize=True, max_examples=3500, deadline=None)
@given(
    seed=SEEDS,
    log_cond=st.sampled_from([0, 1, 4, 8]),
    frame=st.integers(0, 2),
    kind=st.integers(0, 2),
)
def test_random_ellipsoids_agree_with_the_exact_decision(seed, log_cond, frame, kind):
    rng = np.random.default_rng(seed)
    _check(_center(rng, frame), _shape(rng, log_cond), _target(rng, kind))


@settings(derandomize=True, max_examples=3000, deadline=None)
@given(
    seed=SEEDS,
    digits=st.integers(1, 15),
    sign=st.sampled_from([-1.0, 1.0]),
    log_cond=st.sampled_from([0, 2, 8]),
    frame=st.integers(0, 1),
    kind=st.integers(0, 2),
)
def test_near_ties_agree_with_the_exact_decision(seed, digits, sign, log_cond, frame, kind):
    """The critical face at a relative margin of +-10^-digits, down to a few ulps."""
    rng = np.random.default_rng(seed)
    c, C, G = _center(rng, frame), _shape(rng, log_cond), _target(rng, kind)
    C = C * (_critical_scale(c, C, G) * (1.0 + sign * _ten(-digits)))
    fast, exact = _check(c, C, G)
    if digits <= 6 and log_cond == 0 and exact is not None:
        assert fast is not None  # well away from the tie the bound always decides


def _ulp_nudge(rng: np.random.Generator, a: np.ndarray) -> np.ndarray:
    steps = rng.integers(-1, 2, a.shape)
    out = a.copy()
    for idx in zip(*np.nonzero(steps), strict=True):
        out[idx] = math.nextafter(float(out[idx]), math.inf * float(steps[idx]))
    return out


@settings(derandomize=True, max_examples=2000, deadline=None)
@given(
    seed=SEEDS,
    ex=st.lists(st.integers(-8, -3), min_size=3, max_size=3),
    cz=st.sampled_from([0.0, 1.0, 1.5, -0.25, 0.75, 3.0]),
    nudge=st.sampled_from(["none", "shape", "center", "both"]),
    triangular=st.booleans(),
)
def test_exact_ties_agree_with_the_exact_decision(seed, ex, cz, nudge, triangular):
    """Dyadic half-widths that touch the box exactly, c_z + h_z exactly a float; then ulp nudges."""
    rng = np.random.default_rng(seed)
    h = np.array([2.0**e for e in ex])  # half-widths, exact floats
    G = Box([-h[0], -h[1], 0.0], [h[0], h[1], 2 * h[2]])  # every face touches exactly
    C = np.diag(1.0 / h)
    if triangular:  # same set, different matrix: C^T C unchanged under an exact signed permutation
        C = C[rng.permutation(3)] * rng.choice([-1.0, 1.0], 3)[:, None]
    c = np.array([rng.choice([0.0, 0.5, -1.25]), rng.choice([0.0, 2.0]), cz])
    if nudge in ("shape", "both"):
        C = _ulp_nudge(rng, C)
    if nudge in ("center", "both"):
        c = _ulp_nudge(rng, c)
    fast, exact = _check(c, C, G)
    if nudge == "none" and exact is not None:
        assert exact.accept and (fast is None or fast.accept)  # touching is containment


@settings(derandomize=True, max_examples=1500, deadline=None)
@given(seed=SEEDS, world=st.booleans(), kind=st.integers(0, 2), tight=st.booleans())
def test_the_rule_decides_network_shapes_like_the_exact_proof(seed, world, kind, tight):
    """End to end (fast path, then the exact fallback): same accept and turn-off point, every time."""
    rng = np.random.default_rng(seed)
    L = np.array([[_uniform(rng, -0.6, 0.6) if j < i else 0.0 for j in range(3)] for i in range(3)])
    L[np.diag_indices(3)] = [_uniform(rng, 0.6, 1.65) for _ in range(3)]  # about exp(+-0.5)
    C = L * np.array([1.0 / _uniform(rng, 0.004, 0.02) for _ in range(3)])  # L diag(1/sigma), as the engine
    c = _center(rng, 0 if world else 1)
    if world:
        C = _matmul(C, _rotation(rng).T)  # the camera-to-world map of the case study
    G = _target(rng, kind)
    if tight:
        margin = _uniform(rng, 1.0, 10.0) * _ten(-int(rng.integers(4, 16)))  # 1e-15 .. 1e-3
        C = C * (_critical_scale(c, C, G) * (1.0 + rng.choice([-1.0, 1.0]) * margin))
    rule = LandingRule(G)
    d = rule.decide(c, C)
    exact = _exact(c, C, G)
    if exact is None:
        assert not d.accept
        return
    assert d.accept == exact.accept and np.array_equal(d.turnoff, exact.turnoff)
    assert d.decided_by in (DecidedBy.BOUND, DecidedBy.EXACT)
    if d.accept and seed % 16 == 0:  # the certificate on demand re-verifies exactly
        assert check_landing(d.proof).status is Status.PROVEN


@settings(derandomize=True, max_examples=1000, deadline=None)
@given(
    seed=SEEDS,
    log_scale=st.sampled_from([-200, -120, -30, 30, 100, 120]),
    singular=st.booleans(),
)
def test_extreme_and_singular_shapes_are_never_misjudged(seed, log_scale, singular):
    rng = np.random.default_rng(seed)
    C = _shape(rng, 0) * _ten(log_scale)
    if singular:
        C[2] = C[0] * rng.choice([0.0, 1.0, 2.0])  # rank 2 (or a zero row)
    c = _center(rng, 1)
    G = Box(
        *(
            np.array([s * _uniform(rng, 1.0, 10.0) * _ten(int(rng.integers(-3, 3))) for _ in range(3)])
            for s in (-1, 1)
        )
    )
    fast, exact = _check(c, C, G)
    if singular:
        assert fast is None or not fast.accept
    elif exact is not None and np.abs(C).max() > RANGE:
        assert fast is not None  # scaled exactly by a power of two, then decided
    d = LandingRule(G).decide(c, C)
    assert d.accept == (exact is not None and exact.accept)


# --------------------------------------------------------------------- examples
def test_the_rule_reports_how_it_decided():
    rule = LandingRule(PAPER_G)
    fast = rule.decide(np.array([0.0, 0.0, 1.0]), np.diag([40.0, 40.0, 80.0]))
    assert fast.decided_by is DecidedBy.BOUND and fast.proven and fast.exact is None
    assert fast.proof is not None and fast.proof.accept and fast.exact is fast.proof  # computed once
    tie = rule.decide(np.array([0.0, 0.0, 1.0]), np.diag([20.0, 40.0, 80.0]))  # x face touches
    assert tie.decided_by is DecidedBy.EXACT and tie.exact is not None
    assert rule.decide_float(np.zeros(3), np.eye(3)).decided_by is DecidedBy.FLOAT_RULE
    degenerate = rule.decide(np.zeros(3), np.diag([1.0, 1.0, 0.0]))
    assert degenerate.decided_by is DecidedBy.DOMAIN and degenerate.verdict.name == "OUTSIDE_DOMAIN"


def test_nearly_singular_sets_are_never_accepted_and_never_an_error():
    rule = LandingRule(PAPER_G)
    huge = rule.decide(np.zeros(3), np.diag([1e3, 1e3, 1e-12]))  # 1e12 tall: provably too tall
    assert huge.verdict.name == "REJECT" and huge.decided_by is DecidedBy.BOUND
    thin = np.diag([1e3, 1e3, 1e16])  # fits G, but reciprocal condition number 1e-13: not an Ellipsoid
    d = rule.decide(np.array([0.0, 0.0, 1.0]), thin)
    assert d.verdict.name == "OUTSIDE_DOMAIN" and not d.accept


def test_a_target_narrower_than_a_float_spacing_still_says_so():
    G = Box([1e-20, 0.0, 0.0], [2e-20, 1.0, 1.0])  # P_x - G is inside one float gap below 1e6
    with pytest.raises(SetError, match="narrower than one float spacing"):
        LandingRule(G).decide(np.array([1e6, 0.0, 0.0]), np.eye(3) * 1e3)


def test_targets_out_of_range_go_to_the_exact_path():
    assert not bound_target((-1e300, 0.0, 0.0), (1.0, 1.0, 1.0))
    rule = LandingRule(Box([-1e300, -1.0, 0.0], [1.0, 1.0, 1.0]))
    d = rule.decide(np.zeros(3), np.eye(3) * 10.0)
    assert d.decided_by is DecidedBy.EXACT and d.accept


def test_the_fast_path_agrees_with_its_own_certificate_on_demand():
    rng = np.random.default_rng(5)
    rule = LandingRule(PAPER_G)
    checked = 0
    for _ in range(40):
        c, C = _center(rng, 1), _shape(rng, 0) * 0.7
        d = rule.decide(c, C)
        if d.accept and d.decided_by is DecidedBy.BOUND:
            assert check_landing(d.proof).status is Status.PROVEN
            checked += 1
    assert checked > 5


# c_z + h_z within 2^-64 h_z of a float (the first found by perturbing the inputs that failed on an AMD
# EPYC, where LAPACK's QR drew them; the others by the machine-independent generator above)
NEAR_A_FLOAT = [
    (
        [-0.01232009109129277, 0.02956242785876901, 0.01278352560561269],
        [8.49582896760036, -18.917137986788955, 163.65830314728638, -24.034161079915553, -8.58379475416589,
         35.03871771802901, 74.34789233459873, 83.20140978218265, -96.55025546191952],
        False,
    ),
    (
        [-0.05155955549689333, 0.07353426009416572, -0.010197477404269977],
        [-64.73622163561446, 2.467620227039593, 28.540199778890425, 52.60972405754732, 53.38974446701726,
         -25.87031618997925, -80.43926958043293, -9.40546285938612, -22.910628957750795],
        True,
    ),
    (
        [0.0042250971063934745, -0.018400698797348, -0.01846990039729695],
        [-47.89286241710737, 36.42936271698527, 19.360716876110228, 75.71320901999408, -83.7327449984245,
         46.648490087039704, 74.92161615530844, -26.844364280856855, 44.10177007784264],
        True,
    ),
]  # fmt: skip


@pytest.mark.parametrize(("c", "C", "accept"), NEAR_A_FLOAT)
def test_a_top_within_2_to_the_minus_64_of_a_float_is_decided_like_the_exact_path(c, C, accept):
    """There ``P_z`` depends on the rational ``sqrt_upper`` picks; the bound computes it the same way.

    The 130-bit enclosure of ``c_z + sqrt_upper(h_z^2)`` contains a float, so it cannot settle ``P_z``;
    before the bound evaluated the exact path's formula here, it declined at any margin (these
    inputs are 1e-1 .. 1e-5 from a tie).
    """
    c, C = np.array(c), np.array(C).reshape(3, 3)
    cz = Fraction(c[2])
    lo, hi = _sqrt_enclosure(_half_widths(C)[2])
    assert _float_up(cz + lo) <= cz + hi * (
        1 + Fraction(1, 2**64)
    )  # a float within 2^-64 h_z above c_z + h_z
    fast, exact = _check(c, C, PAPER_G)
    assert exact is not None and exact.accept is accept
    assert fast is not None and fast.exact_turnoff and fast.accept is accept


def test_a_turnoff_height_within_2_to_the_minus_100_of_a_float_is_the_exact_paths():
    """h_z = 2^-4 sqrt(1 + p^2) lies about 2^-104 (relative) below the float 2^-4 (1 + 2^-52)."""
    p = math.nextafter(2.0**-25.5, 0.0)
    C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [p, 0.0, 16.0]])
    c = np.array([0.0, 0.0, 0.0])
    fast, exact = _check(c, C, Box([-2.0, -2.0, 0.0], [2.0, 2.0, 1.0]))
    assert exact is not None and exact.turnoff[2] == 2.0**-4 * (1 + 2.0**-52)
    assert fast is not None and fast.exact_turnoff  # sqrt_upper's rational, evaluated as the exact path does
    d = LandingRule(Box([-2.0, -2.0, 0.0], [2.0, 2.0, 1.0])).decide(c, C)
    assert np.array_equal(d.turnoff, exact.turnoff) and d.accept == exact.accept


@pytest.mark.parametrize("top", [5e-324, 1e-320, 1e-310, 2.0**-1023, 2.0**-1022, 1e-300])
def test_subnormal_shape_matrices_are_never_an_error_and_never_accepted(top):
    """Scaling such a matrix by 2^-k needed a float beyond the range (an OverflowError before)."""
    C = np.diag([top, top, top])
    c = np.array([0.0, 0.0, 1.0])
    fast, exact = _check(c, C, PAPER_G)
    assert fast is None or not fast.accept
    d = LandingRule(PAPER_G).decide(c, C)
    assert not d.accept and d.verdict.name in ("REJECT", "OUTSIDE_DOMAIN")
