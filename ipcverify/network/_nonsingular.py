"""Which shape matrices of a batch are non-singular by the rule of Ellipsoid -- without an SVD each.

:class:`~ipcverify.sets.Ellipsoid` refuses a shape matrix ``C`` whose reciprocal condition number
``sigma_min / sigma_max`` (from an SVD) is below :data:`~ipcverify.sets.SINGULAR_RCOND`. An SVD per
matrix costs about 1.4 microseconds, more than the whole network evaluation of a query. For
``n = 3``:

* ``sigma_max <= ||C||_F`` and ``1 / sigma_min = ||C^-1||_2 <= ||adj C||_F / |det C|``, so
  ``rho = |det C| / (||C||_F ||adj C||_F) <= sigma_min / sigma_max``;
* ``rho`` takes one pass of cofactors over the batch; ``|det C|`` is lowered by the rounding bound of
  its float evaluation (``8 u`` times the permanent of ``|C|``, as in ``proofs/float_landing.md``);
* where ``rho >= 2 SINGULAR_RCOND`` the SVD (whose singular values are accurate to a small multiple
  of ``u sigma_max``) finds the matrix non-singular too, so only the other matrices are decomposed,
  and they are judged by the very SVD computation of :class:`~ipcverify.sets.Ellipsoid`.

:func:`nonsingular` gives the verdicts; :func:`checked_ellipsoid` builds an
:class:`~ipcverify.sets.Ellipsoid` validated this way (same rules, same messages) for
:meth:`ipcverify.contract.IPCModel.predict`. Other dimensions use the SVD throughout.

Examples
--------
>>> import numpy as np
>>> ok, rcond = nonsingular(np.stack([np.eye(3), np.diag([1.0, 1.0, 1e-14])]))
>>> ok.tolist(), float(rcond[1])
([True, False], 1e-14)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import SetError
from ipcverify.network._kernels import rcond_lower_3
from ipcverify.sets._ellipsoid import SINGULAR_RCOND, Ellipsoid

FloatArray = NDArray[np.float64]
_U8 = 8.0 * 2.0**-53
_ABS = 2.0**-1060
_NORMAL = 2.0**-1000


def svd_rcond(shapes: FloatArray) -> FloatArray:
    """``sigma_min / sigma_max`` per matrix, computed exactly as :class:`~ipcverify.sets.Ellipsoid` does."""
    sv = np.linalg.svd(shapes, compute_uv=False)
    return np.asarray(sv[:, -1] / np.maximum(sv[:, 0], np.finfo(float).tiny))


def _rcond_lower_3(s: FloatArray) -> FloatArray:
    """A lower bound of ``sigma_min / sigma_max`` for 3x3 matrices (0 where not shown).

    ``|det C|`` is lowered by its rounding bound: ``8 u`` times the permanent of ``|C|`` (the
    relative part, Lemma 3 of ``proofs/float_landing.md``) plus ``2^-1060 max_j |C_0j|`` (products
    that underflow). The ratio is trusted only when ``det``, ``||C||_F^2`` and ``||adj C||_F^2`` are
    normal numbers, so that no other underflow or overflow can enter; the last factor
    ``1 - 1e-12`` covers the rounding of the norms (in any summation order), the square roots and
    the division. One compiled pass (:func:`ipcverify.network.rcond_lower_3`).
    """
    return rcond_lower_3(np.ascontiguousarray(s, dtype=np.float64), _U8, _ABS, _NORMAL)  # type: ignore[no-any-return]


def nonsingular(shapes: ArrayLike) -> tuple[NDArray[np.bool_], FloatArray]:
    """Per matrix: does :class:`~ipcverify.sets.Ellipsoid` accept it as non-singular?

    Parameters
    ----------
    shapes : array_like, shape (B, n, n)
        Finite shape matrices.

    Returns
    -------
    ok : bool ndarray (B,)
        Exactly the verdict of the SVD test ``sigma_min / sigma_max >= SINGULAR_RCOND``.
    rcond : ndarray (B,)
        The SVD's ratio where it was computed, NaN where the cheap bound settled it.
    """
    s = np.asarray(shapes, dtype=np.float64)
    rcond = np.full(len(s), np.nan)
    todo = np.arange(len(s))
    if s.shape[1:] == (3, 3) and len(s):
        lower = _rcond_lower_3(s)
        todo = np.flatnonzero(~(lower >= 2.0 * SINGULAR_RCOND))
    if len(todo):
        rcond[todo] = svd_rcond(s[todo])
    ok = np.ones(len(s), dtype=np.bool_)
    ok[todo] = rcond[todo] >= SINGULAR_RCOND
    return ok, rcond


class CheckedEllipsoid(Ellipsoid):
    """An :class:`~ipcverify.sets.Ellipsoid` whose non-singularity is checked by :func:`nonsingular`.

    The same checks and messages as :class:`~ipcverify.sets.Ellipsoid` (shapes, finiteness, the
    reciprocal condition number), with an SVD only for the matrices the cheap bound does not
    settle. Build it with :func:`checked_ellipsoid`.
    """

    def __post_init__(self) -> None:
        c = np.array(self.centers, dtype=np.float64, copy=True)
        s = np.array(self.shapes, dtype=np.float64, copy=True)
        c = c[None, :] if c.ndim == 1 else c
        s = s[None, :, :] if s.ndim == 2 else s
        shapes_ok = c.ndim == 2 and s.ndim == 3 and s.shape == (c.shape[0], c.shape[1], c.shape[1])
        if not (shapes_ok and c.shape[1] and np.isfinite(c).all() and np.isfinite(s).all()):
            Ellipsoid(c, s)  # a bad shape or a non-finite entry: the base class raises its own message
        ok, rcond = nonsingular(s)
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            raise SetError(
                f"ellipsoid {i}: shape matrix is singular (reciprocal condition number "
                f"{rcond[i]:.3g} < {SINGULAR_RCOND:g}); an IPC must output a non-singular C"
            )
        c.setflags(write=False)
        s.setflags(write=False)
        object.__setattr__(self, "centers", c)
        object.__setattr__(self, "shapes", s)


def checked_ellipsoid(centers: ArrayLike, shapes: ArrayLike) -> Ellipsoid:
    """A batch of ellipsoids validated by :func:`nonsingular` (see :class:`CheckedEllipsoid`).

    Examples
    --------
    >>> import numpy as np
    >>> e = checked_ellipsoid(np.zeros((2, 3)), np.stack([np.eye(3)] * 2))
    >>> isinstance(e, Ellipsoid), e.batch_size
    (True, 2)
    """
    return CheckedEllipsoid(centers, shapes)  # type: ignore[arg-type]
