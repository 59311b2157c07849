"""Decisions built on a set.

Containment proofs (Proposition 1), the landing rule and its float bound, the one-query path
(``IPCQuery``: engine -> calibration scale -> domain test, any output dimension) and the landing
decision on it (``LandingQuery(IPCQuery(model), G)``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.decision._landing import (
        DecidedBy,
        LandingRule,
        QueryDecision,
        Verdict,
    )
    from ipcverify.decision._landing_bound import (
        BoundDecision,
        finish,
        float_tier,
        landing_by_bound,
        landing_by_bound_compiled,
        prepare,
    )
    from ipcverify.decision._landing_float import (
        landing_accept_float,
        landing_slack,
    )
    from ipcverify.decision._landing_proof import (
        LandingDecision,
        check_landing,
        landing_decision,
        turnoff_point,
    )
    from ipcverify.decision._landing_query import (
        LandingQuery,
        Transform,
    )
    from ipcverify.decision._query import (
        IPCQuery,
        QuerySet,
    )

__all__ = [
    "BoundDecision",
    "DecidedBy",
    "IPCQuery",
    "LandingDecision",
    "LandingQuery",
    "LandingRule",
    "QueryDecision",
    "QuerySet",
    "Transform",
    "Verdict",
    "check_landing",
    "finish",
    "float_tier",
    "landing_accept_float",
    "landing_by_bound",
    "landing_by_bound_compiled",
    "landing_decision",
    "landing_slack",
    "prepare",
    "turnoff_point",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
