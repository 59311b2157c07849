"""Data collection, dataset files, exploration paths, configuration and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing import Flight, load_config
from case_studies.quad_landing.cli import main
from case_studies.quad_landing.data.collect import collect, pad_outline_world, write_dataset
from case_studies.quad_landing.data.columns import DATASET_COLUMNS, X_COLUMNS
from case_studies.quad_landing.data.paths import (
    TEMPLATES,
    ExplorationPath,
    PathParams,
    fit_to_view,
    make_path,
    pad_in_view_along,
)
from case_studies.quad_landing.settings import ConfigError
from case_studies.quad_landing.sim.camera import Camera
from case_studies.quad_landing.sim.features import camera_frame_state
from ipcverify.errors import InvalidInputError

CFG = load_config()
SHORT = CFG.replace(paths={"duration": 2.0}, collect={"warmup_time": 0.5})


@pytest.fixture(scope="module")
def small() -> tuple[pd.DataFrame, object]:
    return collect(150, buffer_size=2, seed=4, config=SHORT)


def test_collect_returns_n_rows_with_the_documented_columns(small):
    data, stats = small
    assert list(data.columns) == list(DATASET_COLUMNS)
    assert len(data) == 150 == stats.samples
    assert np.all(np.isfinite(data.drop(columns=["path"]).to_numpy()))
    assert stats.samples + stats.missed == stats.measurements
    assert stats.paths == data["path"].nunique() and stats.buffer_size == 2
    assert set(data["path"]) == set(range(stats.paths))


def test_dataset_columns_mean_what_the_docs_say(small):
    data, _ = small
    cam = Camera(SHORT.camera)
    for _, row in data.sample(20, random_state=0).iterrows():
        xw = row[[f"xw_{i}" for i in range(12)]].to_numpy(float)
        x_c, T_WC = camera_frame_state(xw, cam, SHORT.sim.ground_z)
        np.testing.assert_allclose(row[list(X_COLUMNS)].to_numpy(float), x_c, atol=1e-9)
        y_c = row[["y_0", "y_1", "y_2"]].to_numpy(float)
        yhat_c = row[["yhat_0", "yhat_1", "yhat_2"]].to_numpy(float)
        np.testing.assert_allclose(T_WC.apply(y_c), SHORT.pad.position, atol=1e-9)
        np.testing.assert_allclose(row[["yw_0", "yw_1", "yw_2"]].to_numpy(float),
                                   SHORT.pad.position, atol=1e-9)  # fmt: skip
        np.testing.assert_allclose(row[["yhatw_0", "yhatw_1", "yhatw_2"]].to_numpy(float),
                                   T_WC.apply(yhat_c), atol=1e-9)  # fmt: skip


def test_same_seed_same_data_and_paths_do_not_depend_on_n(small):
    data, _ = small
    again, _ = collect(60, buffer_size=2, seed=4, config=SHORT)
    pd.testing.assert_frame_equal(again, data.iloc[:60])


def test_paths_are_shared_across_buffer_sizes(small):
    data, _ = small
    other, _ = collect(40, buffer_size=0, seed=4, config=SHORT)
    # same path 0, same sampling instants, same states; only yhat differs
    cols = [c for c in DATASET_COLUMNS if not c.startswith("yhat")]
    pd.testing.assert_frame_equal(other[cols], data.iloc[:40][cols])


def test_the_buffer_size_reaches_the_simulator_from_one_place(small):
    # the argument and the config's [collect] default are two ways to give the same one value
    data, stats = small
    via_config, cstats = collect(60, seed=4, config=SHORT.replace(collect={"buffer_size": 2}))
    pd.testing.assert_frame_equal(via_config, data.iloc[:60])
    assert stats.buffer_size == cstats.buffer_size == 2
    # the argument wins over the config, and the config is not what the flight reads
    other, ostats = collect(60, buffer_size=0, seed=4, config=SHORT.replace(collect={"buffer_size": 2}))
    assert ostats.buffer_size == 0 and not np.allclose(other["yhat_0"], data["yhat_0"].iloc[:60])
    with pytest.raises(InvalidInputError, match="buffer size must be an integer in"):
        collect(5, buffer_size=99, seed=4, config=SHORT, jobs=2)


def test_worker_processes_do_not_change_the_data():
    a, sa = collect(30, buffer_size=1, seed=2, config=SHORT)
    b, sb = collect(30, buffer_size=1, seed=2, config=SHORT, jobs=2)
    pd.testing.assert_frame_equal(a, b)
    assert sa.measurements == sb.measurements


def test_missed_detections_are_counted_not_dropped_silently():
    # heavy blur and noise make the detector miss frames with the marker in view
    cfg = SHORT.replace(render={"blur_sigma": 2.2, "noise_std": 12.0})
    data, stats = collect(40, buffer_size=1, seed=0, config=cfg)
    assert len(data) == 40
    assert stats.missed_in_view > 0
    assert stats.measurements == 40 + stats.missed
    assert 0 < stats.detection_rate < 1
    assert "missed" in stats.summary()


def test_exploration_reaches_speed_rotation_and_heights():
    data, stats = collect(900, buffer_size=1, seed=0, config=CFG.replace(paths={"duration": 6.0}))
    speed = np.linalg.norm(data[["x_3", "x_4", "x_5"]].to_numpy(), axis=1)
    rate = np.linalg.norm(data[["x_9", "x_10", "x_11"]].to_numpy(), axis=1)
    height = np.linalg.norm(data[["x_0", "x_1", "x_2"]].to_numpy(), axis=1)
    # "order 0.5-2 m/s, with some rotation" (one seeded run of 5 short paths)
    assert np.median(speed) > 0.4 and np.percentile(speed, 90) > 0.8 and speed.max() > 1.2
    assert np.percentile(rate, 75) > 0.3
    assert height.min() > 0.6 and height.max() > 2.0
    assert stats.detection_rate > 0.97


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), which=st.integers(0, 4))
def test_fitted_paths_keep_the_pad_in_view(seed, which):
    cam = Camera(CFG.camera)
    outline = pad_outline_world(CFG)
    raw = make_path(TEMPLATES[which], np.random.default_rng(seed), CFG.pad.position, CFG.paths)
    fitted = fit_to_view(raw, cam, outline, CFG.paths.view_margin_px)
    assert pad_in_view_along(fitted, cam, outline, CFG.paths.view_margin_px)
    assert np.all(fitted.amplitude[:2] <= raw.amplitude[:2] + 1e-12)
    r = fitted.sample(np.linspace(0, fitted.duration, 200))
    heights = r.position[:, 2] - CFG.pad.position[2]
    assert heights.min() >= CFG.paths.min_height - 1e-9
    assert heights.max() <= CFG.paths.max_height + 1e-9
    assert np.all(np.abs(r.position[:, :2]) < 3.0)  # inside the workspace


def test_path_derivatives_are_consistent():
    path = make_path("lissajous", np.random.default_rng(1), (0, 0, 0), PathParams.defaults())
    t = np.linspace(0.5, 5.0, 50)
    h = 1e-5
    a, b, m = path.sample(t + h), path.sample(t - h), path.sample(t)
    np.testing.assert_allclose((a.position - b.position) / (2 * h), m.velocity, atol=1e-6)
    np.testing.assert_allclose((a.velocity - b.velocity) / (2 * h), m.acceleration, atol=1e-6)
    np.testing.assert_allclose((a.acceleration - b.acceleration) / (2 * h), m.jerk, atol=1e-5)
    np.testing.assert_allclose((a.yaw - b.yaw) / (2 * h), m.yaw_rate, atol=1e-6)


def test_fit_to_view_refuses_a_path_that_cannot_see_the_pad():
    cam = Camera(CFG.camera)
    low = ExplorationPath(name="low", center=(0, 0, 0.15), amplitude=(0, 0, 0), omega=(1, 1, 1),
                          phase=(0, 0, 0), duration=1.0)  # fmt: skip
    with pytest.raises(InvalidInputError, match="leaves the image even without"):
        fit_to_view(low, cam, pad_outline_world(CFG), 3.0)


# ----------------------------------------------------------------------------- files


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_write_dataset_round_trips_and_leaves_no_temp_files(tmp_path, small, suffix):
    data, stats = small
    out = write_dataset(data, tmp_path / f"d{suffix}", stats)
    back = pd.read_parquet(out) if suffix == ".parquet" else pd.read_csv(out)
    pd.testing.assert_frame_equal(back, data, check_exact=False, rtol=1e-8)
    assert json.loads((tmp_path / "d.stats.json").read_text())["samples"] == 150
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["d.stats.json", f"d{suffix}"])


def test_a_failed_write_leaves_the_old_file_untouched(tmp_path, small, monkeypatch):
    data, _ = small
    target = tmp_path / "d.parquet"
    target.write_bytes(b"old")

    def boom(self, fh, **kwargs):
        fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_parquet", boom)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(data, target)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["d.parquet"]


def test_write_dataset_refuses_unknown_extensions(tmp_path, small):
    with pytest.raises(InvalidInputError, match=r"\.parquet or \.csv"):
        write_dataset(small[0], tmp_path / "d.xlsx")


# ----------------------------------------------------------------------------- config


def test_config_overrides_and_unknown_keys(tmp_path):
    assert load_config().camera.width == 320
    f = tmp_path / "c.toml"
    f.write_text("[camera]\nfx = 250.0\n[collect]\nbuffer_size = 4\n")
    cfg = load_config(f)
    assert cfg.camera.fx == 250.0 and cfg.collect.buffer_size == 4 and cfg.camera.fy == 220.0
    with pytest.raises(ConfigError, match="unknown key camera.focal; valid keys: .*fx"):
        load_config(overrides={"camera": {"focal": 1}})
    with pytest.raises(ConfigError, match=r"unknown section \[cam\]"):
        load_config(overrides={"cam": {}})
    with pytest.raises(ConfigError, match="integer multiple of camera.fps"):
        load_config(overrides={"sim": {"physics_rate": 250.0}})
    f.write_text("[camera\nfx = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(f)


def test_flight_validates_its_inputs():
    f = Flight(CFG, buffer_size=1)
    with pytest.raises(InvalidInputError, match="call Flight.reset"):
        f.measure()
    with pytest.raises(InvalidInputError, match="12 finite numbers"):
        f.reset(np.zeros(11))
    with pytest.raises(InvalidInputError, match="buffer size must be"):
        Flight(CFG, buffer_size=99)


# ----------------------------------------------------------------------------- CLI


def _run(capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_collect_writes_the_dataset(tmp_path, capsys):
    out = tmp_path / "data.parquet"
    code, stdout, _ = _run(capsys, "collect", "--buffer-size", "1", "--n", "25", "--seed", "3",
                           "--out", out, "--quiet")  # fmt: skip
    assert code == 0 and out.exists() and (tmp_path / "data.stats.json").exists()
    assert len(pd.read_parquet(out)) == 25
    assert "25 samples" in stdout and "detection rate" in stdout


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["collect", "--n", "0", "--out", "{d}/x.parquet"], "--n"),
        (["collect", "--n", "5", "-k", "-1", "--out", "{d}/x.parquet"], "--buffer-size"),
        (["collect", "--n", "5", "--out", "{d}/x.txt"], ".parquet or .csv"),
        (["collect", "--n", "5", "--out", "{d}/missing/x.csv"], "does not exist"),
        (["collect", "--n", "5", "--out", "{d}/x.csv", "--config", "{d}/nope.toml"],
         "does not exist"),
        (["collect", "--n", "5", "--out", "{d}/x.csv", "--config", "{d}/bad.toml"],
         "unknown key"),
        (["collect", "--n", "5"], "--out"),
        (["fly"], "No such command"),
    ],
)  # fmt: skip
def test_cli_bad_input_is_one_line_and_status_2(tmp_path, capsys, args, match):
    (tmp_path / "bad.toml").write_text("[camera]\nfocal = 3\n")
    code, _, stderr = _run(capsys, *[a.format(d=tmp_path) for a in args])
    assert code == 2
    assert stderr.startswith("error: ") and len(stderr.strip().splitlines()) == 1
    assert match in stderr
    assert not list(tmp_path.glob("x.*"))
