"""The simulator: everything between a reference trajectory and a camera measurement.

It owns the quadrotor dynamics (:mod:`.dynamics`, CasADi) and its LQR (:mod:`.lqr`), the
coordinate frames (:mod:`.frames`), where the landing pad lies (:mod:`.marker`), the flight's
state history (:mod:`.history`), the exploration paths flown to collect data (:mod:`.paths`),
the :class:`~.flight.Flight` that flies them together and measures (:mod:`.flight`),
frame-by-frame legs to a waypoint (:mod:`.legs`), and the simulator's configuration read from
``defaults.toml`` (:mod:`.config`).

The camera pipeline is the subpackage :mod:`.camera`, with one entry point,
:func:`~.camera.build_camera_stage`: the pinhole camera, the renderer, exposure and rolling
shutter, the camera-timing model (free-running clock, V4L2 queue, reader loop, motion
capture) or the previous fixed lag of ``k`` frames, the measurement it pairs with a state,
and the buffer size's one validator. The ArUco detector a :class:`~.flight.Flight` runs is
in :mod:`case_studies.quad_landing.perception`, below the simulator: it imports nothing of it.
"""
