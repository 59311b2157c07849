"""The guard against shift.

The domain of validity (an exact k-nearest-neighbour test) and the run-time monitor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.guard._domain import DomainModel
    from ipcverify.guard._domain_report import DomainReport
    from ipcverify.guard._domain_spec import DomainSpec
    from ipcverify.guard._monitor import ViolationMonitor

__all__ = [
    "DomainModel",
    "DomainReport",
    "DomainSpec",
    "ViolationMonitor",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
