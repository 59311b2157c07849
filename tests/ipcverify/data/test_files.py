"""Writing files: an output never replaces an input, and a refused write names the file asked for."""

from __future__ import annotations

import os
import tempfile

import pytest

from ipcverify.data._files import atomic_write, refuse_overwriting_input
from ipcverify.errors import InvalidInputError


@pytest.fixture
def data(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("x_0\n1\n", encoding="utf-8")
    return p


def test_another_path_is_fine(tmp_path, data):
    refuse_overwriting_input(tmp_path / "model.pt", {"DATA": data, "MODEL": None})


@pytest.mark.parametrize(
    "spell",
    [
        pytest.param(lambda p: p, id="same-path"),
        pytest.param(lambda p: p.parent / "." / p.name, id="other-spelling"),
        pytest.param(lambda p: os.path.relpath(p), id="relative"),
    ],
)
def test_the_input_itself_is_refused_naming_it_and_the_option(data, spell):
    with pytest.raises(
        InvalidInputError, match=r"--onnx .*log\.csv is also the input DATA; .*choose another"
    ):
        refuse_overwriting_input(spell(data), {"MODEL": None, "DATA": data}, option="--onnx")
    assert data.read_text(encoding="utf-8") == "x_0\n1\n"


def test_a_link_to_the_input_is_the_input(tmp_path, data):
    (tmp_path / "sym.csv").symlink_to(data)
    os.link(data, tmp_path / "hard.csv")
    for out in (tmp_path / "sym.csv", tmp_path / "hard.csv"):
        with pytest.raises(InvalidInputError, match="is also the input DATA"):
            refuse_overwriting_input(out, {"DATA": data})
    with pytest.raises(InvalidInputError, match="is also the input DATA"):  # the input given through a link
        refuse_overwriting_input(data, {"DATA": tmp_path / "sym.csv"})


def test_a_refused_temporary_file_is_reported_as_the_file_asked_for(tmp_path, monkeypatch):
    """A read-only folder: the error names ``out``, not the hidden temporary file beside it."""
    out = tmp_path / "m.pt"

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / ".m.pt.abc123.tmp"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(PermissionError) as info:
        atomic_write(out, lambda f: f.write(b"x"))
    assert info.value.filename == str(out) and info.value.errno == 13
    assert list(tmp_path.iterdir()) == []
