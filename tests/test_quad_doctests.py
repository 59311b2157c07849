"""The docstring examples of the quad-landing case study run and are right."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "bias", "camera", "collect", "config", "dynamics", "features", "framebuffer", "frames",
    "lqr", "marker", "paths", "perception", "sim",
]  # fmt: skip


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"case_studies.quad_landing.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
