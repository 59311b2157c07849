"""Decisions built on a set.

Containment proofs (Proposition 1), the landing rule and its float bound, the one-query path
(``IPCQuery``: engine -> calibration scale -> domain test, any output dimension) and the landing
decision on it (``LandingQuery(IPCQuery(model), G)``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.decision._landing_proof import LandingDecision, check_landing, landing_decision
    from ipcverify.decision._landing_query import LandingQuery
    from ipcverify.decision._query import IPCQuery

__all__ = [
    "IPCQuery",
    "LandingDecision",
    "LandingQuery",
    "check_landing",
    "landing_decision",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
