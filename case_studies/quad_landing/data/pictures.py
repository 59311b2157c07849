"""Pictures for the docs: a camera frame with the detection, the exploration paths, error per buffer size.

Plots are drawn on :class:`matplotlib.figure.Figure` objects (Agg canvas, no pyplot
and no global backend change); images are written as PNG files.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from case_studies.quad_landing.data.collect import collect, pad_outline_world, path_rng, start_state
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.paths import TEMPLATES, fit_to_view, make_path
from ipcverify.errors import InvalidInputError

__all__ = ["camera_frame_picture", "paths_picture", "lag_error_picture", "write_pictures"]

#: File names written by :func:`write_pictures`.
PICTURES = ("quad_camera_frame.png", "quad_paths.png", "quad_lag_error.png")


def camera_frame_picture(out: Path, *, buffer_size: int = 2, seed: int = 0,
                         config: SimConfig | None = None) -> dict[str, float]:  # fmt: skip
    """Draw a camera frame read at speed, with the ArUco detection overlaid.

    Red: the marker as detected in the image the reader loop read (motion blur and rolling
    shutter included). Green: where the marker really is at the motion-capture state paired
    with it. Returns a few numbers about the frame (speed, error, age) for the caption.
    """
    cfg = load_config() if config is None else config
    flight = Flight(cfg, buffer_size=buffer_size, seed=seed)
    rng = np.random.default_rng(seed)
    path = make_path("dash", rng, cfg.pad.position, cfg.paths)
    path = fit_to_view(path, flight.camera, pad_outline_world(cfg), cfg.paths.view_margin_px)
    flight.reset(start_state(path))
    best = None
    for _ in flight.follow(path, 3.0):
        m = flight.measure()
        speed = float(np.linalg.norm(m.state[3:6]))
        if m.detected and (best is None or speed > best[0]):
            best = (speed, m, flight.camera_stage.image().copy())
    if best is None:
        raise InvalidInputError("the marker was never detected on the picture path; try a seed")
    speed, m, gray = best
    scale = 2
    img = np.asarray(cv2.resize(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), None, fx=scale, fy=scale,
                                interpolation=cv2.INTER_NEAREST), dtype=np.uint8)  # fmt: skip
    corners = flight.perception.detect(gray)
    if corners is None:  # pragma: no cover - the measurement was a detection
        raise InvalidInputError("the picture's frame has no detection")
    drawn = (corners * scale + (scale - 1) / 2).astype(np.float32).reshape(1, 4, 2)
    cv2.aruco.drawDetectedMarkers(img, [drawn], np.array([[cfg.marker.marker_id]]), (0, 0, 255))
    true_c = flight.renderer.marker_corners_camera(m.world_from_camera.inverse(), flight.pad)
    uv = flight.camera.project(true_c) * scale + (scale - 1) / 2
    cv2.polylines(img, [np.round(uv).astype(np.int32).reshape(-1, 1, 2)], True, (0, 200, 0), 2)
    if m.yhat_c is None:  # pragma: no cover - the measurement was a detection
        raise InvalidInputError("the picture's frame has no estimate")
    err = float(np.linalg.norm(m.yhat_c - m.y_c))
    lines = [
        f"buffer size {buffer_size}: image {1000 * m.age:.0f} ms older than the state",
        f"speed {speed:.2f} m/s, |yhat_C - y_C| = {100 * err:.1f} cm",
        "red: detected in the image   green: true at the paired state",
    ]
    img[: 14 + 22 * len(lines)] //= 3  # dark banner behind the text
    for i, text in enumerate(lines):
        cv2.putText(img, text, (8, 22 + 22 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                    (255, 255, 255), 1, cv2.LINE_AA)  # fmt: skip
    cv2.imwrite(str(out), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    return {"speed": speed, "error": err, "age": float(m.age)}


def paths_picture(out: Path, *, seed: int = 0, config: SimConfig | None = None) -> None:
    """Plot the first five paths of a collection with ``seed`` (one per template), as flown."""
    cfg = load_config() if config is None else config
    flight = Flight(cfg, buffer_size=0, seed=seed)
    outline = pad_outline_world(cfg)
    fig = Figure(figsize=(9.0, 4.2), dpi=90)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    colors = colormaps["tab10"](np.arange(10))  # its ten colours, RGBA
    for i, name in enumerate(TEMPLATES):
        path = make_path(name, path_rng(seed, i), cfg.pad.position, cfg.paths)
        path = fit_to_view(path, flight.camera, outline, cfg.paths.view_margin_px)
        flight.reset(start_state(path))
        track = np.array([flight.state[:3] for _ in flight.follow(path, 8.0)])
        speed = np.linalg.norm(np.diff(track, axis=0), axis=1) * cfg.camera.fps
        label = f"{name} (≤{speed.max():.1f} m/s)"
        ax3.plot(track[:, 0], track[:, 1], track[:, 2], color=colors[i], lw=1.0, label=label)
        ax2.plot(track[:, 0], track[:, 1], color=colors[i], lw=1.0, label=label)
    pad = np.vstack([outline, outline[:1]])
    ax3.plot(pad[:, 0], pad[:, 1], pad[:, 2], color="k", lw=2)
    ax2.fill(outline[:, 0], outline[:, 1], color="0.3", label="pad (0.4 m)")
    ax3.set(xlabel="x_W (m)", ylabel="y_W (m)", zlabel="z_W (m)", zlim=(0, 2.6),
            title="exploration paths (8 s each)")  # fmt: skip
    ax2.set(xlabel="x_W (m)", ylabel="y_W (m)", title="top view", aspect="equal")
    ax2.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(out)


def lag_error_picture(out: Path, *, n: int = 1500, seed: int = 0,
                      config: SimConfig | None = None) -> dict[int, float]:  # fmt: skip
    """Box plot of ``|yhat_C - y_C|`` for buffer sizes 0 (ideal camera) ..5 on the same paths.

    Returns the median error (m) per buffer size.
    """
    errors, medians = [], {}
    for k in range(6):
        data, _ = collect(n, buffer_size=k, seed=seed, config=config)
        e = np.linalg.norm(
            data[["yhat_0", "yhat_1", "yhat_2"]].to_numpy() - data[["y_0", "y_1", "y_2"]].to_numpy(),
            axis=1,
        )
        errors.append(100 * e)
        medians[k] = float(np.median(e))
    fig = Figure(figsize=(6.0, 3.4), dpi=90)
    ax = fig.add_subplot()
    ax.boxplot(errors, whis=(1, 99), showfliers=False)
    ax.set_xticks(range(1, 7), [str(k) for k in range(6)])
    ax.set(xlabel="camera buffer size (0: ideal camera)", ylabel="|yhat_C - y_C| (cm)",
           title=f"error per buffer size ({n} samples each; whiskers 1-99 %)")  # fmt: skip
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out)
    return medians


def write_pictures(out_dir: str | Path, *, seed: int = 0, config: SimConfig | None = None) -> dict:
    """Write :data:`PICTURES` into ``out_dir``; returns the numbers shown in them."""
    d = Path(out_dir)
    if not d.is_dir():
        raise InvalidInputError(f"picture directory {d} does not exist; create it first")
    frame = camera_frame_picture(d / PICTURES[0], seed=seed, config=config)
    paths_picture(d / PICTURES[1], seed=seed, config=config)
    medians = lag_error_picture(d / PICTURES[2], seed=seed, config=config)
    return {"frame": frame, "median_error_by_k": medians}
