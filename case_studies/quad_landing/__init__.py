"""Quad-landing case study: a simulated rerun of the paper's quadcopter experiment.

A CasADi quadrotor (F450-class) flies under an LQR over a landing pad with an ArUco
marker; a 320 x 240, 60 fps camera renders what it sees, OpenCV's ArUco pipeline
estimates the pad position ``yhat_C``, and a frame buffer of size ``k`` makes the image
lag the state by ``k`` frames, the main error source in the paper. See
``docs/case_study.md``.

Layout, one subpackage per stage (each ``__init__`` says what it owns):
:mod:`.sim` (the simulator), :mod:`.perception` (the ArUco detector),
:mod:`.data` (exploration paths, approach flights, datasets), :mod:`.landing` (the
landing state machine and contracts) and :mod:`.reproduction` (the paper reproduction).
The settings live in ``defaults.toml`` and ``reproduce.toml`` beside this file, read by
:mod:`.settings`; :mod:`.cli` is the command line.

Public API
----------
* :func:`load_config`, :class:`SimConfig` — defaults from ``defaults.toml``.
* :class:`Flight` — ``reset`` / ``fly_to`` / ``hold`` / ``step`` / ``follow`` /
  ``measure`` / ``pad_in_view`` / ``cut_motors``.
* :class:`Measurement` — ``x_c``, ``y_c``, ``yhat_c`` and the camera pose ``T_WC``.
* :func:`transform_ellipsoid` — move an ellipsoid from the camera to the world frame.
* :func:`collect`, :class:`CollectStats`, :func:`write_dataset` — exploration data.
* The paper reproduction (``docs/reproduce.md``), imported on first use (they pull in
  torch and matplotlib): :func:`run_landing`, :class:`LandingRun`, :class:`Outcome`,
  :class:`LearnedContract`, :class:`TrivialContract`, :func:`draw_scenario`,
  :func:`run_campaign`, :func:`reproduce`, :func:`load_reproduce_config`.

Run ``python -m case_studies.quad_landing --help`` for the command line.
"""

from __future__ import annotations

import importlib
from typing import Any

from case_studies.quad_landing.data.collect import CollectStats, collect, write_dataset
from case_studies.quad_landing.data.columns import DATASET_COLUMNS, X_COLUMNS, X_DESCRIPTIONS
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.dynamics import hover_state
from case_studies.quad_landing.sim.flight import Flight, FlyResult, LandingResult, Measurement
from case_studies.quad_landing.sim.frames import Pose, transform_ellipsoid
from case_studies.quad_landing.sim.lqr import Reference
from case_studies.quad_landing.sim.marker import Pad

__all__ = [
    "DATASET_COLUMNS",
    "CollectStats",
    "Flight",
    "FlyResult",
    "LandingResult",
    "Measurement",
    "Pad",
    "Pose",
    "Reference",
    "SimConfig",
    "X_COLUMNS",
    "X_DESCRIPTIONS",
    "collect",
    "hover_state",
    "load_config",
    "transform_ellipsoid",
    "write_dataset",
    # the reproduction, loaded lazily (see __getattr__)
    "LandingRun",
    "LearnedContract",
    "Outcome",
    "TrivialContract",
    "draw_scenario",
    "load_reproduce_config",
    "reproduce",
    "run_campaign",
    "run_landing",
]

_LAZY = {
    "LandingRun": "landing.runs",
    "Outcome": "landing.runs",
    "run_landing": "landing.state_machine",
    "LearnedContract": "landing.contracts",
    "TrivialContract": "landing.contracts",
    "draw_scenario": "landing.scenario",
    "load_reproduce_config": "reproduction.config",
    "reproduce": "reproduction.pipeline",
    "run_campaign": "reproduction.campaign",
}


def __getattr__(name: str) -> Any:
    """Import the reproduction's names on first use (PEP 562)."""
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
