"""Where does a calibrated set family lose volume against the oracle? Diagnose before tuning.

``python -m benchmarks.diagnose_tightness --toy`` runs the seeded self-check (planted
centre bias, planted size and shape errors are recovered); ``python -m
benchmarks.diagnose_tightness`` diagnoses the recipes ``v1`` (ipcverify's earlier default)
and ``tight`` (the default) on the known-oracle data of :mod:`benchmarks.oracle_data`
and writes ``benchmarks/diagnosis_results.json`` (a few minutes).

Decomposition
-------------
:func:`diagnose` takes any ellipsoidal method's calibrated sets ``E(c_i, C_i)`` on test
inputs and the oracle of those inputs (``y = mu_i + S_i u``), and splits the ratio of its
mean volume to the oracle's (both at coverage ``q``, by default ``1 - epsilon``) into a
product of factors along a chain of set families. Each family is given exactly population
coverage ``q`` under the true law by one global radius, found by Monte Carlo (``m`` draws
of ``u`` per input, the same draws for every family, so the ratios are paired):

1. ``centre``      -- the oracle's shape around the method's centres instead of ``mu``;
2. ``rel_scale``   -- the method's size ``|det C_i|`` per input with the oracle's orientation
   (does the size follow the truth's across inputs?);
3. ``orientation`` -- the method's full shape (eigen-directions and aspect ratios);
4. ``calibration`` -- the method's actual radius (its finite-sample PAC order statistic)
   against the radius that gives exactly coverage ``q`` for its own shape, split into the
   ``pac_margin`` (coverage ``k / (n + 1)`` instead of ``q``) and the ``draw`` (the
   calibration sample's luck).

The product of the four is the volume ratio (it telescopes). The order matters:
centre-first asks what the centre error costs a set that does not know about it,
shape-first what it costs given the method's own shape. Both orders are reported, and
their two-order Shapley split ``factors_symmetric`` = {centre, shape, calibration}
(geometric means; still a product equal to the ratio). Direct statistics: the RMS whitened
centre bias ``||S_i^-1 (c_i - mu_i)||``, the spread of the log relative size, the aspect
misfit of ``C_i S_i`` (log of arithmetic over geometric mean of its squared singular values;
0 for the oracle's orientation) and the population coverage of the sets.

Besides the ratio at ``q``, :func:`diagnose` reports the ratio **at the method's own
coverage** (``volume_ratio_same_coverage``): the method's mean volume over the oracle's at
the population coverage the method actually reaches (Monte Carlo, the same draws). A
PAC-calibrated family covers more than ``q`` by design (its order statistic is chosen so
that coverage falls below ``q`` with probability at most ``delta``), so the ratio at ``q``
charges it for the certificate's margin; the ratio at its own coverage compares set sizes
at equal coverage, the comparison the tightness issue's "Why" makes.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from benchmarks.common import write_json
from benchmarks.oracle_data import Oracle, make_hetlag
from ipcverify.sets import Ellipsoid
from ipcverify.sets._ellipsoid import unit_ball_log_volume

__all__ = ["DiagnosisResult", "diagnose", "toy_check", "diagnose_recipes", "main"]

FloatArray = NDArray[np.float64]
OUT = Path(__file__).with_name("diagnosis_results.json")


@dataclass(frozen=True)
class DiagnosisResult:
    """A method's mean-volume ratio to the oracle at coverage ``q`` and its factors (module docstring)."""

    q: float
    volume_ratio: float
    volume_ratio_same_coverage: float
    factors: dict[str, float]
    factors_shape_first: dict[str, float]
    factors_symmetric: dict[str, float]
    stats: dict[str, float]
    mean_volume: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "coverage_q": self.q,
            "volume_ratio_to_oracle": self.volume_ratio,
            "volume_ratio_to_oracle_same_coverage": self.volume_ratio_same_coverage,
            "factors": self.factors,
            "factors_shape_first": self.factors_shape_first,
            "factors_symmetric": self.factors_symmetric,
            "stats": self.stats,
            "mean_volume": self.mean_volume,
        }

    def summary(self) -> str:
        """One line: the ratio, the symmetric split and the direct statistics."""
        f, s = self.factors_symmetric, self.stats
        return (
            f"x{self.volume_ratio:.3g} oracle = centre x{f['centre']:.3g} * shape x{f['shape']:.3g} "
            f"* calibration x{f['calibration']:.3g} (PAC margin x{self.factors['pac_margin']:.3g}); "
            f"RMS whitened bias {s['rms_whitened_bias']:.3g}, sd log rel. size {s['sd_log_rel_scale']:.3g}, "
            f"aspect misfit {s['aspect_misfit']:.3g}"
        )


def _quantile(scores: FloatArray, q: float) -> float:
    return float(np.quantile(scores, q, method="inverted_cdf"))


def diagnose(
    sets: Ellipsoid,
    oracle: Oracle,
    q: float = 0.99,
    pac_k: int | None = None,
    pac_n: int | None = None,
    m: int = 400,
    seed: int = 0,
) -> DiagnosisResult:
    """Split a calibrated ellipsoid family's volume excess over the oracle (module docstring).

    Parameters
    ----------
    sets : Ellipsoid
        The method's calibrated sets on the test inputs.
    oracle : Oracle
        The true conditional law on the same inputs.
    q : float
        Coverage at which the oracle and the families are compared (``1 - epsilon``).
    pac_k, pac_n : int, optional
        The order statistic ``k`` of ``n`` calibration scores that set the method's radius;
        with them the calibration factor is split into the PAC margin and the draw.
    m : int
        Monte Carlo draws of ``u`` per input.
    seed : int
        Seed of the draws.
    """
    c = np.asarray(sets.centers, dtype=np.float64)
    C = np.asarray(sets.shapes, dtype=np.float64)
    N, n = c.shape
    S = oracle.chol
    U = oracle.sample_u(np.random.default_rng(seed), (N, m))  # (N, m, n)
    lvn = unit_ball_log_volume(n)
    log_det_S = np.log(np.abs(np.diagonal(S, axis1=1, axis2=2))).sum(1)
    bias = np.einsum("bij,bj->bi", np.linalg.inv(S), c - oracle.mean)  # c = mu + S bias
    A = np.einsum("bij,bjk->bik", C, S)  # score = ||A (u - bias)||
    sv = np.linalg.svd(A, compute_uv=False)
    log_det_A = np.log(sv).sum(1)
    kappa = np.exp(log_det_A / n)  # per-input relative size (det A = kappa^n)

    def mean_volume(logv: FloatArray) -> float:
        return float(np.exp(logv).mean())

    def ball_scores(size: FloatArray, b: FloatArray) -> FloatArray:  # oracle orientation, size per input
        return (np.linalg.norm(U - b[:, None, :], axis=2) * size[:, None]).ravel()

    def shape_scores(b: FloatArray) -> FloatArray:  # the method's full shape
        return np.linalg.norm(np.einsum("bij,bmj->bmi", A, U - b[:, None, :]), axis=2).ravel()

    def ball_volume(radius: float, size: FloatArray) -> float:
        return mean_volume(lvn + n * math.log(radius) - n * np.log(size) + log_det_S)

    def shape_volume(radius: float) -> float:
        return mean_volume(lvn + n * math.log(radius) - log_det_A + log_det_S)

    zeros, ones = np.zeros_like(bias), np.ones(N)
    v_oracle = mean_volume(oracle.log_volume(q))
    v_centre = ball_volume(_quantile(ball_scores(ones, bias), q), ones)
    v_rel = ball_volume(_quantile(ball_scores(kappa, bias), q), kappa)
    full = shape_scores(bias)
    r_full = _quantile(full, q)
    v_full = shape_volume(r_full)
    v_method = mean_volume(np.asarray(sets.log_volume()))
    v_rel0 = ball_volume(_quantile(ball_scores(kappa, zeros), q), kappa)  # shape first: around mu
    v_full0 = shape_volume(_quantile(shape_scores(zeros), q))
    factors = {
        "centre": v_centre / v_oracle,
        "rel_scale": v_rel / v_centre,
        "orientation": v_full / v_rel,
        "calibration": v_method / v_full,
        "pac_margin": math.nan,
        "draw": math.nan,
    }
    if pac_k is not None and pac_n is not None:
        factors["pac_margin"] = (_quantile(full, pac_k / (pac_n + 1.0)) / r_full) ** n
        factors["draw"] = factors["calibration"] / factors["pac_margin"]
    shape_first = {
        "rel_scale": v_rel0 / v_oracle,
        "orientation": v_full0 / v_rel0,
        "centre": v_full / v_full0,
        "calibration": v_method / v_full,
    }
    shape_1 = factors["rel_scale"] * factors["orientation"]
    shape_2 = shape_first["rel_scale"] * shape_first["orientation"]
    symmetric = {
        "centre": math.sqrt(factors["centre"] * shape_first["centre"]),
        "shape": math.sqrt(shape_1 * shape_2),
        "calibration": factors["calibration"],
    }
    aspect = np.log(np.mean(sv**2, axis=1)) - np.mean(np.log(sv**2), axis=1)
    covered = float(np.mean(full <= 1.0))
    # the oracle at the method's own population coverage (undefined if every draw was covered)
    v_same = mean_volume(oracle.log_volume(covered)) if covered < 1.0 else math.nan
    stats_ = {
        "rms_whitened_bias": float(np.sqrt(np.mean(np.sum(bias * bias, axis=1)))),
        "mean_whitened_bias": float(np.mean(np.linalg.norm(bias, axis=1))),
        "sd_log_rel_scale": float(np.std(np.log(kappa))),
        "aspect_misfit": float(np.mean(aspect)),
        "population_coverage": covered,
        "radius_oracle_q": oracle.radius(q),
    }
    volumes = {
        "oracle_q": v_oracle,
        "oracle_same_coverage": v_same,
        "centre_step": v_centre,
        "rel_scale_step": v_rel,
        "full_shape_step": v_full,
        "method": v_method,
    }
    return DiagnosisResult(
        q, v_method / v_oracle, v_method / v_same, factors, shape_first, symmetric, stats_, volumes
    )


#: Each planted error must show in its own factor by more than this, the others stay within TOL of 1.
PLANTED_MIN, TOL = 1.1, 0.03


def toy_check(seed: int = 0, n: int = 4000, m: int = 400) -> dict[str, Any]:
    """Seeded self-check: a planted centre bias, size error and shape error are each recovered.

    On :func:`~benchmarks.oracle_data.make_hetlag` inputs four "methods" are built from the
    oracle: exact; the centre moved by a whitened bias of norm 1 (random direction per
    input); the oracle's orientation with the size off by ``exp(0.5 z)`` per input
    (log-normal, ``sd log size = 0.5``); the aspect ratios distorted by diag(2, 1, 1/2) in
    whitened coordinates. Each is calibrated to coverage 0.99 on the exact law (many
    independent draws), so its calibration factor is ~1. A check passes when the planted
    error shows in its own factor (> 1.1x) while the others stay within 3 % of 1, and the
    direct statistics recover the planted sizes.
    """
    _, orc = make_hetlag(n, seed=seed + 12345)
    rng = np.random.default_rng(seed)
    Sinv = np.linalg.inv(orc.chol)
    q = 0.99

    def calibrated(centres: FloatArray, shapes: FloatArray) -> Ellipsoid:
        U = orc.sample_u(np.random.default_rng(seed + 1), (n, m))
        y = orc.mean[:, None, :] + np.einsum("bij,bmj->bmi", orc.chol, U)
        g = np.linalg.norm(np.einsum("bij,bmj->bmi", shapes, y - centres[:, None, :]), axis=2).ravel()
        return Ellipsoid(centres, shapes / _quantile(g, q))

    dirs = rng.standard_normal((n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    size = np.exp(0.5 * rng.standard_normal(n))
    aspect = np.diag([2.0, 1.0, 0.5])
    cases = {
        "exact": calibrated(orc.mean, Sinv),
        "planted_centre_bias": calibrated(orc.mean + np.einsum("bij,bj->bi", orc.chol, dirs), Sinv),
        "planted_rel_scale": calibrated(orc.mean, Sinv * size[:, None, None]),
        "planted_orientation": calibrated(orc.mean, np.einsum("ij,bjk->bik", aspect, Sinv)),
    }
    out: dict[str, Any] = {k: diagnose(v, orc, q=q, m=m, seed=seed + 7).to_dict() for k, v in cases.items()}
    f = {k: v["factors"] for k, v in out.items()}
    st = {k: v["stats"] for k, v in out.items()}
    names = ("centre", "rel_scale", "orientation", "calibration")

    def isolated(case: str, planted: str) -> bool:
        return f[case][planted] > PLANTED_MIN and all(
            abs(f[case][k] - 1.0) < TOL for k in names if k != planted
        )

    exact_aspect = math.log(np.mean([4.0, 1.0, 0.25])) - float(np.mean(np.log([4.0, 1.0, 0.25])))
    checks = {
        "exact_all_factors_near_1": all(abs(f["exact"][k] - 1.0) < TOL for k in names),
        "bias_in_centre_factor": isolated("planted_centre_bias", "centre"),
        "bias_size_recovered": abs(st["planted_centre_bias"]["mean_whitened_bias"] - 1.0) < 1e-6,
        "rel_scale_in_rel_scale_factor": isolated("planted_rel_scale", "rel_scale"),
        "rel_scale_size_recovered": abs(st["planted_rel_scale"]["sd_log_rel_scale"] - 0.5) < TOL,
        "orientation_in_orientation_factor": isolated("planted_orientation", "orientation"),
        "aspect_recovered": abs(st["planted_orientation"]["aspect_misfit"] - exact_aspect) < 1e-6,
    }
    out["checks"] = {k: bool(v) for k, v in checks.items()}
    out["all_passed"] = all(checks.values())
    return out


def diagnose_recipes(
    recipes: tuple[str, ...] = ("v1", "tight"),
    n: int = 5000,
    seeds: int = 2,
    laws: tuple[str, ...] = ("gauss", "t4"),
) -> dict[str, Any]:
    """Train each recipe (``seeds`` seeds), PAC-calibrate it and diagnose it on the known-oracle data.

    Data seeds 2000 / 2001 / 2002 (train / calibration / test), the seeds the research
    branch diagnosed the old default on. Returns ``{law: {recipe: [run, ...]}}``.
    """
    import torch

    from ipcverify.calibration import Global
    from ipcverify.contract import calibrate
    from ipcverify.training import TrainConfig, train

    torch.set_num_threads(1)
    res: dict[str, Any] = {}
    for law in laws:
        tr, _ = make_hetlag(n, seed=2000, law=law)
        cal, _ = make_hetlag(n, seed=2001, law=law)
        te, orc = make_hetlag(n, seed=2002, law=law)
        res[law] = {}
        for recipe in recipes:
            runs = []
            for seed in range(seeds):
                t0 = time.perf_counter()
                model = train(tr, train_config=TrainConfig.recipe(recipe, seed=seed), recipe=recipe).model
                secs = time.perf_counter() - t0
                cm = calibrate(model, cal, 0.01, 0.001, Global(mode="pac"), domain=None)
                th = cm.require_calibration().groups()[0]
                sets = cm.predict_unguarded(te.x, te.yhat)
                d = diagnose(sets, orc, 0.99, pac_k=th.k, pac_n=th.n)
                runs.append(
                    {**d.to_dict(), "coverage": float(sets.contains(te.y).mean()), "train_seconds": secs}
                )
                print(f"{law} {recipe} seed {seed}: {d.summary()}", flush=True)
            res[law][recipe] = runs
    return res


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--toy", action="store_true", help="run the planted-error self-check only")
    ap.add_argument("--n", type=int, default=5000)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help=f"JSON output (default {OUT.name}; --toy: none)")
    a = ap.parse_args(argv)
    if a.toy:
        r = toy_check()
        for k in ("exact", "planted_centre_bias", "planted_rel_scale", "planted_orientation"):
            f, s = r[k]["factors"], r[k]["stats"]
            print(
                f"{k:22s} "
                + " ".join(f"{x}={f[x]:.3f}" for x in ("centre", "rel_scale", "orientation", "calibration"))
                + f"  bias={s['mean_whitened_bias']:.3f} sdlog={s['sd_log_rel_scale']:.3f}"
                f" aspect={s['aspect_misfit']:.3f}"
            )
        print(r["checks"], "ALL PASSED" if r["all_passed"] else "FAILED")
        if a.out is not None:
            write_json(a.out, r)
        return r
    res = {
        "settings": {"n": a.n, "seeds": a.seeds, "epsilon": 0.01, "delta": 0.001},
        **diagnose_recipes(n=a.n, seeds=a.seeds),
    }
    write_json(a.out or OUT, res)
    return res


if __name__ == "__main__":
    main()
