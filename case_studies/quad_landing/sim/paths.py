"""Predefined exploration paths for data collection.

Every path is a smooth periodic reference (position, velocity, yaw) around a centre
above the pad: one sinusoid per axis plus a yaw that spins and/or swings. Five
templates give diverse positions, velocities (up to about 2 m/s) and rotations:

* ``orbit`` — circles around the pad while the heading spins;
* ``figure8`` — a horizontal figure of eight with a swinging heading;
* ``bob`` — fast climbs and descents, off-centre, with slow spin;
* ``dash`` — quick side-to-side dashes (large roll rates), heading swinging;
* ``lissajous`` — random frequency ratios on all three axes, off-centre.

Template parameters are drawn from a seeded generator, then the horizontal part of the
path is shrunk (:func:`fit_to_view`) until the pad stays inside the image along the
whole path, with the attitude the quadrotor needs to follow it (thrust along
``a + g e_3``) and a pixel margin for tracking error.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection
from case_studies.quad_landing.sim.camera import Camera
from case_studies.quad_landing.sim.frames import mount_rotation
from case_studies.quad_landing.sim.lqr import Reference
from ipcverify.errors import InvalidInputError

__all__ = ["PathParams", "PathSample", "ExplorationPath", "TEMPLATES", "make_path", "exploration_paths",
           "fit_to_view"]  # fmt: skip


#: Template names, in the order :func:`exploration_paths` cycles through them.
TEMPLATES: tuple[str, ...] = ("orbit", "figure8", "bob", "dash", "lissajous")

#: Time step (s) at which a path is checked for visibility.
VIEW_CHECK_DT = 1.0 / 30.0


@dataclass(frozen=True, kw_only=True)
class PathParams(TomlSection, file=DEFAULTS_PATH, section="paths"):
    """Limits of the exploration paths.

    Parameters
    ----------
    duration : float
        Length of each path (s).
    min_height, max_height : float
        Range of the camera height above the pad (m).
    view_margin_px : float
        The planned pad outline is kept this many pixels inside the image.

    Examples
    --------
    >>> PathParams.defaults().max_height
    2.4
    """

    duration: float
    min_height: float
    max_height: float
    view_margin_px: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise InvalidInputError(f"paths.duration must be > 0 s, got {self.duration}")
        if not (0.3 <= self.min_height < self.max_height - 0.2):
            raise InvalidInputError(
                "paths.min_height must be >= 0.3 m and at least 0.2 m below paths.max_height, "
                f"got {self.min_height} and {self.max_height}"
            )
        if not (np.isfinite(self.view_margin_px) and self.view_margin_px >= 0):
            raise InvalidInputError(f"paths.view_margin_px must be >= 0, got {self.view_margin_px}")


class PathSample(NamedTuple):
    """A path's reference at N times: ``(N, 3)`` arrays and ``(N,)`` yaw and yaw rate."""

    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    jerk: FloatArray
    yaw: FloatArray
    yaw_rate: FloatArray


def _triple(name: str, value: ArrayLike) -> FloatArray:
    a = np.array(value, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"path {name} must be 3 finite numbers, got {value!r}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True)
class ExplorationPath:
    """A periodic reference ``p(t) = centre + a * sin(w t + phase)`` (per axis) with yaw.

    ``yaw(t) = yaw0 + yaw_rate t + yaw_amplitude sin(yaw_omega t)``.

    Examples
    --------
    >>> path = ExplorationPath(name="hover", center=(0, 0, 1), amplitude=(0, 0, 0),
    ...                        omega=(1, 1, 1), phase=(0, 0, 0), duration=2.0)
    >>> path.reference(0.5).position
    array([0., 0., 1.])
    """

    name: str
    center: FloatArray
    amplitude: FloatArray
    omega: FloatArray
    phase: FloatArray
    yaw0: float = 0.0
    yaw_rate: float = 0.0
    yaw_amplitude: float = 0.0
    yaw_omega: float = 0.0
    duration: float = 15.0

    def __post_init__(self) -> None:
        for name in ("center", "amplitude", "omega", "phase"):
            object.__setattr__(self, name, _triple(name, getattr(self, name)))
        for name in ("yaw0", "yaw_rate", "yaw_amplitude", "yaw_omega", "duration"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise InvalidInputError(f"path {name} must be finite, got {value}")
            object.__setattr__(self, name, value)
        if self.duration <= 0:
            raise InvalidInputError(f"path duration must be > 0 s, got {self.duration}")

    def sample(self, t: ArrayLike) -> PathSample:
        """The reference and its derivatives at times ``t`` (shape ``(N,)``)."""
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64))[:, None]
        arg = self.omega * tt + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a, w = self.amplitude, self.omega
        t1 = tt[:, 0]
        return PathSample(
            position=self.center + a * s,
            velocity=a * w * c,
            acceleration=-a * w**2 * s,
            jerk=-a * w**3 * c,
            yaw=self.yaw0 + self.yaw_rate * t1 + self.yaw_amplitude * np.sin(self.yaw_omega * t1),
            yaw_rate=self.yaw_rate + self.yaw_amplitude * self.yaw_omega * np.cos(self.yaw_omega * t1),
        )

    def reference(self, t: float) -> Reference:
        """The controller reference at time ``t`` (s)."""
        r = self.sample(t)
        return Reference(
            r.position[0], r.velocity[0], float(r.yaw[0]), r.acceleration[0], r.jerk[0],
            float(r.yaw_rate[0]),
        )  # fmt: skip

    def shrunk(self, factor: float, anchor: ArrayLike) -> ExplorationPath:
        """The path with its horizontal amplitudes and its centre's horizontal offset
        from ``anchor`` (a point in W, e.g. the pad) multiplied by ``factor``."""
        a = self.amplitude.copy()
        a[:2] *= factor
        c = self.center.copy()
        anchor_xy = np.asarray(anchor, dtype=np.float64).reshape(-1)[:2]
        c[:2] = anchor_xy + factor * (c[:2] - anchor_xy)
        return replace(self, amplitude=a, center=c)


def _attitudes(acc: FloatArray, yaw: FloatArray, gravity: float) -> FloatArray:
    """Body rotations (N, 3, 3) that put the thrust along ``acc + g e3`` with heading ``yaw``."""
    b3 = acc + np.array([0.0, 0.0, gravity])
    b3 /= np.linalg.norm(b3, axis=1, keepdims=True)
    heading = np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)])
    b2 = np.cross(b3, heading)
    b2 /= np.linalg.norm(b2, axis=1, keepdims=True)
    b1 = np.cross(b2, b3)
    return np.stack([b1, b2, b3], axis=2)


def pad_in_view_along(
    path: ExplorationPath, camera: Camera, pad_corners_w: FloatArray, margin_px: float,
    gravity: float = 9.81,
) -> bool:  # fmt: skip
    """True if the pad corners stay ``margin_px`` inside the image along the whole path."""
    t = np.arange(0.0, path.duration + 1e-9, VIEW_CHECK_DT)
    r = path.sample(t)
    pos = r.position
    R_WQ = _attitudes(r.acceleration, r.yaw, gravity)
    R_QC = mount_rotation(camera.params.tilt_deg)
    R_WC = R_WQ @ R_QC
    t_WC = pos + R_WQ @ np.asarray(camera.params.offset)
    # corners in C: R_CW (c - t_WC)
    d = pad_corners_w[None, :, :] - t_WC[:, None, :]
    pc = np.einsum("nji,nkj->nki", R_WC, d)
    if np.any(pc[..., 2] < 0.05):
        return False
    p = camera.params
    u = p.fx * pc[..., 0] / pc[..., 2] + p.cx
    v = p.fy * pc[..., 1] / pc[..., 2] + p.cy
    lo = -0.5 + margin_px
    return bool(
        np.all(u >= lo) and np.all(u <= p.width - 0.5 - margin_px)
        and np.all(v >= lo) and np.all(v <= p.height - 0.5 - margin_px)
    )  # fmt: skip


def fit_to_view(
    path: ExplorationPath, camera: Camera, pad_corners_w: FloatArray, margin_px: float,
    gravity: float = 9.81,
) -> ExplorationPath:  # fmt: skip
    """Shrink the horizontal motion (bisection on the scale) until the pad stays in view.

    Amplitudes and the centre's horizontal offset from the pad are scaled together,
    so the path contracts towards the column above the pad.

    Raises
    ------
    InvalidInputError
        If the pad is out of view even with no horizontal motion (path too low or
        the camera does not look down); raise the path or tilt the camera down.
    """
    if pad_in_view_along(path, camera, pad_corners_w, margin_px, gravity):
        return path
    anchor = pad_corners_w.mean(axis=0)
    if not pad_in_view_along(path.shrunk(0.0, anchor), camera, pad_corners_w, margin_px, gravity):
        raise InvalidInputError(
            f"path {path.name!r}: the pad leaves the image even without horizontal motion; "
            "raise paths.min_height, reduce view_margin_px or tilt the camera down"
        )
    lo, hi = 0.0, 1.0
    for _ in range(10):
        mid = 0.5 * (lo + hi)
        if pad_in_view_along(path.shrunk(mid, anchor), camera, pad_corners_w, margin_px, gravity):
            lo = mid
        else:
            hi = mid
    return path.shrunk(lo, anchor)


def make_path(
    template: str, rng: np.random.Generator, pad_position: ArrayLike, params: PathParams
) -> ExplorationPath:
    """Draw one path of the named template around the pad (before :func:`fit_to_view`).

    Examples
    --------
    >>> params = PathParams.defaults()
    >>> p = make_path("orbit", np.random.default_rng(0), (0, 0, 0), params)
    >>> p.name, bool(p.center[2] >= params.min_height)
    ('orbit', True)
    """
    if template not in TEMPLATES:
        raise InvalidInputError(f"unknown path template {template!r}; use one of {TEMPLATES}")
    lo, hi = params.min_height, params.max_height
    pad = np.asarray(pad_position, dtype=np.float64)
    u = rng.uniform
    phase = u(0, 2 * np.pi, 3)
    yaw0 = u(-np.pi, np.pi)
    if template == "orbit":
        h = u(lo + 0.2, hi - 0.1)
        r, w = u(0.3, 0.7), u(1.5, 3.0) * rng.choice([-1.0, 1.0])
        amp = (r, r, min(0.15, h - lo, hi - h))
        omega = (w, w, u(0.5, 1.5))
        phase[1] = phase[0] - np.pi / 2
        yaw = dict(yaw_rate=u(-0.8, 0.8), yaw_amplitude=u(0, 0.4), yaw_omega=u(0.5, 1.5))
    elif template == "figure8":
        h = u(lo + 0.2, hi - 0.1)
        w = u(1.2, 2.2)
        amp = (u(0.4, 0.8), u(0.3, 0.5), min(0.2, h - lo, hi - h))
        omega = (w, 2 * w, u(0.5, 1.5))
        yaw = dict(yaw_amplitude=u(0.3, 1.0), yaw_omega=u(0.6, 2.0))
    elif template == "bob":
        az = u(0.4, 0.5 * (hi - lo))
        h = u(lo + az, hi - az)
        amp = (u(0.05, 0.2), u(0.05, 0.2), az)
        # vertical speed up to ~2.3 m/s; peak acceleration at most 6 m/s^2 (thrust margin)
        omega = (u(0.5, 1.5), u(0.5, 1.5), min(u(2.5, 3.5), np.sqrt(6.0 / az)))
        yaw = dict(yaw_rate=u(-1.0, 1.0), yaw_amplitude=u(0, 0.3), yaw_omega=u(0.5, 1.5))
    elif template == "dash":
        h = u(lo + 0.4, hi - 0.1)
        # side-to-side along the body's y axis: the image's wide direction
        amp = (u(0.5, 0.9), u(0.0, 0.15), min(0.2, h - lo, hi - h))
        omega = (u(2.0, 3.5), u(0.5, 1.5), u(0.5, 1.5))
        yaw0 = np.pi / 2 + u(-0.3, 0.3)
        yaw = dict(yaw_amplitude=u(0.1, 0.5), yaw_omega=u(0.5, 2.0))
    else:  # lissajous
        az = u(0.1, 0.4 * (hi - lo))
        h = u(lo + az, hi - az)
        amp = (u(0.2, 0.7), u(0.2, 0.7), az)
        omega = (u(0.8, 2.5), u(0.8, 2.5), u(0.8, 2.5))
        yaw = dict(yaw_rate=u(-0.6, 0.6), yaw_amplitude=u(0, 0.8), yaw_omega=u(0.5, 2.0))
    # bob and lissajous are off-centre by up to 0.6 h so that the pad is seen across
    # the whole image; the others are centred over the pad to leave room for speed
    off = u(0.0, 0.6 * h) if template in ("bob", "lissajous") else 0.0
    bearing = u(-np.pi, np.pi)
    center = pad + np.array([off * np.cos(bearing), off * np.sin(bearing), h])
    return ExplorationPath(
        name=template, center=center, amplitude=np.array(amp), omega=np.array(omega), phase=phase,
        yaw0=yaw0, duration=params.duration, **yaw,
    )  # fmt: skip


def exploration_paths(
    count: int,
    rng: np.random.Generator,
    pad_corners_w: FloatArray,
    pad_position: ArrayLike,
    params: PathParams,
    camera: Camera,
    gravity: float = 9.81,
) -> list[ExplorationPath]:
    """``count`` paths cycling through :data:`TEMPLATES`, each fitted to keep the pad in view.

    Parameters
    ----------
    count : int
        Number of paths.
    rng : numpy.random.Generator
        Draws the template parameters.
    pad_corners_w : ndarray, shape (4, 3)
        Outline of the pad in W (kept in view).
    pad_position : array_like, shape (3,)
        Pad centre in W; paths are centred above it.
    params : PathParams
        Heights, duration and view margin.
    camera : Camera
        The camera whose image must contain the pad.
    gravity : float
        For the attitude needed to follow a path.
    """
    if int(count) != count or count < 1:
        raise InvalidInputError(f"number of paths must be a positive integer, got {count}")
    out = []
    for i in range(int(count)):
        path = make_path(TEMPLATES[i % len(TEMPLATES)], rng, pad_position, params)
        out.append(fit_to_view(path, camera, pad_corners_w, params.view_margin_px, gravity))
    return out
