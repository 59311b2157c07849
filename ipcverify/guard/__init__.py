"""The guard against shift.

The domain of validity (an exact k-nearest-neighbour test) and the run-time monitor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.guard._domain import (
        DEFAULT_ALPHA,
        DEFAULT_K,
        MAX_REFERENCE,
        DomainModel,
        DomainReport,
        other_group_distances,
    )
    from ipcverify.guard._domain_spec import (
        DomainSpec,
    )
    from ipcverify.guard._index import (
        BAND,
        LEAF_SIZE,
        MAX_INPUTS,
        DomainIndex,
        levels,
        one_blas_thread,
    )
    from ipcverify.guard._kernels import (
        domain_one,
        domain_rows,
        kth_rows,
        scan_rows,
        whiten_one,
        whiten_rows,
    )
    from ipcverify.guard._monitor import (
        ADAPTIVE_MEMORIES,
        ALARM_MARGIN,
        MAX_BET_FRACTION,
        BettingEProcess,
        MonitorConfig,
        MonitorResult,
        MonitorState,
        ViolationMonitor,
        plot_monitor,
    )

__all__ = [
    "ADAPTIVE_MEMORIES",
    "ALARM_MARGIN",
    "BAND",
    "DEFAULT_ALPHA",
    "DEFAULT_K",
    "LEAF_SIZE",
    "MAX_BET_FRACTION",
    "MAX_INPUTS",
    "MAX_REFERENCE",
    "BettingEProcess",
    "DomainIndex",
    "DomainModel",
    "DomainReport",
    "DomainSpec",
    "MonitorConfig",
    "MonitorResult",
    "MonitorState",
    "ViolationMonitor",
    "domain_one",
    "domain_rows",
    "kth_rows",
    "levels",
    "one_blas_thread",
    "other_group_distances",
    "plot_monitor",
    "scan_rows",
    "whiten_one",
    "whiten_rows",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
