"""The guard against shift.

The domain of validity (an exact k-nearest-neighbour test) and the run-time monitor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.guard._clustering import (
        RUNS_LEVEL,
        ViolationRuns,
    )
    from ipcverify.guard._domain import (
        DEFAULT_ALPHA,
        DEFAULT_K,
        MAX_REFERENCE,
        DomainModel,
    )
    from ipcverify.guard._domain_report import (
        DomainReport,
    )
    from ipcverify.guard._domain_spec import (
        DomainSpec,
    )
    from ipcverify.guard._eprocess import (
        BettingEProcess,
    )
    from ipcverify.guard._index import (
        BAND,
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
        ALARM_MARGIN,
        MonitorConfig,
        MonitorResult,
        MonitorState,
        ViolationMonitor,
        plot_monitor,
    )
    from ipcverify.guard._neighbours import (
        other_group_distances,
    )

__all__ = [
    "ALARM_MARGIN",
    "BAND",
    "DEFAULT_ALPHA",
    "DEFAULT_K",
    "MAX_INPUTS",
    "MAX_REFERENCE",
    "RUNS_LEVEL",
    "BettingEProcess",
    "DomainIndex",
    "DomainModel",
    "DomainReport",
    "DomainSpec",
    "MonitorConfig",
    "MonitorResult",
    "MonitorState",
    "ViolationMonitor",
    "ViolationRuns",
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
