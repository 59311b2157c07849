"""Perception: the ArUco pipeline that turns a camera image into the pad estimate ``yhat_C``.

It owns the marker the detector looks for (:mod:`.marker`: dictionary, id, size, corners) and
the detector and its settings (:mod:`.aruco`: OpenCV's ``ArucoDetector`` and ``solvePnP``).
It imports nothing of the simulator: a camera is anything with an intrinsic matrix
(:class:`.aruco.Intrinsics`). The simulator runs the detector on every image it reads; the
detector knows nothing of the timing. The studies of the detector on simulated images (its
range bias, its time per frame) are in :mod:`case_studies.quad_landing.studies`.
"""
