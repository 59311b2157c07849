"""Robot logs in: ROS bags, MCAP and trajectory files to perception triples (x, y, yhat).

:func:`ingest_bags` and :func:`ingest_trajectories` return a pandas DataFrame with columns
``x_*``, ``y_*``, ``yhat_*``, ``run`` and ``t``, ready for
:meth:`ipcverify.data.PerceptionDataset.from_frame`; :func:`write_ingested` writes it with its
manifest. docs/ingest.md has a worked example, from a bag to a certificate.

Modules: ``trajectory`` (poses and their interpolation), ``formats`` (TUM, EuRoC, KITTI),
``bagio`` and ``messages`` (bags through rosbags), ``quantity`` (y, yhat and x),
``align`` (Umeyama), ``samples`` (time association, drops), ``manifest``, ``api``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.io.ingest._api import ingest_bags, ingest_trajectories
    from ipcverify.io.ingest._bagio import list_topics
    from ipcverify.io.ingest._manifest import write_ingested
    from ipcverify.io.ingest._samples import IngestOptions

__all__ = [
    "IngestOptions",
    "ingest_bags",
    "ingest_trajectories",
    "list_topics",
    "write_ingested",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
