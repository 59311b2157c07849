"""build_samples against the formulas: grid, quantities, drops, clock offset, alignment, state."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import DataError, Hint
from ipcverify.io.ingest._bagio import StateSeries
from ipcverify.io.ingest._quantity import UP_AXES
from ipcverify.io.ingest._samples import MANIFEST_KEY, IngestOptions, RunData, build_samples
from ipcverify.io.ingest._trajectory import Trajectory

H, S = 0.5, 0.25


def _direct(truth, est, t0_est, offset_truth_clock):
    """y, yhat and x straight from the motions (the estimate's clock; truth(t) is the same instant)."""
    y = truth.displacement(t0_est, H)
    yhat = est.displacement(t0_est, H)
    rot = est.rotation(t0_est)
    x = np.column_stack(
        [
            np.linalg.norm(yhat, axis=1) / H,
            np.full(len(t0_est), est.w),
            rot.inv().apply([0.0, 0.0, 1.0]),
        ]
    )
    return x, y, yhat


def test_displacement_matches_the_formulas_at_different_rates_and_clocks(motions):
    truth, est = motions
    # truth at 120 Hz on a clock 1000.3 s ahead, estimate at 20 Hz from 0.013 s
    t_truth = np.arange(-1.0, 12.0, 1 / 120)
    t_est = 0.013 + np.arange(0.0, 10.0, 1 / 20)
    run = RunData("r", truth.trajectory(t_truth).shifted(1000.3), est.trajectory(t_est))
    df = build_samples([run], IngestOptions(t_offset=-1000.3))
    t0 = S * np.arange(len(df))
    assert t0[-1] + H < t_est[-1] - t_est[0] <= t0[-1] + S + H  # the whole grid, nothing more
    x, y, yhat = _direct(truth, est, t_est[0] + t0, 1000.3)
    np.testing.assert_allclose(df["t"], t0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(df[["y_0", "y_1", "y_2"]], y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(df[["yhat_0", "yhat_1", "yhat_2"]], yhat, rtol=0, atol=1e-9)
    np.testing.assert_allclose(df[[f"x_{i}" for i in range(5)]], x, rtol=0, atol=1e-9)
    assert (df["run"] == "r").all()
    account = df.attrs[MANIFEST_KEY]["runs"][0]
    assert account["rows"] == len(df) == account["sample_starts"]


def test_samples_whose_brackets_are_too_wide_are_dropped_and_counted(motions):
    truth, est = motions
    t_truth = np.arange(0.0, 10.0, 0.01)
    t_truth = t_truth[(t_truth < 3.0) | (t_truth > 3.6)]  # a 0.61 s hole in the truth
    t_est = np.arange(0.0, 8.0, 0.05)
    t_est = t_est[(t_est < 5.0) | (t_est > 5.3)]  # a 0.35 s hole in the estimate
    df = build_samples([RunData("r", truth.trajectory(t_truth), est.trajectory(t_est))], IngestOptions())
    t0 = S * np.arange(int((t_est[-1] - H) / S) + 1)
    t0 = t0[t0 + H < t_est[-1]]

    def hit(lo, hi):  # t0 or t1 falls in [lo, hi)
        return ((t0 >= lo) & (t0 < hi)) | ((t0 + H >= lo) & (t0 + H < hi))

    est_gap = hit(t_est[t_est < 5.0][-1], t_est[t_est > 5.3][0])
    truth_gap = hit(t_truth[t_truth < 3.0][-1], t_truth[t_truth > 3.6][0]) & ~est_gap
    assert df.attrs[MANIFEST_KEY]["runs"][0]["dropped"] == {
        "estimate_gap": int(est_gap.sum()),
        "truth_outside": 0,
        "truth_gap": int(truth_gap.sum()),
        "no_state": 0,
    }
    np.testing.assert_allclose(df["t"], t0[~est_gap & ~truth_gap], atol=1e-12)
    assert est_gap.sum() > 0 and truth_gap.sum() > 0


def test_state_fields_are_held_causally(motions):
    truth, est = motions
    t = np.arange(0.0, 5.0, 0.02)
    st = np.array([0.3, 1.0, 2.6, 2.75])  # state stamps on the estimate's clock
    state = StateSeries(st, np.array([[1.0], [2.0], [3.0], [4.0]]), ("speed",))
    df = build_samples([RunData("r", truth.trajectory(t), est.trajectory(t), state)], IngestOptions())
    held = {0.5: 1.0, 0.75: 1.0, 1.0: 2.0, 2.5: 2.0, 2.75: 4.0, 4.0: 4.0}
    got = dict(zip(df["t"].round(9), df["x_5"], strict=True))
    assert all(got[k] == v for k, v in held.items())
    assert df["t"].min() == 0.5  # t0 = 0 and 0.25 precede the first state message
    assert df.attrs[MANIFEST_KEY]["runs"][0]["dropped"]["no_state"] == 2
    assert df.attrs[MANIFEST_KEY]["x_columns"]["x_5"] == "speed"


def test_se3_alignment_fitted_on_named_runs_recovers_the_frame():
    t = np.arange(0.0, 6.0, 0.05)
    p = np.column_stack([np.cos(t), np.sin(1.3 * t), 0.1 * t])
    rot = Rotation.from_rotvec(np.outer(t, [0.1, 0.2, 0.7]))
    truth = Trajectory(t, p, rot.as_quat())
    R = Rotation.from_euler("xyz", [0.2, -0.1, 1.0])
    shift = np.array([3.0, -1.0, 0.5])
    # the same motion seen in another world frame, p' = R^T (p - shift)
    other = Trajectory(t, R.inv().apply(p - shift), (R.inv() * rot).as_quat())
    opts = IngestOptions(quantity="position", align="se3", align_runs=("fit",))
    df = build_samples([RunData("fit", truth, other), RunData("use", truth, other)], opts)
    a = df.attrs[MANIFEST_KEY]["alignment"]
    np.testing.assert_allclose(a["rotation"], R.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(a["translation"], shift, atol=1e-9)
    assert a["fitted_on_runs"] == ["fit"] and a["rmse"] < 1e-9 and a["scale"] == 1.0
    np.testing.assert_allclose(df[["yhat_0", "yhat_1", "yhat_2"]], df[["y_0", "y_1", "y_2"]], atol=1e-9)
    pose = build_samples(
        [RunData("fit", truth, other)], IngestOptions(quantity="pose", align="se3", align_runs=("fit",))
    )
    np.testing.assert_allclose(
        pose[[f"yhat_{i}" for i in range(6)]], pose[[f"y_{i}" for i in range(6)]], atol=1e-8
    )
    # unaligned, the estimate is off by the frame change, and a hint quotes the error it makes
    with pytest.warns(
        Hint, match=r"quantity=\'position\' without align .*median position error up to 3\."
    ) as w:
        raw = build_samples([RunData("fit", truth, other)], IngestOptions(quantity="position"))
    err = np.linalg.norm(
        raw[["yhat_0", "yhat_1", "yhat_2"]].to_numpy() - raw[["y_0", "y_1", "y_2"]].to_numpy(), axis=1
    )
    assert f"{np.median(err):.4g} in run fit" in str(w[0].message)
    with warnings.catch_warnings():  # aligned, or displacements: no hint
        warnings.simplefilter("error", Hint)
        build_samples([RunData("fit", truth, other)], opts)
        build_samples([RunData("fit", truth, other)], IngestOptions())
    assert (
        np.abs(raw[["yhat_0", "yhat_1", "yhat_2"]].to_numpy() - raw[["y_0", "y_1", "y_2"]].to_numpy()).max()
        > 1
    )


def test_the_frame_makes_a_dataset_with_runs_as_groups(motions):
    truth, est = motions
    t = np.arange(0.0, 4.0, 0.05)
    runs = [RunData(n, truth.trajectory(t), est.trajectory(t)) for n in ("a", "b", "c")]
    ds = PerceptionDataset.from_frame(build_samples(runs, IngestOptions()))
    assert ds.x_dim == 5 and ds.y_dim == 3 and sorted(set(ds.column("run"))) == ["a", "b", "c"]
    parts = ds.split((1 / 3, 1 / 3, 1 / 3), seed=0, group_column="run")
    assert {len(set(p.column("run"))) for p in (parts.train, parts.calibration, parts.test)} == {1}


def test_no_overlap_prints_both_spans_and_hints_at_units_or_offset(motions):
    truth, est = motions
    t = np.arange(0.0, 5.0, 0.05)
    with pytest.raises(DataError, match=r"truth \(100\.000000\.\.104\.950000 s.*t_offset \(about -100 s"):
        build_samples([RunData("r", truth.trajectory(t + 100.0), est.trajectory(t))], IngestOptions())
    ns = truth.trajectory(t * 1e9 + 1.4e18)
    with pytest.raises(DataError, match="looks like nanoseconds"):
        build_samples([RunData("r", ns, est.trajectory(t + 1.4e9))], IngestOptions())


def test_a_grid_far_denser_than_the_poses_is_refused_before_it_is_allocated(motions):
    """Nanosecond stamps read as seconds (both files, e.g. EuRoC as TUM) or a mistyped --stride."""
    truth, est = motions
    t = np.arange(0.0, 20.0, 0.05)  # 400 poses
    ns = t * 1e9 + 1.4e18
    run = RunData("r", truth.trajectory(ns), est.trajectory(ns + 1e6))
    ns_match = (
        r"run r: the estimate spans 1\.995e\+10 s, .*7\.98e\+10 sample starts for its 400 poses; the stamps "
        r"look like nanoseconds: this estimate_format reads seconds"
    )
    with pytest.raises(DataError, match=ns_match):
        build_samples([run], IngestOptions())
    run = RunData("r", truth.trajectory(t), est.trajectory(t))
    with pytest.raises(
        DataError, match=r"at stride=1e-09 s makes 1\.95e\+10 sample starts .*use a larger stride"
    ):
        build_samples([run], IngestOptions(stride=1e-9))
    fine = build_samples([run], IngestOptions(stride=0.05 / 1000))  # 1000 starts a pose: still accepted
    assert len(fine) > 100_000


def test_too_few_truth_samples_gives_the_count_and_the_largest_gap(motions):
    truth, est = motions
    t_truth = np.arange(0.0, 10.0, 0.5)
    with pytest.raises(
        DataError,
        match=r"the truth has 8 stamps within the estimate's span and its largest gap there is 0\.5 s",
    ):
        build_samples(
            [RunData("r", truth.trajectory(t_truth), est.trajectory(np.arange(0.2, 4.3, 0.05)))],
            IngestOptions(),
        )


def test_gaps_that_drop_most_samples_give_a_hint_with_the_largest_gap(motions):
    """Keyframe-rate estimates (bundle adjustment): the run is kept, and the hint says how far to
    raise --max-gap; with that --max-gap every sample is kept and nothing is hinted."""
    truth, est = motions
    t_truth = np.arange(0.0, 10.0, 0.01)
    t_est = np.concatenate([np.arange(0.0, 1.0, 0.05), np.arange(1.0, 8.0, 0.4)])  # 0.4 s keyframes
    run = RunData("kf", truth.trajectory(t_truth), est.trajectory(t_est))
    with pytest.warns(
        Hint,
        match=r"run kf: \d+ of \d+ samples dropped as estimate_gap: the estimate's stamps "
        r"are up to 0\.4 s apart, above max_gap=0\.2 s; to keep them, raise max_gap above 0\.4",
    ):
        df = build_samples([run], IngestOptions())
    account = df.attrs[MANIFEST_KEY]["runs"][0]
    assert 0 < account["rows"] and 2 * account["dropped"]["estimate_gap"] > account["sample_starts"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", Hint)
        wide = build_samples([run], IngestOptions(max_gap=0.41))
        assert wide.attrs[MANIFEST_KEY]["runs"][0]["rows"] == account["sample_starts"]
        # a few samples dropped (under half) are counted, not hinted
        holed = t_truth[(t_truth < 3.0) | (t_truth > 3.6)]
        few = build_samples(
            [RunData("r", truth.trajectory(holed), est.trajectory(t_est))], IngestOptions(max_gap=0.41)
        )
        assert 0 < few.attrs[MANIFEST_KEY]["runs"][0]["dropped"]["truth_gap"] < len(few)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"horizon": 0.0}, "--horizon must be a positive number"),
        ({"max_gap": float("nan")}, "--max-gap must be a positive number"),
        ({"quantity": "velocity"}, "unknown quantity 'velocity'"),
        ({"quantity": "position", "align": "se3"}, "name the runs to fit the alignment on with align_runs"),
        ({"align_runs": ("a",)}, "align_runs is given but align='none'"),
        ({"up": "up"}, "unknown up axis 'up'"),
    ],
)
def test_bad_options_are_refused(kwargs, match):
    with pytest.raises(DataError, match=match):
        IngestOptions(**kwargs)


def test_repeated_run_names_and_unknown_alignment_runs_are_refused(motions):
    truth, est = motions
    t = np.arange(0.0, 4.0, 0.05)
    run = RunData("a", truth.trajectory(t), est.trajectory(t))
    with pytest.raises(DataError, match="run name\\(s\\) a used twice"):
        build_samples([run, run], IngestOptions())
    with pytest.raises(DataError, match="align_runs: no run named b; the runs are a"):
        build_samples([run], IngestOptions(quantity="position", align="sim3", align_runs=("b",)))


def test_from_frame_validates_like_a_file():
    import pandas as pd

    bad = pd.DataFrame({"x_0": [0.1, np.nan], "y_0": [1.0, 2.0], "yhat_0": [1.1, 1.9]})
    with pytest.raises(DataError, match=r"<frame>: row 1 \(0-based\), column 'x_0': non-finite value nan"):
        PerceptionDataset.from_frame(bad)
    with pytest.raises(DataError, match=r"log: no yhat columns"):
        PerceptionDataset.from_frame(bad.drop(columns="yhat_0"), source="log")
    with pytest.raises(DataError, match="the table has no rows"):
        PerceptionDataset.from_frame(bad.iloc[:0])
    named = PerceptionDataset.from_frame(
        pd.DataFrame({"speed": [1.0], "gt": [2.0], "est": [2.5], "run": ["a"]}),
        x_columns=["speed"], y_columns=["gt"], yhat_columns=["est"],
    )  # fmt: skip
    assert named.x_columns == ("speed",) and named.extra["run"].tolist() == ["a"]


@pytest.mark.parametrize("up", list(UP_AXES))
def test_the_tilt_columns_are_the_named_up_axis_in_the_body_frame(motions, up):
    truth, est = motions
    t = np.arange(0.0, 6.0, 0.02)
    df = build_samples([RunData("r", truth.trajectory(t), est.trajectory(t))], IngestOptions(up=up))
    want = est.rotation(S * np.arange(len(df))).inv().apply(UP_AXES[up])
    np.testing.assert_allclose(df[["x_2", "x_3", "x_4"]], want, rtol=0, atol=1e-9)
    names = df.attrs[MANIFEST_KEY]["x_columns"]
    assert names["x_3"] == f"world {'z' if up == '+z' else up} axis in the estimated body frame, y"


def _kitti_drive(folder, pitch: float = 0.0):
    """A car driving straight ahead (+z in KITTI's camera frame: x right, y down, z forward), 20 Hz,
    its camera pitched down by ``pitch`` radians (a rotation about the camera's x axis)."""
    t = np.arange(0.0, 4.0, 0.05)
    c, s_ = np.cos(pitch), np.sin(pitch)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, c, -s_], [0.0, s_, c]])  # body to world, written out
    poses = np.zeros((len(t), 12))
    poses[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]] = rot.reshape(-1)
    poses[:, 11] = 5.0 * t
    np.savetxt(folder / "gt.txt", poses)
    poses[:, 11] *= 1.02  # the estimate: 2 % fast
    np.savetxt(folder / "00.txt", poses)
    np.savetxt(folder / "times.txt", t)
    return {"truth_format": "kitti", "estimate_format": "kitti", "times": folder / "times.txt"}


def test_the_tilt_of_a_pitched_camera_is_the_up_axis_in_its_body_frame(tmp_path):
    from ipcverify.io.ingest import ingest_trajectories

    theta = 0.3
    kw = _kitti_drive(tmp_path, theta)
    df = ingest_trajectories(tmp_path / "gt.txt", [tmp_path / "00.txt"], **kw)
    # R^T (0, -1, 0) for R the rotation about x by theta, by hand: (0, -cos theta, sin theta)
    want = [0.0, -np.cos(theta), np.sin(theta)]
    np.testing.assert_allclose(df[["x_2", "x_3", "x_4"]].to_numpy(), np.tile(want, (len(df), 1)), atol=1e-12)


def test_kitti_estimates_take_the_camera_frames_up_axis_unless_told(tmp_path):
    from ipcverify.io.ingest import ingest_trajectories

    kw = _kitti_drive(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", Hint)  # the KITTI convention is no reason for a hint
        df = ingest_trajectories(tmp_path / "gt.txt", [tmp_path / "00.txt"], **kw)
    np.testing.assert_array_equal(df[["x_2", "x_3", "x_4"]].drop_duplicates().to_numpy(), [[0.0, -1.0, 0.0]])
    assert df.attrs[MANIFEST_KEY]["options"]["up"] == "-y"
    told = ingest_trajectories(
        tmp_path / "gt.txt", [tmp_path / "00.txt"], options=IngestOptions(up="+z"), **kw
    )
    np.testing.assert_array_equal(told[["x_2", "x_3", "x_4"]].drop_duplicates().to_numpy(), [[0.0, 0.0, 1.0]])
    assert told.attrs[MANIFEST_KEY]["options"]["up"] == "+z"


def test_an_estimate_starting_at_the_identity_with_z_taken_as_up_gets_a_hint(tmp_path):
    from ipcverify.io.ingest import ingest_trajectories

    t = np.arange(0.0, 4.0, 0.05)
    rows = np.column_stack([t, t, 0 * t, 0 * t, 0 * t, 0 * t, 0 * t, 1 + 0 * t])  # TUM: identity start
    np.savetxt(tmp_path / "gt.txt", rows)
    np.savetxt(tmp_path / "vo.txt", rows * [1, 1.05, 1, 1, 1, 1, 1, 1])  # 5 % fast along x
    with pytest.warns(Hint, match=r"run vo starts at the identity pose.*pass up"):
        ingest_trajectories(tmp_path / "gt.txt", [tmp_path / "vo.txt"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", Hint)  # told: no hint
        ingest_trajectories(tmp_path / "gt.txt", [tmp_path / "vo.txt"], options=IngestOptions(up="-y"))


def test_an_aligned_estimate_takes_the_truths_up_axis(tmp_path):
    from ipcverify.io.ingest import ingest_trajectories

    t = np.arange(0.0, 4.0, 0.05)
    path = np.column_stack([np.sin(t), 0.5 * t**2, 5.0 * t])  # a curve, so that se3 is determined
    poses = np.zeros((len(t), 12))
    poses[:, [0, 5, 10]] = 1.0
    poses[:, [3, 7, 11]] = path
    np.savetxt(tmp_path / "00.txt", poses)
    np.savetxt(tmp_path / "times.txt", t)
    kw = {"times": tmp_path / "times.txt"}
    tum = np.column_stack([t, path, 0 * t, 0 * t, 0 * t, 1 + 0 * t])
    np.savetxt(tmp_path / "est.txt", tum)
    options = IngestOptions(quantity="position", align="se3", align_runs=("est",))
    df = ingest_trajectories(tmp_path / "00.txt", [tmp_path / "est.txt"], truth_format="kitti",
                             times=kw["times"], options=options)  # fmt: skip
    assert df.attrs[MANIFEST_KEY]["options"]["up"] == "-y"  # the KITTI truth's frame, after alignment
