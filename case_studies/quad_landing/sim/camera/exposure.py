"""One camera frame with its exposure time (motion blur) and its rolling shutter.

Row ``r`` of a frame whose first row starts at ``s`` integrates the scene over
``[s + r t_row, s + r t_row + E]`` (``t_row = readout / height``, ``E`` the exposure). The
frame is composed from ``K`` geometry-only sub-renders at the centres of ``K`` equal time
bins spanning ``[s, s + readout + E]``: every output row is a weighted sum of the
sub-renders' rows, the weight of bin ``j`` being the share of the row's exposure window
that falls in it (:func:`row_weights`; with ``E = 0``, linear interpolation between the two
bins around the row's instant). Optical blur and sensor noise are applied once to the
composed frame (:meth:`.render.Renderer.sensor_effects`), as for a plain render.

Cost (what keeps a reproduction within its time budget):

* ``K`` adapts to the motion: the pad's corners are projected at both ends of the span
  and ``K`` is chosen so that they move at most ``max_step_px`` between sub-renders
  (2 <= K <= ``max_subframes``);
* only the pad is sub-rendered, in a window around it (the union of its outlines over the
  span); the floor is drawn once, at mid-span. The floor is a low-contrast texture outside
  the pad's white border, so its own blur does not reach the marker.

Examples
--------
>>> w = row_weights(4, 2, exposure=1.0, readout=0.0)   # global shutter: every row the same
>>> w.tolist()
[[0.5, 0.5], [0.5, 0.5], [0.5, 0.5], [0.5, 0.5]]
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.sim.camera.render import Renderer
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.marker import Pad

__all__ = ["row_weights", "subframe_count", "render_exposed"]

UInt8Image = NDArray[np.uint8]
#: Pixels added around the pad's outline in the sub-rendered window (optical blur, rounding).
WINDOW_MARGIN_PX = 3


@lru_cache(maxsize=256)
def _weights(height: int, k: int, exposure: float, readout: float) -> NDArray[np.float32]:
    span = readout + exposure
    w = np.zeros((height, k), np.float64)
    if span <= 0 or k == 1:
        w[:, 0] = 1.0
        return w.astype(np.float32)
    edges = np.linspace(0.0, span, k + 1)
    starts = np.arange(height) * (readout / height)
    if exposure > 0:
        lo = np.maximum(edges[None, :-1], starts[:, None])
        hi = np.minimum(edges[None, 1:], starts[:, None] + exposure)
        w = np.clip(hi - lo, 0.0, None) / exposure
    else:  # instantaneous rows: linear interpolation between bin centres
        centres = 0.5 * (edges[:-1] + edges[1:])
        pos = np.interp(starts, centres, np.arange(k, dtype=np.float64))
        i0 = np.clip(np.floor(pos).astype(int), 0, k - 1)
        i1 = np.clip(i0 + 1, 0, k - 1)
        f = pos - i0
        w[np.arange(height), i0] += 1.0 - f
        w[np.arange(height), i1] += f
    w /= w.sum(axis=1, keepdims=True)
    out = w.astype(np.float32)
    out.setflags(write=False)
    return out


def row_weights(height: int, k: int, exposure: float, readout: float) -> NDArray[np.float32]:
    """``(height, k)`` weights of ``k`` equal time bins over ``[0, readout + exposure]``, per row.

    Row ``r`` integrates ``[r t_row, r t_row + exposure]``, ``t_row = readout / height``;
    each row's weights sum to 1 (read-only, cached).

    Examples
    --------
    >>> w = row_weights(240, 8, exposure=0.0, readout=0.008)   # pure rolling shutter
    >>> bool(w[0, 0] == 1.0 and w[-1, -1] > 0.9)
    True
    """
    return _weights(int(height), int(k), float(exposure), float(readout))


def subframe_count(move_px: float, max_step_px: float, max_subframes: int) -> int:
    """Sub-renders so that the pad moves at most ``max_step_px`` between two of them.

    Examples
    --------
    >>> subframe_count(0.0, 0.5, 24), subframe_count(3.2, 0.5, 24), subframe_count(100.0, 0.5, 24)
    (2, 8, 24)
    """
    return int(np.clip(np.ceil(move_px / max_step_px) + 1, 2, max_subframes))


def _outline_px(renderer: Renderer, pose: Pose, pad: Pad) -> NDArray[np.float64] | None:
    corners = renderer.pad_corners_camera(pose, pad)
    if np.any(corners[:, 2] < 0.05):
        return None
    return renderer.camera.project(corners)


def _window(outlines: list[NDArray[np.float64]], width: int, height: int) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` around every outline, clipped to the image; None if outside it."""
    pts = np.vstack(outlines)
    x0 = max(int(np.floor(pts[:, 0].min())) - WINDOW_MARGIN_PX, 0)
    y0 = max(int(np.floor(pts[:, 1].min())) - WINDOW_MARGIN_PX, 0)
    x1 = min(int(np.ceil(pts[:, 0].max())) + WINDOW_MARGIN_PX + 1, width)
    y1 = min(int(np.ceil(pts[:, 1].max())) + WINDOW_MARGIN_PX + 1, height)
    return None if x0 >= x1 or y0 >= y1 else (x0, y0, x1, y1)


def render_exposed(
    renderer: Renderer,
    pose_at: Callable[[float], Pose],
    pad: Pad,
    t_start: float,
    exposure: float,
    readout: float,
    noise_key: int,
    *,
    max_step_px: float = 0.5,
    max_subframes: int = 24,
) -> UInt8Image:
    """One frame whose first row starts integrating at ``t_start`` (see the module docstring).

    Parameters
    ----------
    renderer : Renderer
        The simulator's renderer (camera, marker, floor, blur and noise).
    pose_at : callable
        ``t -> T_CW`` (camera from world) at simulator time ``t``.
    pad : Pad
        Where the pad lies.
    t_start : float
        Exposure start of row 0 (s).
    exposure, readout : float
        Exposure time and first-to-last-row readout time (s).
    noise_key : int
        The frame's sensor-noise key (as :meth:`.render.Renderer.render`).
    max_step_px, max_subframes : float, int
        How finely the span is sampled (:func:`subframe_count`).

    Returns
    -------
    ndarray of uint8, shape (height, width)
    """
    span = readout + exposure
    if span <= 0:
        return renderer.render(pose_at(t_start), pad, noise_key)
    p = renderer.camera.params
    floor = renderer.blank()
    renderer.draw_floor(floor, pose_at(t_start + 0.5 * span))
    frame = floor.astype(np.float32)
    first, last = (
        _outline_px(renderer, pose_at(t_start), pad),
        _outline_px(renderer, pose_at(t_start + span), pad),
    )
    move = 0.0 if first is None or last is None else float(np.max(np.linalg.norm(last - first, axis=1)))
    k = subframe_count(move, max_step_px, max_subframes)
    times = t_start + (np.arange(k) + 0.5) * span / k
    poses = [pose_at(float(t)) for t in times]
    outlines = [o for T in poses if (o := _outline_px(renderer, T, pad)) is not None]
    win = _window(outlines, p.width, p.height) if len(outlines) == k else (0, 0, p.width, p.height)
    if outlines and win is not None:
        x0, y0, x1, y1 = win
        stack = np.empty((k, y1 - y0, x1 - x0), np.float32)
        for j, T in enumerate(poses):
            crop = floor[y0:y1, x0:x1].copy()
            renderer.draw_pad(crop, T, pad, origin=(x0, y0))
            stack[j] = crop
        w = row_weights(p.height, k, exposure, readout)[y0:y1]
        frame[y0:y1, x0:x1] = np.einsum("rk,krc->rc", w, stack)
    return renderer.sensor_effects(frame, noise_key)
