"""The simulator: everything between a reference trajectory and a lagged camera measurement.

It owns the quadrotor dynamics (:mod:`.dynamics`, CasADi) and its LQR (:mod:`.lqr`), the
coordinate frames (:mod:`.frames`), the camera (:mod:`.camera`), the landing pad and its
marker (:mod:`.marker`), the image renderer (:mod:`.render`), the frame buffer that makes
the image lag the state (:mod:`.framebuffer`), the camera-frame state ``x_C``
(:mod:`.features`), the :class:`~.flight.Flight` that flies them together and measures
(:mod:`.flight`), frame-by-frame legs to a waypoint (:mod:`.legs`), and the simulator's
configuration read from ``defaults.toml`` (:mod:`.config`). The ArUco detector a
:class:`~.flight.Flight` runs is in :mod:`case_studies.quad_landing.perception`.
"""
