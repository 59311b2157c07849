"""CLI command `export` (ONNX); registered on the shared app."""

from __future__ import annotations

from ipcverify.cli.app import app  # noqa: F401
