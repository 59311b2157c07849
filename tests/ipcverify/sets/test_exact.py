"""Tests of the exact rational helpers (ipcverify.sets._exact)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.errors import InvalidInputError
from ipcverify.sets._exact import (
    decode_exact,
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

F = Fraction
DERANDOMIZED = settings(derandomize=True, max_examples=150, deadline=None)


def test_exact_conversion_is_exact():
    assert exact_vector([0.1])[0] == F(3602879701896397, 2**55)
    assert exact_matrix([[1e-300, 2.0]])[0][0] == F(1e-300)
    with pytest.raises(InvalidInputError, match="non-finite"):
        exact_vector([np.nan])
    with pytest.raises(InvalidInputError, match="2-D"):
        exact_matrix([1.0])


def test_inverse_times_matrix_is_identity_exactly():
    rng = np.random.default_rng(0)
    for _ in range(20):
        m = exact_matrix(rng.standard_normal((4, 4)))
        prod = matmul(m, inverse(m))
        assert prod == [[F(int(i == j)) for j in range(4)] for i in range(4)]


def test_inverse_rejects_singular():
    with pytest.raises(InvalidInputError, match="singular"):
        inverse([[F(1), F(2)], [F(2), F(4)]])


@DERANDOMIZED
@given(
    entries=st.lists(st.integers(-3, 3), min_size=9, max_size=9),
    rank=st.integers(0, 3),
)
def test_definiteness_matches_minors(entries, rank, minors):
    # M = B^T B with B of `rank` rows (PSD, singular when rank < 3), plus a nudge of
    # -1/4, 0 or +1/4 on the last diagonal entry (sometimes indefinite, sometimes PD)
    rows = [[F(entries[3 * i + j]) for j in range(3)] for i in range(rank)]
    m = [[sum((r[i] * r[j] for r in rows), F(0)) for j in range(3)] for i in range(3)]
    m[2][2] += F(entries[0] % 3 - 1, 4)
    assert is_positive_semidefinite(m) == minors.psd(m)
    assert is_positive_definite(m) == minors.pd(m)


def test_psd_handles_zero_pivots():
    z = F(0)
    assert is_positive_semidefinite([[z, z], [z, z]])
    assert not is_positive_semidefinite([[z, F(1)], [F(1), z]])
    assert is_positive_semidefinite([[z, z, z], [z, F(2), F(1)], [z, F(1), F(1)]])
    assert not is_positive_definite([[z, z], [z, F(1)]])


@DERANDOMIZED
@given(num=st.integers(0, 10**30), den=st.integers(1, 10**30), bits=st.sampled_from([8, 64, 200]))
def test_sqrt_bounds_bracket_the_root(num, den, bits):
    q = F(num, den)
    lo, hi = sqrt_lower(q, bits), sqrt_upper(q, bits)
    assert lo >= 0 and lo * lo <= q <= hi * hi
    assert hi - lo <= F(1, q.denominator * 2**bits)


def test_sqrt_of_negative_is_an_error():
    with pytest.raises(InvalidInputError):
        sqrt_upper(F(-1))


@DERANDOMIZED
@given(num=st.integers(-(10**40), 10**40), den=st.integers(1, 10**40))
def test_directed_rounding(num, den):
    q = F(num, den)
    up, down = float_up(q), float_down(q)
    assert F(down) <= q <= F(up)
    assert up == down or math.nextafter(down, math.inf) == up


@DERANDOMIZED
@given(st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.fractions()))
def test_encode_decode_round_trip(q):
    import json

    v = F(q)
    assert decode_exact(json.loads(json.dumps(encode_exact(v)))) == v


@pytest.mark.parametrize("bad", ["1/0", "x", "1.5/2", True, None, float("nan"), [1]])
def test_decode_rejects_garbage(bad):
    with pytest.raises(InvalidInputError):
        decode_exact(bad)


def test_small_helpers():
    assert matvec([[F(1), F(2)]], [F(3), F(4)]) == [F(11)]
    assert sqnorm([F(3), F(4)]) == 25
