"""The frame buffer: the frame read is the one captured k ticks before the newest."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.sim.framebuffer import Frame, FrameBuffer
from ipcverify.errors import InvalidInputError


def test_frame_buffer_returns_the_frame_k_ticks_old():
    buf = FrameBuffer(3)
    img = np.zeros((2, 2), np.uint8)
    buf.fill(Frame(0.0, np.zeros(12), img))
    for i in range(1, 8):
        buf.capture(Frame(float(i), np.zeros(12), img))
        assert buf.read().time == max(i - 3, 0)
        assert buf.newest().time == i
    assert len(buf) == 4
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        FrameBuffer(-1)
    with pytest.raises(InvalidInputError, match="call fill"):
        FrameBuffer(2).read()
