"""Robot logs in: ROS bags, MCAP and trajectory files to perception triples (x, y, yhat).

:func:`ingest_bags` and :func:`ingest_trajectories` return a pandas DataFrame with columns
``x_*``, ``y_*``, ``yhat_*``, ``run`` and ``t``, ready for
:meth:`ipcverify.data.PerceptionDataset.from_frame`; :func:`write_ingested` writes it with its
manifest. docs/ingest.md has a worked example, from a bag to a certificate.

Modules: ``trajectory`` (poses and their interpolation), ``formats`` (TUM, EuRoC, KITTI),
``bagio`` and ``messages`` (bags through rosbags), ``quantity`` (y, yhat and x),
``align`` (Umeyama), ``samples`` (time association, drops), ``manifest``, ``api``.
"""

from ipcverify.ingest.api import ingest_bags, ingest_trajectories
from ipcverify.ingest.bagio import list_topics
from ipcverify.ingest.formats import read_trajectory
from ipcverify.ingest.manifest import write_ingested
from ipcverify.ingest.samples import IngestOptions
from ipcverify.ingest.trajectory import Trajectory

__all__ = [
    "IngestOptions",
    "Trajectory",
    "ingest_bags",
    "ingest_trajectories",
    "list_topics",
    "read_trajectory",
    "write_ingested",
]
