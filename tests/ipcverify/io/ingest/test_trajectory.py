"""Trajectory: validation, sorting, and interpolation (exact on the reference motion; the bracket rule)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipcverify.errors import DataError
from ipcverify.io.ingest._trajectory import Trajectory


def test_interpolation_is_exact_on_linear_motion_at_constant_rate(motions):
    truth, _ = motions
    stamps = np.sort(np.random.default_rng(0).uniform(0.0, 10.0, 300))
    tr = truth.trajectory(stamps)
    q = np.random.default_rng(1).uniform(stamps[0], stamps[-1], 500)
    at = tr.at(q, max_gap=1.0)
    assert at.ok.all()
    np.testing.assert_allclose(at.p, truth.position(q), rtol=0, atol=1e-12)
    diff = (at.rotation.inv() * truth.rotation(q)).magnitude()
    assert diff.max() < 1e-9


def test_rotations_take_the_short_way_between_stamps():
    a = Rotation.from_euler("z", 170, degrees=True)
    b = Rotation.from_euler("z", -170, degrees=True)
    tr = Trajectory([0.0, 1.0], np.zeros((2, 3)), np.vstack([a.as_quat(), b.as_quat()]))
    mid = tr.at([0.5], max_gap=2.0).rotation
    assert abs(abs(mid.as_euler("xyz", degrees=True)[0, 2]) - 180.0) < 1e-9


def test_bracket_rule_is_half_open_and_max_gap_is_inclusive():
    tr = Trajectory([0.0, 1.0, 3.0], np.zeros((3, 3)), np.tile([0.0, 0, 0, 1], (3, 1)))
    at = tr.at([-0.1, 0.0, 0.99, 1.0, 2.5, 3.0], max_gap=1.0)
    assert at.inside.tolist() == [False, True, True, True, True, False]
    assert at.bracket.tolist() == [np.inf, 1.0, 1.0, 2.0, 2.0, np.inf]
    assert at.ok.tolist() == [False, True, True, False, False, False]


def test_from_unsorted_sorts_and_keeps_the_first_of_a_repeated_stamp():
    tr, dropped = Trajectory.from_unsorted(
        [2.0, 1.0, 2.0, 0.0], [[2, 0, 0], [1, 0, 0], [9, 9, 9], [0, 0, 0]], np.tile([0.0, 0, 0, 1], (4, 1))
    )
    assert tr.t.tolist() == [0.0, 1.0, 2.0] and tr.p[:, 0].tolist() == [0.0, 1.0, 2.0] and dropped == 1


@pytest.mark.parametrize(
    ("t", "p", "q", "match"),
    [
        ([0.0, 1.0], np.zeros((2, 3)), [[0, 0, 0, 1], [0, 0, 0, 0]], r"pose 1 \(0-based\): quaternion of"),
        ([0.0, np.nan], np.zeros((2, 3)), np.tile([0.0, 0, 0, 1], (2, 1)), r"1 \(0-based\): non-finite st"),
        ([0.0, 0.0], np.zeros((2, 3)), np.tile([0.0, 0, 0, 1], (2, 1)), r"1 \(0-based\): stamp 0.0 does not"),
        ([0.0], np.zeros((1, 3)), [[0, 0, 0, 1]], "needs at least 2"),
        ([0.0, 1.0], np.zeros((2, 2)), np.tile([0.0, 0, 0, 1], (2, 1)), r"positions \(N, 3\)"),
    ],
)
def test_bad_trajectories_are_refused_with_the_pose_at_fault(t, p, q, match):
    with pytest.raises(DataError, match=match):
        Trajectory(t, p, q, "gt.txt")
