"""Perception: the ArUco pipeline that turns a camera image into the pad estimate ``yhat_C``.

It owns the detector and its settings (:mod:`.aruco`: OpenCV's ``ArucoDetector`` and
``solvePnP``) and the study of how each corner refinement biases the range
(:mod:`.bias`, ``python -m case_studies.quad_landing bias``), and the measurement of the
detector's time per frame that the camera-timing model scales to a Raspberry Pi 3
(:mod:`.reader_time`, ``python -m case_studies.quad_landing reader-timing``). The simulator
runs the detector on every image it reads; the detector knows nothing of the timing.
"""
