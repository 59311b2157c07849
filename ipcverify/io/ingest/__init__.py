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
    from ipcverify.io.ingest._align import (
        Alignment,
        fit_alignment,
    )
    from ipcverify.io.ingest._api import (
        ingest_bags,
        ingest_trajectories,
        run_names,
    )
    from ipcverify.io.ingest._bagio import (
        BagContents,
        PoseRequest,
        StateSeries,
        TopicInfo,
        list_topics,
        read_bag,
        typestore_names,
    )
    from ipcverify.io.ingest._formats import (
        FORMATS,
        FileTrajectory,
        read_times,
        read_trajectory,
    )
    from ipcverify.io.ingest._manifest import (
        TABLE_SUFFIXES,
        input_record,
        manifest_path,
        write_ingested,
    )
    from ipcverify.io.ingest._messages import (
        POSE_TYPES,
        TF_TYPE,
        PoseRow,
        check_pose_type,
        field_reader,
        pose_rows,
    )
    from ipcverify.io.ingest._quantity import (
        QUANTITIES,
        STATE_COLUMNS,
        quantity_pair,
        state_features,
    )
    from ipcverify.io.ingest._rawpose import (
        raw_pose_parser,
    )
    from ipcverify.io.ingest._samples import (
        MANIFEST_KEY,
        REASONS,
        IngestOptions,
        RunData,
        build_samples,
    )
    from ipcverify.io.ingest._trajectory import (
        PosesAt,
        Trajectory,
    )

__all__ = [
    "FORMATS",
    "MANIFEST_KEY",
    "POSE_TYPES",
    "QUANTITIES",
    "REASONS",
    "STATE_COLUMNS",
    "TABLE_SUFFIXES",
    "TF_TYPE",
    "Alignment",
    "BagContents",
    "FileTrajectory",
    "IngestOptions",
    "PoseRequest",
    "PoseRow",
    "PosesAt",
    "RunData",
    "StateSeries",
    "TopicInfo",
    "Trajectory",
    "build_samples",
    "check_pose_type",
    "field_reader",
    "fit_alignment",
    "ingest_bags",
    "ingest_trajectories",
    "input_record",
    "list_topics",
    "manifest_path",
    "pose_rows",
    "quantity_pair",
    "raw_pose_parser",
    "read_bag",
    "read_times",
    "read_trajectory",
    "run_names",
    "state_features",
    "typestore_names",
    "write_ingested",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
