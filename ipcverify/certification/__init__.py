"""Certification.

The certificate and its report, Theorem 1 with its Lipschitz estimates, the group test, evaluation
and the baselines it is compared with.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.certification._baselines import (
        BonferroniBox,
        Boxes,
        GlobalMahalanobis,
        fit_bonferroni_box,
        fit_global_mahalanobis,
    )
    from ipcverify.certification._certificate import (
        ASSUMPTION,
        Certificate,
        CertificateStatus,
        CertifyEvidence,
        CertifyResult,
        DataIdentity,
        ModelIdentity,
        VolumeSummary,
    )
    from ipcverify.certification._certify import (
        certify,
        certify_files,
        write_certificate,
    )
    from ipcverify.certification._certify_steps import (
        DEFAULT_DELTA,
        NO_STATISTICS,
        statement,
    )
    from ipcverify.certification._evaluation import (
        BinCoverage,
        Evaluation,
        WorstBin,
        coverage_by_bin,
        evaluate,
        worst_bin_coverage,
    )
    from ipcverify.certification._group_check import (
        group_test_step,
    )
    from ipcverify.certification._lipschitz import (
        LipschitzEstimate,
        Theorem1UnavailableError,
        empirical_lipschitz,
        per_sample_gradient_norms,
        sound_lipschitz,
    )
    from ipcverify.certification._report import (
        render_report,
    )
    from ipcverify.certification._report_plots import (
        figure_to_png,
        plot_coverage,
        plot_projections,
        plot_scores,
    )
    from ipcverify.certification._summarize import (
        summarize,
    )
    from ipcverify.certification._summary import (
        DEFAULT_UNITS,
        WEAK_EPSILON,
        CertificateSummary,
        Check,
        CheckLevel,
        Strength,
    )
    from ipcverify.certification._test_result import (
        Consistency,
        GroupTest,
        GroupTestResult,
        TestResult,
    )
    from ipcverify.certification._theorem1 import (
        Theorem1Bound,
        Theorem1Result,
        TrainingStatistics,
        n_needed,
        theorem1,
        theorem1_terms,
        truncated_hinge_mean,
    )

__all__ = [
    "ASSUMPTION",
    "DEFAULT_DELTA",
    "DEFAULT_UNITS",
    "NO_STATISTICS",
    "WEAK_EPSILON",
    "BinCoverage",
    "BonferroniBox",
    "Boxes",
    "Certificate",
    "CertificateStatus",
    "CertificateSummary",
    "CertifyEvidence",
    "CertifyResult",
    "Check",
    "CheckLevel",
    "Consistency",
    "DataIdentity",
    "Evaluation",
    "GlobalMahalanobis",
    "GroupTest",
    "GroupTestResult",
    "LipschitzEstimate",
    "ModelIdentity",
    "Strength",
    "TestResult",
    "Theorem1Bound",
    "Theorem1Result",
    "Theorem1UnavailableError",
    "TrainingStatistics",
    "VolumeSummary",
    "WorstBin",
    "certify",
    "certify_files",
    "coverage_by_bin",
    "empirical_lipschitz",
    "evaluate",
    "figure_to_png",
    "fit_bonferroni_box",
    "fit_global_mahalanobis",
    "group_test_step",
    "n_needed",
    "per_sample_gradient_norms",
    "plot_coverage",
    "plot_projections",
    "plot_scores",
    "render_report",
    "sound_lipschitz",
    "statement",
    "summarize",
    "theorem1",
    "theorem1_terms",
    "truncated_hinge_mean",
    "worst_bin_coverage",
    "write_certificate",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
