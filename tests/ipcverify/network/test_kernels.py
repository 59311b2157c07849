"""Tests of the compiled one-query kernels' own behaviour (their numbers are tested against the
batch paths in test_lowrank.py and test_domain_one.py)."""

from __future__ import annotations

import numpy as np

from ipcverify.network._kernels import _activate, _compiled


def test_a_kernel_that_cannot_be_cached_is_still_compiled():
    # a function without a source file has no cache location, as in a read-only install: numba
    # refuses cache=True, and the kernel is compiled per process instead of failing at import
    namespace: dict = {}
    exec("def f(x):\n    return x + 1.0\n", namespace)
    f = _compiled(namespace["f"])
    assert f(2.0) == 3.0


def test_the_compiled_activations_are_numpys():
    v = np.array([-3.0, -0.5, -0.0, 0.0, 0.25, 4.0, np.nan])
    relu = [_activate(x, 0) for x in v]
    np.testing.assert_array_equal(relu, np.maximum(v, 0.0))  # NaN kept
    np.testing.assert_allclose([_activate(x, 1) for x in v], np.tanh(v), rtol=1e-15)
    elu = np.where(v > 0, v, np.expm1(np.minimum(v, 0.0)))
    np.testing.assert_allclose([_activate(x, 2) for x in v], elu, rtol=1e-15)


def test_the_fused_bias_passes_give_numpys_separate_passes():
    from ipcverify.network._engine import activate
    from ipcverify.network._kernels import ACTIVATION_CODES, bias_activate, bias_skip_add

    rng = np.random.default_rng(7)
    h = rng.normal(size=(27, 40)) * 3  # (units, queries): the batch's rows-as-columns layout
    h[5, 2] = np.nan
    bias = rng.normal(size=27)
    skip = rng.normal(size=(27, 40))
    for name, code in ACTIVATION_CODES.items():
        got = h.copy()
        bias_activate(got, bias, code)
        want = activate(h + bias[:, None], name)
        if name == "relu":  # the default: the very same numbers
            np.testing.assert_array_equal(got, want)
        else:  # libm's tanh / expm1 may differ from NumPy's by an ulp
            np.testing.assert_allclose(got, want, rtol=1e-15, atol=1e-300)
        assert np.isnan(got[5, 2])
    got = h.copy()
    bias_activate(got, bias, -1)  # the bias alone
    np.testing.assert_array_equal(got, h + bias[:, None])
    got = h.copy()
    bias_skip_add(got, bias, skip)
    np.testing.assert_array_equal(got, (h + bias[:, None]) + skip)
