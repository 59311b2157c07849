"""The columns of every dataset the case study writes, and the row of one measurement.

Columns (float64 unless noted), in order (:data:`DATASET_COLUMNS`):

* ``x_0 .. x_11`` — state in the camera frame ``x_C``
  (:mod:`case_studies.quad_landing.sim.camera.features`; meanings in :data:`X_DESCRIPTIONS`);
* ``y_0 .. y_2`` — true pad centre in the camera frame ``y_C`` (m);
* ``yhat_0 .. yhat_2`` — perceived pad centre ``yhat_C`` from the lagged image (m);
* ``xw_0 .. xw_11`` — world-frame state ``[p, v, roll, pitch, yaw, omega]``;
* ``yw_0 .. yw_2``, ``yhatw_0 .. yhatw_2`` — true and perceived pad centre in W, the
  perceived one moved with the *current* camera pose, as on the vehicle;
* ``path`` (int), ``t`` — path (or flight) index and the time of the paired state on it (s);
* ``age`` — how much older the image is than the paired state (s): a diagnostic of the
  camera's timing, not an input of the IPC (the paper's vehicle does not know it).

The reproduction's datasets add ``source`` (:mod:`case_studies.quad_landing.data.datasets`).

Examples
--------
>>> len(DATASET_COLUMNS), FLOAT_COLUMNS[-1], DATASET_COLUMNS[-3:]
(39, 'yhatw_2', ('path', 't', 'age'))
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError

if TYPE_CHECKING:
    from case_studies.quad_landing.sim.flight import Measurement

__all__ = [
    "X_COLUMNS",
    "X_DESCRIPTIONS",
    "Y_COLUMNS",
    "YHAT_COLUMNS",
    "XW_COLUMNS",
    "YW_COLUMNS",
    "YHATW_COLUMNS",
    "FLOAT_COLUMNS",
    "DATASET_COLUMNS",
    "measurement_row",
]

#: Column names of ``x_C`` in datasets.
X_COLUMNS: tuple[str, ...] = tuple(f"x_{i}" for i in range(12))

#: One-line meaning of each ``x_C`` column.
X_DESCRIPTIONS: dict[str, str] = {
    "x_0": "nadir vector n_C (camera to floor, straight down), x_C component (m)",
    "x_1": "nadir vector n_C, y_C component (m)",
    "x_2": "nadir vector n_C, z_C component (m)",
    "x_3": "camera velocity v_C, x_C component (m/s)",
    "x_4": "camera velocity v_C, y_C component (m/s)",
    "x_5": "camera velocity v_C, z_C component (m/s)",
    "x_6": "unit down direction g_C, x_C component",
    "x_7": "unit down direction g_C, y_C component",
    "x_8": "unit down direction g_C, z_C component",
    "x_9": "angular velocity omega_C, about x_C (rad/s)",
    "x_10": "angular velocity omega_C, about y_C (rad/s)",
    "x_11": "angular velocity omega_C, about z_C (rad/s)",
}

#: True pad centre in C.
Y_COLUMNS: tuple[str, ...] = ("y_0", "y_1", "y_2")
#: Perceived pad centre in C.
YHAT_COLUMNS: tuple[str, ...] = ("yhat_0", "yhat_1", "yhat_2")
#: World-frame state ``[p, v, roll, pitch, yaw, omega]`` (:data:`.dynamics.STATE_NAMES`).
XW_COLUMNS: tuple[str, ...] = tuple(f"xw_{i}" for i in range(12))
#: True pad centre in W.
YW_COLUMNS: tuple[str, ...] = ("yw_0", "yw_1", "yw_2")
#: Perceived pad centre in W (moved with the current camera pose).
YHATW_COLUMNS: tuple[str, ...] = ("yhatw_0", "yhatw_1", "yhatw_2")
#: The float columns of a measurement row (:func:`measurement_row`).
FLOAT_COLUMNS: tuple[str, ...] = (
    X_COLUMNS + Y_COLUMNS + YHAT_COLUMNS + XW_COLUMNS + YW_COLUMNS + YHATW_COLUMNS
)
#: All dataset columns, in order.
DATASET_COLUMNS: tuple[str, ...] = FLOAT_COLUMNS + ("path", "t", "age")


def measurement_row(m: Measurement) -> NDArray[np.float64]:
    """The :data:`FLOAT_COLUMNS` of a measurement with a detection, shape ``(36,)``.

    Examples
    --------
    >>> from case_studies.quad_landing import Flight, hover_state
    >>> flight = Flight(buffer_size=0)
    >>> flight.reset(hover_state((0.05, -0.03, 1.2)))
    >>> measurement_row(flight.measure()).shape
    (36,)
    """
    if m.yhat_c is None:
        raise InvalidInputError("a measurement row needs a detection (yhat_c is None)")
    T = m.world_from_camera
    return np.concatenate([m.x_c, m.y_c, m.yhat_c, m.state, T.apply(m.y_c), T.apply(m.yhat_c)])
