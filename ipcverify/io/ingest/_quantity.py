"""The perceived quantities built from a pair of trajectories, and the state features beside them.

For a sample start ``t0`` and end ``t1 = t0 + H``, with truth poses ``(p_gt, R_gt)`` and
estimated poses ``(p_est, R_est)`` interpolated at both times:

``displacement`` (needs no alignment)
    ``y = R_gt(t0)^T (p_gt(t1) - p_gt(t0))``, ``yhat = R_est(t0)^T (p_est(t1) - p_est(t0))``:
    the body-frame displacement over the horizon (3 numbers).
``position``
    ``y = p_gt(t0)``, ``yhat = p_est(t0)`` after the estimate is aligned to the truth's frame.
``pose``
    ``y = [p_gt(t0), log R_gt(t0)]``, ``yhat`` likewise: position and rotation vector (6
    numbers; the rotation vector jumps where the angle passes pi).

The state ``x`` is the same for every quantity, read from the estimate alone:
``x_0 = ||R_est(t0)^T (p_est(t1) - p_est(t0))|| / H`` (speed), ``x_1`` = the angle of
``R_est(t0)^T R_est(t1)`` over ``H`` (rotation rate), ``x_2..x_4 = R_est(t0)^T u`` (the world's
up axis ``u`` in the body frame: the direction opposite to gravity, which tells the body's tilt;
``u = e_z`` where z is up, as in EuRoC, TUM and ROS, ``u = -e_y`` in KITTI's camera frame, whose y
points down; :data:`UP_AXES`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ipcverify.io.ingest._trajectory import PosesAt

Quantity = Literal["displacement", "position", "pose"]
QUANTITIES: tuple[Quantity, ...] = ("displacement", "position", "pose")

#: A signed axis of the estimate's world frame.
UpAxis = Literal["+x", "-x", "+y", "-y", "+z", "-z"]
#: The world's up axis, by name: the unit vector in the estimate's world frame.
UP_AXES: dict[str, tuple[float, float, float]] = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}


def state_columns(up: str = "+z") -> tuple[str, ...]:
    """What the five state columns hold, with the world's up axis ``up`` (a key of :data:`UP_AXES`).

    Examples
    --------
    >>> state_columns()[2], state_columns("-y")[4]
    ('world z axis in the estimated body frame, x', 'world -y axis in the estimated body frame, z')
    """
    axis = "z" if up == "+z" else up  # "+z" keeps the name the manifests have always had
    return (
        "estimated speed |yhat_displacement| / H (m/s)",
        "estimated rotation rate, angle of R_est(t0)^T R_est(t1) / H (rad/s)",
        *(f"world {axis} axis in the estimated body frame, {c}" for c in "xyz"),
    )


#: What the five state columns hold where z is up.
STATE_COLUMNS = state_columns()


def _body_displacement(at0: PosesAt, at1: PosesAt) -> NDArray[np.float64]:
    return np.asarray(at0.rotation.inv().apply(at1.p - at0.p), dtype=np.float64).reshape(-1, 3)


def quantity_pair(
    quantity: Quantity, truth0: PosesAt, truth1: PosesAt, est0: PosesAt, est1: PosesAt
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(y, yhat)`` of the quantity at every sample (see the module docstring).

    Parameters
    ----------
    quantity : {"displacement", "position", "pose"}
        The quantity.
    truth0, truth1 : PosesAt
        Truth poses at the samples' starts ``t0`` and ends ``t1``.
    est0, est1 : PosesAt
        Estimated poses at the same times.
    """
    if quantity == "displacement":
        return _body_displacement(truth0, truth1), _body_displacement(est0, est1)
    if quantity == "position":
        return truth0.p, est0.p
    return (
        np.hstack([truth0.p, truth0.rotation.as_rotvec().reshape(-1, 3)]),
        np.hstack([est0.p, est0.rotation.as_rotvec().reshape(-1, 3)]),
    )


def state_features(est0: PosesAt, est1: PosesAt, horizon: float, up: str = "+z") -> NDArray[np.float64]:
    """The five state columns (see the module docstring) at every sample.

    Parameters
    ----------
    est0, est1 : PosesAt
        Estimated poses at the samples' starts ``t0`` and ends ``t1``.
    horizon : float
        ``H = t1 - t0`` (seconds).
    up : str
        The world's up axis in the estimate's frame, a key of :data:`UP_AXES`.
    """
    disp = _body_displacement(est0, est1)
    speed = np.linalg.norm(disp, axis=1) / horizon
    rate = (est0.rotation.inv() * est1.rotation).magnitude().reshape(-1) / horizon
    axis = np.asarray(est0.rotation.inv().apply(UP_AXES[up]), dtype=np.float64).reshape(-1, 3)
    return np.column_stack([speed, rate, axis])
