"""TUM, EuRoC and KITTI files: one motion written in each layout reads back as the same trajectory."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from ipcverify.errors import DataError
from ipcverify.io.ingest._formats import read_times, read_trajectory


@pytest.fixture
def poses(motions):
    truth, _ = motions
    t = 1403638128.0 + np.arange(50) * 0.005
    return t, truth.position(t - t[0]), truth.rotation(t - t[0])


def _same(tr, t, p, rot, atol_t=0.0):
    np.testing.assert_allclose(tr.t, t, rtol=0, atol=atol_t)
    np.testing.assert_allclose(tr.p, p, rtol=0, atol=1e-12)
    assert (tr.at(tr.t[:-1], 1.0).rotation.inv() * rot[:-1]).magnitude().max() < 1e-9


def test_tum_with_comments_and_gzip(tmp_path, poses):
    t, p, rot = poses
    rows = np.column_stack([t, p, rot.as_quat()])
    text = "# time x y z qx qy qz qw\n" + "\n".join(" ".join(repr(float(v)) for v in r) for r in rows) + "\n"
    (tmp_path / "a.txt").write_text(text)
    with gzip.open(tmp_path / "a.txt.gz", "wt") as f:
        f.write(text)
    for name in ("a.txt", "a.txt.gz"):
        got = read_trajectory(tmp_path / name, "tum")
        _same(got.trajectory, t, p, rot)
        assert got.repeated_stamps == 0


def test_euroc_stamps_in_nanoseconds_and_w_first(tmp_path, poses):
    t, p, rot = poses
    ns = (np.round(t * 1e9)).astype(np.int64)
    q = rot.as_quat()
    lines = [
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], v"
    ]
    lines += [
        ",".join([str(n), *(repr(float(v)) for v in (*a, b[3], b[0], b[1], b[2])), "0.5"])
        for n, a, b in zip(ns, p, q, strict=True)
    ]
    (tmp_path / "data.csv").write_text("\n".join(lines) + "\n")
    got = read_trajectory(tmp_path / "data.csv", "euroc").trajectory
    _same(got, t, p, rot, atol_t=5e-7)
    # float64 seconds near 1.4e9 resolve 2**-22 s (about 0.24 us): the documented resolution
    assert abs((got.t[1] - got.t[0]) - 0.005) <= 2.0**-22


def test_kitti_poses_with_a_times_file(tmp_path, poses):
    t, p, rot = poses
    m = np.concatenate([rot.as_matrix(), p[:, :, None]], axis=2).reshape(-1, 12)
    np.savetxt(tmp_path / "00.txt", m, fmt="%.17g")
    np.savetxt(tmp_path / "times.txt", t - t[0], fmt="%.17g")
    got = read_trajectory(tmp_path / "00.txt", "kitti", times=tmp_path / "times.txt").trajectory
    _same(got, t - t[0], p, rot, atol_t=1e-12)
    assert read_times(tmp_path / "times.txt").shape == (50,)


@pytest.mark.parametrize(
    ("fmt", "text", "match"),
    [
        ("tum", "1 2 3\n", r"a\.txt, line 1: 3 values; a TUM line holds t x y z qx qy qz qw .*_format"),
        ("tum", "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1 7\n", "line 2: 9 values"),
        ("tum", "0 0 0 0 0 0 0 1\n1 0 x 0 0 0 0 1\n", "line 2: not a number"),
        ("tum", "# only a comment\n", "no poses"),
        ("euroc", "1,2,3\n", "a EUROC line holds timestamp_ns"),
        ("kitti", "1 0 0 0 0 1 0 0 0 0 1 0\n", "KITTI poses carry no stamps; give the times file"),
    ],
)
def test_bad_files_name_the_line_and_the_layout(tmp_path, fmt, text, match):
    (tmp_path / "a.txt").write_text(text)
    with pytest.raises(DataError, match=match):
        read_trajectory(tmp_path / "a.txt", fmt)


def test_kitti_times_must_match_the_poses(tmp_path):
    (tmp_path / "p.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n")
    (tmp_path / "times.txt").write_text("0.0\n")
    with pytest.raises(DataError, match="2 poses but 1 times"):
        read_trajectory(tmp_path / "p.txt", "kitti", times=tmp_path / "times.txt")
    with pytest.raises(DataError, match="times file applies to KITTI poses only"):
        read_trajectory(tmp_path / "p.txt", "tum", times=tmp_path / "times.txt")
