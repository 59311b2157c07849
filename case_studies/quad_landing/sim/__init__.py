"""The simulator: everything between a reference trajectory and a camera measurement.

It owns the quadrotor dynamics (:mod:`.dynamics`, CasADi) and its LQR (:mod:`.lqr`), the
coordinate frames (:mod:`.frames`), the camera (:mod:`.camera`), the landing pad and its
marker (:mod:`.marker`), the image renderer (:mod:`.render`), the camera-frame state ``x_C``
(:mod:`.features`), the flight's state history (:mod:`.history`), the :class:`~.flight.Flight`
that flies them together and measures (:mod:`.flight`), frame-by-frame legs to a waypoint
(:mod:`.legs`), and the simulator's configuration read from ``defaults.toml`` (:mod:`.config`).

The camera stage decides which image a measurement reads and which state it is paired
with (:mod:`.measurement`): the camera-timing model (:mod:`.timing` parameters, the
free-running clock and V4L2 queue of :mod:`.driver_queue`, exposure and rolling shutter in
:mod:`.exposure`, put together in :mod:`.camera_stage`) or the previous fixed lag of ``k``
frames (:mod:`.framebuffer`). The ArUco detector a :class:`~.flight.Flight` runs is in
:mod:`case_studies.quad_landing.perception`.
"""
