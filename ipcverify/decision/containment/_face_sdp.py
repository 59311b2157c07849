"""The S-lemma SDP for boxes and polytopes: one LMI per face, solved by Clarabel, checked exactly.

``E(c, C)`` lies in the half-space ``a^T y <= b`` iff some ``lam >= 0`` makes the face LMI
``M(lam) = [[lam A, -a/2], [-a^T/2, s - lam]]`` positive semidefinite (``A = C^T C``,
``s = b - a^T c``; :mod:`~ipcverify.decision.containment._face_lmi`, ``proofs/containment.md`` section 3).
Here every face of a box or polytope gets its LMI, and Clarabel solves them together as one
SDP, called through its own Python API with a sparsity pattern fixed per ``(n, m)``.

**The program.** In the unit-ball coordinates of ``E`` (``y = c + C^{-1} u``, a congruence
that leaves ``lam`` unchanged) face ``j`` reads ``lam diag(I, -1) + [[0, -z/2], [-z^T/2, s]]``
with ``z = C^{-T} a``. Each face is divided by ``sigma = max(|s|, ||z||)`` and the solver
maximises ``sum_j t_j`` subject to ``face_j(lam_j) - t_j I >= 0``: the smallest eigenvalue of
each LMI, i.e. the most robust multiplier. Its solution is ``lam_j = s_j / 2`` (the centre of
the interval of feasible multipliers) with ``t_j = (s_j - ||z_j||) / 2``, so ``2 sigma t_j``
is the solver's estimate of the face's slack ``b_j - max_E a_j^T y``.

**The policy.** Anything but Clarabel's ``Solved`` is UNKNOWN. Each face is then certified
exactly (:meth:`~ipcverify.decision.containment.FaceSystem.check`) with the solver's ``lam``
taken as an exact rational; if that fails and the solver's ``lam`` lies within
``POLISH_TOLERANCE * sigma`` of the exact centre ``s / 2`` -- the solution of the program,
which the solver approaches only to about the square root of its tolerance, as the objective
is flat to first order there -- with ``s / 2`` itself. ``s / 2`` is feasible whenever the face
holds, touching included, so a face that holds is certified however tight it is. PROVEN
needs every face. REFUTED needs a point of ``E`` outside the outer set, checked exactly: the
maximiser ``u`` of a failing face read off the solver's dual (``Z = u u^T`` up to scale at
the optimum), or, when it lies within :data:`POLISH_TOLERANCE` of it, ``z / ||z||`` from the
data the solver was given, or the centre ``c``. Anything else is UNKNOWN.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> e = Ellipsoid(np.zeros(2), np.diag([2.0, 4.0]))        # semi-axes 0.5, 0.25
>>> prove_sdp_faces(e, Box([-0.5, -0.25], [0.5, 0.25])).status.name   # touching on every face
'PROVEN'
>>> cert = prove_sdp_faces(e, Box([-0.4, -1.0], [0.4, 1.0]))
>>> cert.status.name, cert.witness_floats()
('REFUTED', (0.5, 0.0))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._face_lmi import FaceSystem, face_centre
from ipcverify.decision.containment._geometry import ExactEllipsoid, witness_from_direction
from ipcverify.decision.containment._status import Method, Status
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import exact_vector
from ipcverify.sets._faces import FacedSet

FloatArray = NDArray[np.float64]

#: Relative distance within which the solver's multiplier (or dual maximiser) is replaced by
#: the program's exact solution. On faces that hold, Clarabel's default tolerances leave its
#: multiplier within about 1e-4 of ``s / 2`` (median 1e-5 over the landing decisions of
#: ``benchmarks/bench_containment.py``), so 1e-3 leaves an order of magnitude of room.
POLISH_TOLERANCE = 1e-3

_SQRT2 = math.sqrt(2.0)
_PATTERNS: dict[tuple[int, int], Any] = {}


@dataclass(frozen=True, eq=False)
class FaceSolution:
    """Clarabel's answer to the face SDP of one ellipsoid and one box or polytope.

    Attributes
    ----------
    status : str
        Clarabel's status (``"Solved"`` is the only one trusted), or why it did not run. A
        solve that ends in any other status is retried once without Clarabel's chordal
        decomposition; if the retry fails too, both are reported (``"AlmostSolved then
        MaxIterations"``).
    lam : ndarray, shape (m,) or None
        The multipliers in the units of the original LMI (``lam`` of ``M(lam)``).
    slack : ndarray, shape (m,) or None
        The solver's estimates of ``b_j - max_E a_j^T y`` (``2 sigma_j t_j``).
    direction : ndarray, shape (m, n) or None
        The maximiser of each face in the unit-ball coordinates, from the dual.
    z : ndarray, shape (m, n) or None
        ``C^{-T} a_j``, as given to the solver.
    scale : ndarray, shape (m,) or None
        ``sigma_j = max(|s_j|, ||z_j||)`` (1 where both vanish): each face's LMI is divided by it.
    """

    status: str
    lam: FloatArray | None = None
    slack: FloatArray | None = None
    direction: FloatArray | None = None
    z: FloatArray | None = None
    scale: FloatArray | None = None

    @property
    def solved(self) -> bool:
        """Clarabel reported ``Solved`` (``AlmostSolved`` and every other status are not)."""
        return self.status == "Solved" and self.lam is not None


def _pattern(n: int, m: int) -> Any:
    """Constant parts of the program (``A``, ``P``, ``q``, cones) and the svec layout, per ``(n, m)``."""
    import clarabel
    import scipy.sparse as sp

    key = (n, m)
    if key not in _PATTERNS:
        k = n + 1
        upper = [(i, j) for j in range(k) for i in range(j + 1)]  # Clarabel: upper triangle, by columns
        nv = len(upper)
        diag = [r for r, (i, j) in enumerate(upper) if i == j]
        rows, cols, vals = [], [], []
        for f in range(m):
            for d, r in enumerate(diag):  # lam_f multiplies diag(I, -1); t_f multiplies I
                rows += [f * nv + r, f * nv + r]
                cols += [f, m + f]
                vals += [1.0 if d == n else -1.0, 1.0]
        a_mat = sp.csc_matrix((vals, (rows, cols)), shape=(m * nv, 2 * m))
        p_mat = sp.csc_matrix((2 * m, 2 * m))
        q = np.concatenate([np.zeros(m), -np.ones(m)])
        cones = [clarabel.PSDTriangleConeT(k) for _ in range(m)]
        pos = {ij: r for r, ij in enumerate(upper)}
        side = np.array([pos[(i, n)] for i in range(n)])  # entries (i, n), i < n: off-diagonal
        corner = pos[(n, n)]
        _PATTERNS[key] = (a_mat, p_mat, q, cones, nv, side, corner)
    return _PATTERNS[key]


def solve_face_sdp(inner: Ellipsoid, outer: FacedSet) -> FaceSolution:
    """Solve the face SDP (see the module docstring) with Clarabel; float, not a proof.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid (a ``C`` singular in float64 gives a solution whose status says it
        did not run).
    outer : FacedSet
        A box or polytope of the same dimension.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box, Ellipsoid
    >>> sol = solve_face_sdp(Ellipsoid(np.zeros(1), np.eye(1)), Box([-2.0], [3.0]))
    >>> sol.status, np.round(sol.lam, 4).tolist(), np.round(sol.slack, 4).tolist()
    ('Solved', [1.5, 1.0], [2.0, 1.0])
    """
    import clarabel

    a_rows, b = outer.faces()
    c, cmat = inner.centers[0], inner.shapes[0]
    n, m = c.shape[0], b.shape[0]
    try:
        with np.errstate(all="ignore"):
            z = np.linalg.solve(cmat.T, a_rows.T).T  # C^{-T} a_j, row j
            s = b - a_rows @ c
            sigma = np.maximum(np.abs(s), np.linalg.norm(z, axis=1))
            sigma = np.where(sigma > 0, sigma, 1.0)
            zs, ss = z / sigma[:, None], s / sigma
    except np.linalg.LinAlgError:
        return FaceSolution("not run: C is singular in float64")
    if not (np.isfinite(zs).all() and np.isfinite(ss).all() and np.isfinite(sigma).all()):
        return FaceSolution("not run: the problem data overflow float64")
    a_mat, p_mat, q, cones, nv, side, corner = _pattern(n, m)
    rhs = np.zeros((m, nv))
    rhs[:, side] = -0.5 * _SQRT2 * zs
    rhs[:, corner] = ss
    statuses = []
    for chordal in (True, False):  # Clarabel's chordal decomposition is faster; rarely it stalls
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        if hasattr(settings, "chordal_decomposition_enable"):  # Clarabel >= 0.9
            settings.chordal_decomposition_enable = chordal
        try:
            sol = clarabel.DefaultSolver(p_mat, q, a_mat, rhs.ravel(), cones, settings).solve()
        except BaseException as exc:  # Clarabel's Rust panics arrive as BaseException subclasses
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            return FaceSolution(f"solver error ({type(exc).__name__}: {exc})")
        statuses.append(str(sol.status))
        if statuses[-1] == "Solved":
            break
    status = statuses[-1]
    if status != "Solved":
        return FaceSolution(" then ".join(statuses))
    x = np.asarray(sol.x, dtype=np.float64)
    dual = np.asarray(sol.z, dtype=np.float64).reshape(m, nv)
    with np.errstate(all="ignore"):
        direction = dual[:, side] / (_SQRT2 * dual[:, corner : corner + 1])
        lam = x[:m] * sigma
        slack = 2.0 * x[m:] * sigma
    return FaceSolution(status, lam, slack, direction, z, sigma)


def _certify_face(system: FaceSystem, j: int, lam: float, scale: float) -> tuple[Fraction | None, str]:
    """The multiplier that certifies face ``j`` exactly (the solver's, or the polished centre), or None."""
    raw = Fraction(max(lam, 0.0)) if math.isfinite(lam) else Fraction(0)
    if system.check(j, raw)[0]:
        return raw, "solver"
    centre = face_centre(system, j)
    near = abs(raw - centre) <= Fraction(POLISH_TOLERANCE) * Fraction(scale)
    if centre >= 0 and near and system.check(j, centre)[0]:
        return centre, "centre"
    return None, ""


def _refute(ex: ExactEllipsoid, outer: FacedSet, sol: FaceSolution, faces: list[int]) -> Any:
    """An exact witness from the failing faces' maximisers (dual, then polished), or None.

    The centre ``c`` is tried last: it refutes when a face fails even there (``b_j < a_j^T c``).
    """
    if sol.direction is None or sol.z is None or sol.slack is None:
        return None
    for j in sorted(faces, key=lambda f: float(sol.slack[f])):  # type: ignore[index]
        u = sol.direction[j]
        zj = sol.z[j]
        nz = float(np.linalg.norm(zj))
        candidates = [(u, "the solver's dual")]
        if nz > 0 and np.isfinite(u).all() and float(np.linalg.norm(u - zj / nz)) <= POLISH_TOLERANCE:
            candidates.append((zj / nz, "the dual polished to z / ||z||"))
        for cand, how in candidates:
            if not np.isfinite(cand).all() or not cand.any():
                continue
            y = witness_from_direction(ex, outer, exact_vector(cand), boundary=True)
            if y is not None:
                return tuple(y), f"witness: the maximiser of face {j} from {how}, checked exactly"
    y = witness_from_direction(ex, outer, exact_vector(np.zeros(len(ex.c))))
    if y is not None:
        return tuple(y), "witness: the centre of the inner set, outside a face, checked exactly"
    return None


def prove_sdp_faces(
    inner: Ellipsoid, outer: FacedSet, exact: ExactEllipsoid | None = None
) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` for a box or polytope by the face SDP, checked exactly.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid.
    outer : FacedSet
        The outer set: a Box, a Polytope or any set given by faces.
    exact : ExactEllipsoid, optional
        ``inner`` in exact arithmetic, if the caller has it (used only to build a witness).

    Returns
    -------
    ContainmentCertificate
        Method ``sdp``; PROVEN carries one exact multiplier per face (``"lambda"``, in the
        order of ``outer.faces()``), each passing :func:`~ipcverify.decision.containment.check_face_lmis`.
    """
    answer = partial(ContainmentCertificate, inner, outer, Method.SDP)
    sol = solve_face_sdp(inner, outer)
    m = outer.faces()[1].shape[0]
    lam, slack, scale = sol.lam, sol.slack, sol.scale
    if not sol.solved or lam is None or slack is None or scale is None:
        return answer(
            Status.UNKNOWN,
            detail=f"no Clarabel solution to trust ({sol.status}; only 'Solved' is): nothing is proven "
            "or refuted",
        )
    margin = float(slack.min()) if np.isfinite(slack).all() else None
    system = FaceSystem(inner, outer)
    chosen: list[Fraction] = []
    kinds = {"solver": 0, "centre": 0}
    failed = []
    for j in range(m):
        q, kind = _certify_face(system, j, float(lam[j]), float(scale[j]))
        if q is None:
            failed.append(j)
            chosen.append(Fraction(float(lam[j])) if math.isfinite(lam[j]) else Fraction(0))
        else:
            kinds[kind] += 1
            chosen.append(q)
    mult = {"lambda": tuple(chosen)}
    if not failed:
        return answer(
            Status.PROVEN,
            mult,
            margin,
            detail=f"Clarabel status 'Solved'; all {m} face LMIs hold exactly: {kinds['solver']} with the "
            f"solver's multiplier, {kinds['centre']} with the centre s/2 (solver within "
            f"{POLISH_TOLERANCE:g} of it); verify() re-checks them",
        )
    ex = ExactEllipsoid.of(inner) if exact is None else exact
    found = _refute(ex, outer, sol, failed)
    if found is not None:
        witness, how = found
        detail = f"Clarabel status 'Solved'; {how}"
        return answer(Status.REFUTED, mult, margin, witness, detail=detail)
    return answer(
        Status.UNKNOWN,
        mult,
        margin,
        detail=f"Clarabel status 'Solved', but face(s) {failed} have no multiplier that passes the exact "
        "check and no exact witness was found (the sets nearly touch): use the closed form",
    )
