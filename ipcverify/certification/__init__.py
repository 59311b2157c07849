"""Certification.

The certificate and its report, Theorem 1 with its Lipschitz estimates, the group test, evaluation
and the baselines it is compared with.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.certification._certificate import CertificateStatus, CertifyResult
    from ipcverify.certification._certify import certify, write_certificate
    from ipcverify.certification._evaluation import evaluate

__all__ = [
    "CertificateStatus",
    "CertifyResult",
    "certify",
    "evaluate",
    "write_certificate",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
