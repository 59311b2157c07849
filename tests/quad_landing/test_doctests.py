"""The docstring examples of the quad-landing case study run and are right."""

from __future__ import annotations

import doctest
import importlib

import pytest

#: Every module of the case study with examples, by subpackage.
MODULES = [
    "arrays", "settings",
    "sim.camera.buffer", "sim.camera.driver_queue", "sim.camera.exposure", "sim.camera.features",
    "sim.camera.framebuffer", "sim.camera.measurement", "sim.camera.pinhole", "sim.camera.render",
    "sim.camera.stage", "sim.camera.timed", "sim.camera.timing",
    "sim.config", "sim.dynamics", "sim.flight", "sim.frames", "sim.history", "sim.legs", "sim.lqr",
    "sim.marker", "sim.paths",
    "perception.aruco", "perception.marker",
    "studies.bias", "studies.reader_time",
    "data.approach", "data.collect", "data.columns", "data.datasets", "data.pilot",
    "data.recording",
    "landing.contracts", "landing.runs", "landing.scenario", "landing.state_machine",
    "reproduction.campaign", "reproduction.certified", "reproduction.claims", "reproduction.collection",
    "reproduction.config", "reproduction.coverage", "reproduction.figures", "reproduction.learn",
    "reproduction.markdown", "reproduction.record",
    "reproduction.report_page", "reproduction.run",
    "reproduction.sensitivity", "reproduction.table1", "reproduction.timing_stats", "reproduction.variants",
]  # fmt: skip


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"case_studies.quad_landing.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has no examples: drop it from MODULES or add one"
    assert result.failed == 0
