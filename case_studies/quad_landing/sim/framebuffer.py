"""The camera's frame buffer: the source of the perception lag.

The camera captures a frame at every tick (60 Hz). A driver buffer of size ``k`` keeps
frames in order, so the frame the application reads at a control step was captured
``k`` ticks earlier — rendered from the state of ``k`` frame periods ago — while the
motion-capture state used with it is the current one. ``k = 0`` is an ideal camera
(the frame of the current state), used as a no-lag reference.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError

__all__ = ["Frame", "FrameBuffer", "MAX_BUFFER_SIZE", "check_buffer_size"]

#: Largest buffer size accepted (frames).
MAX_BUFFER_SIZE = 30


def check_buffer_size(size: int) -> int:
    """``size`` as a buffer size: a whole number of frames in ``[0, MAX_BUFFER_SIZE]``.

    Examples
    --------
    >>> check_buffer_size(3)
    3
    """
    if int(size) != size or not 0 <= size <= MAX_BUFFER_SIZE:
        raise InvalidInputError(
            f"buffer size must be an integer in [0, {MAX_BUFFER_SIZE}] frames, got {size}"
        )
    return int(size)


class Frame:
    """One captured frame: capture time (s), the state it shows, and its image.

    The image is either given or drawn by ``render()`` on first access and then kept.
    ``render`` must depend only on what was fixed at capture (the state and the noise
    draw), so a lazily drawn frame has exactly the pixels an eagerly drawn one would;
    frames that are never read are simply never drawn.

    Examples
    --------
    >>> f = Frame(0.0, np.zeros(12), render=lambda: np.zeros((2, 2), np.uint8))
    >>> f.image.shape
    (2, 2)
    """

    __slots__ = ("time", "state", "_image", "_render")

    def __init__(
        self,
        time: float,
        state: NDArray[np.float64],
        image: NDArray[np.uint8] | None = None,
        render: Callable[[], NDArray[np.uint8]] | None = None,
    ) -> None:
        if (image is None) == (render is None):
            raise InvalidInputError("give a Frame either an image or a render function")
        self.time = float(time)
        self.state = state
        self._image = image
        self._render = render

    @property
    def image(self) -> NDArray[np.uint8]:
        """The frame's image (drawn now if it was not yet)."""
        if self._image is None:
            assert self._render is not None
            self._image = self._render()
            self._render = None
        return self._image


class FrameBuffer:
    """A FIFO of the last ``size + 1`` captured frames; :meth:`read` returns the oldest.

    Parameters
    ----------
    size : int
        Buffer size ``k`` in frames (0 = no lag).

    Examples
    --------
    >>> buf = FrameBuffer(2)
    >>> img = np.zeros((2, 2), np.uint8)
    >>> for i in range(5):
    ...     buf.capture(Frame(float(i), np.zeros(12), img))
    >>> buf.read().time  # captured 2 ticks before the newest (t = 4)
    2.0
    """

    def __init__(self, size: int) -> None:
        self.size = check_buffer_size(size)
        self._frames: deque[Frame] = deque(maxlen=self.size + 1)

    def capture(self, frame: Frame) -> None:
        """Add the newest frame; the oldest beyond ``size + 1`` frames is dropped."""
        self._frames.append(frame)

    def fill(self, frame: Frame) -> None:
        """Empty the buffer and fill it with copies of ``frame`` (a still start)."""
        self._frames.clear()
        for _ in range(self.size + 1):
            self._frames.append(frame)

    def read(self) -> Frame:
        """The frame captured ``size`` ticks before the newest one."""
        if len(self._frames) < self.size + 1:
            raise InvalidInputError(
                f"the frame buffer holds {len(self._frames)} of {self.size + 1} frames; "
                "call fill() (Flight.reset does) before reading"
            )
        return self._frames[0]

    def newest(self) -> Frame:
        """The most recently captured frame."""
        if not self._frames:
            raise InvalidInputError("the frame buffer is empty; call fill() first")
        return self._frames[-1]

    def __len__(self) -> int:
        return len(self._frames)
