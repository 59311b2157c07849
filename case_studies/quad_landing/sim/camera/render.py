"""The camera-image renderer: grey-scale frames of the pad on the floor.

A camera frame is drawn in three steps:

1. the floor: a fixed procedural texture (mottled concrete, optionally tiled) warped
   by the ground-plane homography (or flat grey when the horizon is in view, e.g.
   with a forward camera);
2. the pad: the marker texture from ``cv2.aruco.generateImageMarker`` with a white
   quiet zone, warped onto the image with ``cv2.warpPerspective`` by the homography
   that maps its corners to their pinhole projections;
3. optical blur (Gaussian) and sensor noise (Gaussian, in grey levels).

The steps are public (:meth:`Renderer.draw_floor`, :meth:`Renderer.draw_pad`,
:meth:`Renderer.sensor_effects`) so that an exposure can be composed from several
geometry-only sub-renders before the sensor effects are applied once
(:mod:`case_studies.quad_landing.sim.camera.exposure`).

The pad texture is kept as a pyramid of exact powers of two per cell; the level drawn
is the largest not bigger than the projected pad, so bilinear sampling only magnifies
and marker edges stay sharp and unbiased (no aliasing). Texture coordinates use the
OpenCV convention that pixel centres are integers, so a texture's outer edge is at
``-0.5`` and ``N - 0.5``. The pad and its marker are described in
:mod:`case_studies.quad_landing.sim.marker`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.perception.marker import MARKER_CELLS, MarkerParams, aruco_dictionary
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection
from case_studies.quad_landing.sim.camera.pinhole import Camera
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.marker import Pad
from ipcverify.errors import InvalidInputError

__all__ = ["RenderParams", "Renderer", "FLOORS"]

UInt8Image = NDArray[np.uint8]

#: Largest pad texture level, in pixels per cell.
MAX_CELL_PX = 64
#: Floor kinds: mottled concrete, concrete with 0.5 m tiles, or flat grey.
FLOORS: tuple[str, ...] = ("concrete", "tiles", "flat")
#: Number of pre-drawn sensor-noise fields.
NOISE_BANK = 8
#: Seed of the static floor texture (the floor is the same in every run).
FLOOR_SEED = 20230


@dataclass(frozen=True, kw_only=True)
class RenderParams(TomlSection, file=DEFAULTS_PATH, section="render"):
    """Image formation settings.

    Parameters
    ----------
    floor : {"concrete", "tiles", "flat"}
        Procedural mottled concrete, the same with 0.5 m tiles (grout lines make
        many square contours, so detection is about 2x slower), or flat grey.
    floor_gray : int
        Mean floor grey level (0..255).
    noise_std : float
        Sensor noise standard deviation (grey levels); 0 turns it off.
    blur_sigma : float
        Gaussian optical blur (px); 0 turns it off.

    Examples
    --------
    >>> RenderParams.defaults(noise_std=0.0).blur_sigma
    0.5
    """

    floor: str
    floor_gray: int
    noise_std: float
    blur_sigma: float

    def __post_init__(self) -> None:
        if self.floor not in FLOORS:
            raise InvalidInputError(f"render.floor must be one of {FLOORS}, got {self.floor!r}")
        if int(self.floor_gray) != self.floor_gray or not 20 <= self.floor_gray <= 235:
            raise InvalidInputError(
                f"render.floor_gray must be an integer in [20, 235], got {self.floor_gray}"
            )
        for name in ("noise_std", "blur_sigma"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 <= value <= 20):
                raise InvalidInputError(f"render.{name} must be in [0, 20], got {value}")


@lru_cache(maxsize=8)
def _pad_textures(marker: MarkerParams) -> dict[int, UInt8Image]:
    d = aruco_dictionary(marker.dictionary)
    out: dict[int, UInt8Image] = {}
    cell = 2
    while cell <= MAX_CELL_PX:
        m = int(marker.margin_cells) * cell
        tex = np.full((marker.cells * cell, marker.cells * cell), 255, np.uint8)
        tex[m : m + MARKER_CELLS * cell, m : m + MARKER_CELLS * cell] = cv2.aruco.generateImageMarker(
            d, int(marker.marker_id), MARKER_CELLS * cell, None, 1
        )
        tex.setflags(write=False)
        out[tex.shape[0]] = tex
        cell *= 2
    return out


#: Half side of the square covered by the floor texture (m) and its resolution (px/m).
FLOOR_HALF = 5.0
FLOOR_PX_PER_M = 102.4


@lru_cache(maxsize=8)
def _floor_texture(gray: int, tiles: bool) -> UInt8Image:
    rng = np.random.default_rng(FLOOR_SEED)
    n = int(round(2 * FLOOR_HALF * FLOOR_PX_PER_M))
    low = cv2.resize(rng.normal(0.0, 14.0, (20, 20)), (n, n), interpolation=cv2.INTER_CUBIC)
    grain = cv2.GaussianBlur(rng.normal(0.0, 10.0, (n, n)), (0, 0), 1.2)
    img = gray + low + grain
    if tiles:
        step = int(round(0.5 * FLOOR_PX_PER_M))  # 0.5 m tiles with dark grout
        for k in range(0, n, step):
            img[:, k : k + 2] -= 35.0
            img[k : k + 2, :] -= 35.0
    out = np.clip(img, 0, 255).astype(np.uint8)
    out.setflags(write=False)  # shared by every renderer with these settings
    return out


@lru_cache(maxsize=4)
def _noise_bank(std: float, height: int, width: int) -> NDArray[np.int16]:
    bank = np.random.default_rng(FLOOR_SEED + 1).normal(0.0, std, (NOISE_BANK, height + 64, width + 64))
    out = np.round(bank).astype(np.int16)
    out.setflags(write=False)
    return out


@dataclass(eq=False)
class Renderer:
    """Draws grey-scale camera frames of the pad on the floor.

    Parameters
    ----------
    camera : Camera
        Intrinsics (image size) of the frames.
    marker : MarkerParams
        The marker on the pad.
    params : RenderParams
        Floor, noise and blur.

    Examples
    --------
    >>> from case_studies.quad_landing.sim.config import load_config
    >>> cfg = load_config()
    >>> r = Renderer(Camera(cfg.camera), cfg.marker, cfg.render)
    >>> T_CW = Pose(np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, 1.0]))  # 1 m above
    >>> img = r.render(T_CW, Pad((0.0, 0.0, 0.0), yaw=0.0), np.random.default_rng(0))
    >>> img.shape, img.dtype
    ((240, 320), dtype('uint8'))
    """

    camera: Camera
    marker: MarkerParams
    params: RenderParams
    _textures: dict[int, UInt8Image] = field(init=False, repr=False)
    _floor: UInt8Image | None = field(init=False, repr=False)
    _noise: NDArray[np.int16] | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        self._textures = _pad_textures(self.marker)
        floor = self.params.floor
        self._floor = None if floor == "flat" else _floor_texture(self.params.floor_gray, floor == "tiles")

    def pad_corners_camera(self, camera_from_world: Pose, pad: Pad) -> FloatArray:
        """Outer corners of the white pad square in C, shape (4, 3), texture order."""
        return camera_from_world.compose(pad.world_from_marker()).apply(self.marker.pad_outline())

    def marker_corners_camera(self, camera_from_world: Pose, pad: Pad) -> FloatArray:
        """Marker corners in C, shape (4, 3), in ArUco order."""
        return camera_from_world.compose(pad.world_from_marker()).apply(self.marker.object_points())

    def draw_floor(self, img: UInt8Image, camera_from_world: Pose) -> None:
        """Warp the floor texture seen from ``camera_from_world`` into ``img`` (full frame, in place).

        Nothing is drawn (``img`` keeps its grey) when the floor plane does not fill the view
        (horizon in view) or the texture does not reach the image corners.
        """
        if self._floor is None:
            return
        p = self.camera.params
        # rays through the image corners must all hit the floor in front of the camera
        corners = np.array([[0, 0], [p.width, 0], [p.width, p.height], [0, p.height]], float)
        rays_c = np.column_stack(
            [(corners[:, 0] - 0.5 - p.cx) / p.fx, (corners[:, 1] - 0.5 - p.cy) / p.fy, np.ones(4)]
        )
        world_from_camera = camera_from_world.inverse()
        rays_w = world_from_camera.rotate(rays_c)
        height = world_from_camera.t[2]
        if height <= 0.01 or np.any(rays_w[:, 2] > -0.05 * np.linalg.norm(rays_w, axis=1)):
            return
        hit = world_from_camera.t[None, :2] - rays_w[:, :2] * (height / rays_w[:, 2:3])
        if np.any(np.abs(hit) > FLOOR_HALF):
            return
        # floor texture pixel (u, v) -> world (X, Y, 0) -> image
        s = 1.0 / FLOOR_PX_PER_M
        A = np.array([[s, 0.0, -FLOOR_HALF + 0.5 * s], [0.0, -s, FLOOR_HALF - 0.5 * s], [0, 0, 1]])
        R, t = camera_from_world.R, camera_from_world.t
        H = self.camera.K @ np.column_stack([R[:, 0], R[:, 1], t]) @ A
        cv2.warpPerspective(
            self._floor, H, (p.width, p.height), dst=img, flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_TRANSPARENT,
        )  # fmt: skip

    def draw_pad(
        self, img: UInt8Image, camera_from_world: Pose, pad: Pad, origin: tuple[int, int] = (0, 0)
    ) -> None:
        """Warp the pad texture into ``img`` (in place), whose pixel ``(0, 0)`` is image pixel ``origin``.

        ``img`` may be a window of the frame (a region of interest around the pad); the pad
        is drawn as it would be in the full frame. Nothing is drawn if part of the pad is
        behind the camera.
        """
        corners_c = self.pad_corners_camera(camera_from_world, pad)
        if np.any(corners_c[:, 2] < 0.05):
            return  # (part of) the pad is behind the camera: not drawn
        uv = self.camera.project(corners_c)
        side_px = float(np.max(np.linalg.norm(uv - np.roll(uv, 1, axis=0), axis=1)))
        sizes = sorted(self._textures)
        size = sizes[0]
        for s in sizes:
            if s <= side_px:
                size = s
        tex = self._textures[size]
        n = size - 0.5
        src = np.array([[-0.5, -0.5], [n, -0.5], [n, n], [-0.5, n]], np.float32)
        shifted = uv - np.asarray(origin, dtype=np.float64)
        H = cv2.getPerspectiveTransform(src, shifted.astype(np.float32))
        cv2.warpPerspective(
            tex, H, (img.shape[1], img.shape[0]), dst=img, flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_TRANSPARENT,
        )  # fmt: skip

    def noise_field(self, key: int) -> NDArray[np.int16]:
        """The sensor-noise field of key ``key`` (grey levels, shape ``(height, width)``)."""
        p = self.camera.params
        if self._noise is None:
            self._noise = _noise_bank(float(self.params.noise_std), p.height, p.width)
        i, oy, ox = key % NOISE_BANK, (key // NOISE_BANK) % 64, (key // (64 * NOISE_BANK)) % 64
        return self._noise[i, oy : oy + p.height, ox : ox + p.width]

    def render(self, camera_from_world: Pose, pad: Pad, noise: np.random.Generator | int) -> UInt8Image:
        """Draw one frame seen from ``camera_from_world`` (``T_CW``).

        Parameters
        ----------
        camera_from_world : Pose
            ``T_CW``, world coordinates to camera coordinates.
        pad : Pad
            The pad's pose in W.
        noise : numpy.random.Generator or int
            Picks this frame's sensor noise: a generator (one draw), or a non-negative
            integer key (equal keys give equal noise). The noise is a random window
            of a bank of pre-drawn Gaussian fields, which is much cheaper than fresh
            noise and, at 8 x 64 x 64 windows, never visibly repeats in a dataset.

        Returns
        -------
        ndarray of uint8, shape (height, width)
        """
        img = self.blank()
        self.draw_floor(img, camera_from_world)
        self.draw_pad(img, camera_from_world, pad)
        return self.sensor_effects(img, noise)

    def blank(self) -> UInt8Image:
        """A frame of the floor's mean grey (what :meth:`draw_floor` draws on)."""
        p = self.camera.params
        return np.full((p.height, p.width), self.params.floor_gray, np.uint8)

    def sensor_effects(
        self, image: UInt8Image | NDArray[np.float32], noise: np.random.Generator | int
    ) -> UInt8Image:
        """Optical blur, then sensor noise (``noise``: a generator or a key, as in :meth:`render`).

        ``image`` is the drawn scene, in grey levels (``uint8``, or ``float32`` for a frame
        composed from several sub-renders); the result is rounded and clipped to ``uint8``.
        """
        img: NDArray[Any] = image
        if self.params.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), self.params.blur_sigma)
        if img.dtype != np.uint8:
            img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        if self.params.noise_std > 0:
            key = int(noise.integers(2**31)) if isinstance(noise, np.random.Generator) else noise
            if key < 0:
                raise InvalidInputError(f"noise key must be >= 0, got {key}")
            noisy = img.astype(np.int16) + self.noise_field(key)
            img = np.clip(noisy, 0, 255).astype(np.uint8)
        return img.astype(np.uint8, copy=False)
