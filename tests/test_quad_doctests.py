"""The docstring examples of the quad-landing case study run and are right."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "perception.bias", "sim.camera", "data.collect", "data.columns", "sim.config", "sim.dynamics",
    "sim.features", "sim.framebuffer", "sim.frames", "sim.lqr", "sim.marker", "sim.render", "data.paths",
    "perception.aruco", "sim.flight", "settings",
]  # fmt: skip


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"case_studies.quad_landing.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
