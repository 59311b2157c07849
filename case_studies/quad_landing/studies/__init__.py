"""Studies of the detector on simulated images, each behind a command.

It owns the study of how each corner refinement biases the range (:mod:`.bias`,
``python -m case_studies.quad_landing bias``) and the measurement of the detector's time per
frame that the camera-timing model scales to a Raspberry Pi 3 (:mod:`.reader_time`,
``python -m case_studies.quad_landing reader-timing``). They fly the simulator and run the
detector of :mod:`case_studies.quad_landing.perception`, so they sit above both.
"""
