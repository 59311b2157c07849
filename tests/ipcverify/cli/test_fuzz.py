"""Bad and odd inputs to every command: a user error exits 2 with one ``error:`` line, never a traceback.

The table :data:`CASES` lists each input (files are built once by the ``files`` fixture; ``{name}``
in an argument is replaced by the path of that file) with the exit status it must give and a
fragment its ``error:`` line must contain. The exit-status contract is in docs/cli.md:
0 success, 1 a verdict against the model (CONTRADICTED, ALARM, a forged certificate), 2 a user
error, 3 an internal error.
"""

from __future__ import annotations

import builtins
import json
import shlex
from pathlib import Path

import numpy as np
import pytest
import torch

from ipcverify.calibration import Grouped
from ipcverify.contract._calibrate import calibrate
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.guard import DomainSpec
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

MARKER = "pickle_code_ran.txt"


class _RunsCode:
    """Unpickling this would create MARKER (a stand-in for arbitrary code)."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (builtins.open, (self.path, "w"))


def _csv(path: Path, header: str, rows: list[str]) -> None:
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")


def _with_flights(ds: PerceptionDataset, flights: int) -> PerceptionDataset:
    names = np.array([f"vislam_rp_{i % flights}" for i in range(len(ds))])
    return PerceptionDataset(ds.x, ds.y, ds.yhat, extra={"flight": names})


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("fuzz")
    f: dict[str, Path] = {"dir": d / "a_directory"}
    f["dir"].mkdir()
    train_ds, cal_ds = make_lagged_perception(400, seed=0), make_lagged_perception(1500, seed=1)
    test_ds = make_lagged_perception(300, seed=2)
    for name, ds in (("train", train_ds), ("cal", cal_ds), ("test", test_ds)):
        f[name] = d / f"{name}.csv"
        save_dataset(ds, f[name])
    f["flights"] = d / "flights.csv"
    save_dataset(_with_flights(test_ds, 6), f["flights"])
    f["cal_flights"] = d / "cal_flights.csv"
    save_dataset(_with_flights(cal_ds, 8), f["cal_flights"])
    f["unicode"] = d / "données ü 測試.csv"
    save_dataset(test_ds, f["unicode"])
    f["parquet"] = d / "test.parquet"
    save_dataset(test_ds, f["parquet"])
    mc = ModelConfig.recipe("tight", x_dim=6, y_dim=3, hidden=(8,), members=2)
    model = train(train_ds, mc, TrainConfig.recipe("tight", epochs=2, val_fraction=0.0, patience=None)).model
    f["model"] = d / "model.pt"
    save_model(model, f["model"])
    f["calibrated"] = d / "calibrated.pt"
    save_model(calibrate(model, cal_ds, 0.05, 0.01), f["calibrated"])
    # copies of the training and calibration rows that a whole-file hash took for fresh data
    rng = np.random.default_rng(5)
    reused = {
        "cal_shuffled": cal_ds.subset(rng.permutation(len(cal_ds))),
        "cal_minus_one": cal_ds.subset(np.arange(1, len(cal_ds))),
        "cal_twice": cal_ds.subset(np.r_[np.arange(len(cal_ds)), np.arange(len(cal_ds))]),
        "train_shuffled": train_ds.subset(rng.permutation(len(train_ds))),
        "train_minus_one": train_ds.subset(np.arange(1, len(train_ds))),
        "test_twice": test_ds.subset(np.r_[np.arange(len(test_ds)), np.arange(len(test_ds))]),
    }
    for name, ds in reused.items():
        f[name] = d / f"{name}.csv"
        save_dataset(ds, f[name])
    f["old_calibrated"] = d / "old_calibrated.pt"  # as written before row fingerprints
    old = torch.load(f["calibrated"], weights_only=True)
    del old["row_fingerprints"]
    torch.save(old, f["old_calibrated"])
    f["flight_model"] = d / "flight_model.pt"
    flight_cal = calibrate(
        model,
        _with_flights(cal_ds, 40),
        0.3,
        0.1,
        Grouped(column="flight", seed=1),
        domain=DomainSpec(flag_rate=0.1, seed=1),
    )
    save_model(flight_cal, f["flight_model"])

    header = open(f["test"], encoding="utf-8").readline().strip()
    good = open(f["test"], encoding="utf-8").read().splitlines()[1:]
    ncol = len(header.split(","))
    (d / "empty.csv").write_bytes(b"")
    f["empty"] = d / "empty.csv"
    f["header_only"] = d / "header_only.csv"
    _csv(f["header_only"], header, [])
    f["wrong_columns"] = d / "wrong_columns.csv"
    _csv(f["wrong_columns"], "a,b,c", ["1,2,3", "4,5,6"])
    for name, bad in (("nan", "nan"), ("inf", "inf"), ("text", "abc"), ("blank", "")):
        f[name] = d / f"{name}.csv"
        _csv(f[name], header, [f"{bad}," + good[0].split(",", 1)[1], *good[1:]])
    f["huge"] = d / "huge.csv"
    _csv(f["huge"], header, [",".join(["1e300"] * ncol)] + good[1:])
    f["one_row"] = d / "one_row.csv"
    _csv(f["one_row"], header, good[:1])
    f["identical"] = d / "identical.csv"
    _csv(f["identical"], header, [good[0]] * 2855)
    f["constant"] = d / "constant.csv"
    x0 = header.split(",").index("x_0")
    _csv(
        f["constant"],
        header,
        [",".join("0.5" if i == x0 else v for i, v in enumerate(r.split(","))) for r in good],
    )
    f["dup_columns"] = d / "dup_columns.csv"
    _csv(f["dup_columns"], header + ",x_0", [r + ",9.0" for r in good])
    f["ragged"] = d / "ragged.csv"
    _csv(f["ragged"], header, [good[0] + ",1,2,3", *good[1:]])
    f["wrong_dims"] = d / "wrong_dims.csv"
    save_dataset(
        PerceptionDataset(test_ds.x[:, :5], test_ds.y, test_ds.yhat), f["wrong_dims"]
    )  # 5 state columns for a 6-column model
    f["y2"] = d / "y2.csv"
    save_dataset(PerceptionDataset(test_ds.x, test_ds.y[:, :2], test_ds.yhat[:, :2]), f["y2"])
    f["inputs_only"] = d / "inputs_only.csv"
    _csv(f["inputs_only"], "x_0,x_1,x_2,x_3,x_4,x_5", [",".join(r.split(",")[:6]) for r in good])
    f["txt"] = d / "data.txt"
    f["txt"].write_text("x_0\n1\n", encoding="utf-8")
    f["bad_parquet"] = d / "bad.parquet"
    f["bad_parquet"].write_text("not parquet at all", encoding="utf-8")
    f["bad_npz"] = d / "bad.npz"
    f["bad_npz"].write_bytes(b"PK\x03\x04 truncated zip")
    f["object_npz"] = d / "object.npz"
    np.savez(
        f["object_npz"], x=np.array([{"a": 1}] * 3, dtype=object), y=np.zeros((3, 1)), yhat=np.zeros((3, 1))
    )
    f["binary"] = d / "binary.csv"
    f["binary"].write_bytes(bytes(range(256)) * 8)

    raw = f["model"].read_bytes()
    f["truncated"] = d / "truncated.pt"
    f["truncated"].write_bytes(raw[: len(raw) // 2])
    f["garbage"] = d / "garbage.pt"
    f["garbage"].write_bytes(np.random.default_rng(0).bytes(5000))
    f["empty_model"] = d / "empty_model.pt"
    f["empty_model"].write_bytes(b"")
    f["pickle_code"] = d / "pickle_code.pt"
    torch.save({"format": "ipcverify-model", "payload": _RunsCode(str(d / MARKER))}, f["pickle_code"])
    f["not_a_model"] = d / "not_a_model.pt"
    torch.save({"a": 1}, f["not_a_model"])
    f["future_model"] = d / "future_model.pt"
    payload = torch.load(f["model"], weights_only=True)
    torch.save({**payload, "format_version": 99}, f["future_model"])

    f["unwritable"] = d / "train.csv" / "model.pt"  # the parent is a file
    f["problems"] = d / "problems.json"
    ball = {"type": "ellipsoid", "center": [0.0, 0.0], "shape": [[1.0, 0.0], [0.0, 1.0]]}
    box = {"type": "box", "lower": [-2.0, -2.0], "upper": [2.0, 2.0]}
    f["problems"].write_text(json.dumps([{"inner": ball, "outer": box}]), encoding="utf-8")
    json_files = {
        "bad_json": "{not json",
        "json_scalar": "42",
        "json_schema": json.dumps({"inner": 1, "outer": box}),
        "json_dims": json.dumps({"inner": ball, "outer": {"type": "box", "lower": [0.0], "upper": [1.0]}}),
        "json_nan": json.dumps({"inner": {**ball, "shape": [[float("nan"), 0.0], [0.0, 1.0]]}, "outer": box}),
        "json_singular": json.dumps({"inner": {**ball, "shape": [[1.0, 0.0], [0.0, 0.0]]}, "outer": box}),
        "json_inverted_box": json.dumps({"inner": ball, "outer": {**box, "lower": [3.0, 3.0]}}),
        "json_unknown_type": json.dumps({"inner": ball, "outer": {"type": "sphere"}}),
        "json_empty_list": "[]",
        "json_huge": json.dumps({"inner": {**ball, "shape": [[1e308, 0.0], [0.0, 1e308]]}, "outer": box}),
        "json_deep": "[" * 100_000 + "]" * 100_000,
        "json_deep_object": '{"a": ' * 100_000 + "1" + "}" * 100_000,
        "json_5000_digits": json.dumps({"inner": ball, "outer": box}).replace("-2.0", "-" + "9" * 5000, 1),
        "json_1000_digits": json.dumps({"inner": ball, "outer": box}).replace("-2.0", "-" + "9" * 1000, 1),
    }
    for name, text in json_files.items():
        f[name] = d / f"{name}.json"
        f[name].write_text(text, encoding="utf-8")
    f["latin1"] = d / "latin1.json"
    f["latin1"].write_bytes('{"inner": "é"}'.encode("latin-1"))

    f["own_method"] = d / "own_method.json"
    f["own_method"].write_text(
        json.dumps([{"inner": ball, "outer": box, "method": "socp"}]), encoding="utf-8"
    )
    f["extra_x"] = d / "extra_x.csv"
    _csv(f["extra_x"], header + ",x_6", [r + ",0.5" for r in good])
    f["earlier"] = d / "earlier_outputs"  # what earlier runs of monitor, certify, split and demo left
    f["earlier"].mkdir()
    for name in ("monitor.json", "certificate.json", "report.html", "split.json", "test.csv", "sets.png"):
        (f["earlier"] / name).write_text("an earlier run's output\n", encoding="utf-8")
    f["old_onnx"] = d / "old.onnx"
    f["old_onnx"].write_bytes(b"an earlier export")
    f["notes"] = d / "notes.txt"
    f["notes"].write_text("my notes\n", encoding="utf-8")

    f["complex_npz"] = d / "complex.npz"
    np.savez(f["complex_npz"], x=test_ds.x.astype(complex), y=test_ds.y, yhat=test_ds.yhat)
    f["text_parquet"] = d / "text_numbers.parquet"
    frame = test_ds.to_frame()
    frame.astype({"x_1": str}).to_parquet(f["text_parquet"], index=False)
    f["spaced"] = d / "spaced.csv"
    _csv(f["spaced"], ", ".join(header.split(",")), good)
    f["certify_json"] = d / "certificate.json"  # what `certify` writes, handed to check-certificate
    f["certify_json"].write_text(json.dumps({"format": "ipcverify-certificate", "status": "CERTIFIED"}))
    f["ros1_garbage"] = d / "garbage.bag"
    f["ros1_garbage"].write_bytes(bytes(range(200, 256)) * 50)
    stamps = [0.05 * i for i in range(400)]
    for name, lines in (
        ("tum_ns", [f"{1.4e18 + t * 1e9:.0f} {t} 0 0 0 0 0 1" for t in stamps]),
        ("tum", [f"{t:.2f} {t} 0 0 0 0 0 1" for t in stamps]),
        ("euroc", ["#timestamp,x,y,z,qw,qx,qy,qz"] + [f"{int(t * 1e9)},{t},0,0,1,0,0,0" for t in stamps]),
    ):
        f[name] = d / f"{name}.{'csv' if name == 'euroc' else 'txt'}"
        f[name].write_text("\n".join(lines) + "\n", encoding="utf-8")
    return f


# id | exit status | a fragment of the one error line ("-": none expected; "warning: ..." or "hint: ...":
# no error line, and a warning or hint line with that fragment) | the command line.
# {name} is the path of a file built by the fixture, {tmp} a fresh directory; {cal_ok} stands for
# "--epsilon 0.05 --delta 0.01 --out {tmp}/c.pt" (an option given again later overrides it).
TABLE = """
ingest-topics-not-a-bag       | 2 | not a bag                        | ingest topics {train}
ingest-topics-missing-path    | 2 | does not exist                   | ingest topics {tmp}/missing.bag
ingest-bag-plain-directory    | 2 | without metadata.yaml            | ingest bag {dir} --truth /gt --estimate /est --out {tmp}/o.csv
ingest-traj-empty-truth       | 2 | no poses                         | ingest trajectories --truth {empty} --estimate {train} --format tum --out {tmp}/o.csv
ingest-traj-kitti-no-times    | 2 | KITTI poses carry no stamps      | ingest trajectories --truth {train} --estimate {train} --format kitti --out {tmp}/o.csv
ingest-traj-wrong-format      | 2 | pick the right --format          | ingest trajectories --truth {wrong_columns} --estimate {train} --format euroc --out {tmp}/o.csv
ingest-traj-negative-horizon  | 2 | --horizon must be a positive     | ingest trajectories --truth {train} --estimate {train} --format tum --horizon -1 --out {tmp}/o.csv
unknown-command              | 2 | No such command                  | nope
unknown-option               | 2 | No such option                   | train {train} --out {tmp}/m.pt --bogus
missing-argument             | 2 | Missing argument                 | train
train-missing-file           | 2 | does not exist                   | train {tmp}/missing.csv --out {tmp}/m.pt
train-directory-as-data      | 2 | is a directory                   | train {dir} --out {tmp}/m.pt
train-empty-file             | 2 | the file is empty                | train {empty} --out {tmp}/m.pt
train-header-only            | 2 | header but no samples            | train {header_only} --out {tmp}/m.pt
train-wrong-columns          | 2 | no x columns                     | train {wrong_columns} --out {tmp}/m.pt
train-nan                    | 2 | row 0 (0-based), column 'x_0': n | train {nan} --out {tmp}/m.pt
train-inf                    | 2 | non-finite value inf             | train {inf} --out {tmp}/m.pt
train-text-in-numeric-column | 2 | x_0                              | train {text} --out {tmp}/m.pt
train-blank-cell             | 2 | non-finite value nan             | train {blank} --out {tmp}/m.pt
train-huge-values            | 2 | value 1e+300 is too large        | train {huge} --out {tmp}/m.pt
train-one-row                | 2 | only 1 row; training needs at le | train {one_row} --out {tmp}/m.pt
train-identical-rows         | 2 | 1 distinct row among 2855        | train {identical} --out {tmp}/m.pt
train-constant-column        | 2 | x_0 (every row is 0.5)           | train {constant} --out {tmp}/m.pt
train-duplicate-columns      | 2 | x_0 appears 2 times              | train {dup_columns} --out {tmp}/m.pt
train-ragged-rows            | 2 | cannot read as CSV               | train {ragged} --out {tmp}/m.pt
train-binary-file            | 2 | cannot read as CSV               | train {binary} --out {tmp}/m.pt
train-unknown-suffix         | 2 | unknown data format              | train {txt} --out {tmp}/m.pt
train-corrupt-parquet        | 2 | cannot read as PARQUET           | train {bad_parquet} --out {tmp}/m.pt
train-corrupt-npz            | 2 | cannot read as NPZ               | train {bad_npz} --out {tmp}/m.pt
train-object-npz             | 2 | cannot read as NPZ               | train {object_npz} --out {tmp}/m.pt
train-out-is-directory       | 2 | is a directory                   | train {train} --out {dir}
train-out-parent-is-file     | 2 | exists and is not a directory    | train {train} --out {unwritable}
train-epochs-0               | 2 | epochs must be >= 1              | train {train} --out {tmp}/m.pt --epochs 0
train-hidden-text            | 2 | --hidden                         | train {train} --out {tmp}/m.pt --hidden a,b
train-lr-nan                 | 2 | lr must be > 0                   | train {train} --out {tmp}/m.pt --lr nan
train-lr-text                | 2 | 'fast' is not a valid float      | train {train} --out {tmp}/m.pt --lr fast
train-val-fraction-1         | 2 | --val-fraction must be in [0, 1) | train {train} --out {tmp}/m.pt --val-fraction 1
train-unknown-x-column       | 2 | speed                            | train {train} --out {tmp}/m.pt --x-columns speed
train-unknown-recipe         | 2 | 'best' is not one of             | train {train} --out {tmp}/m.pt --recipe best
evaluate-missing-model       | 2 | does not exist                   | evaluate {tmp}/none.pt {test}
evaluate-truncated-model     | 2 | truncated.pt                     | evaluate {truncated} {test}
evaluate-garbage-model       | 2 | garbage.pt                       | evaluate {garbage} {test}
evaluate-empty-model         | 2 | empty_model.pt                   | evaluate {empty_model} {test}
evaluate-pickle-with-code    | 2 | pickle_code.pt                   | evaluate {pickle_code} {test}
evaluate-not-a-model         | 2 | not_a_model.pt                   | evaluate {not_a_model} {test}
evaluate-future-format       | 2 | format version 99                | evaluate {future_model} {test}
evaluate-csv-as-model        | 2 | test.csv                         | evaluate {test} {test}
evaluate-model-as-data       | 2 | unknown data format              | evaluate {model} {model}
evaluate-wrong-dimensions    | 2 | missing column(s) x_5            | evaluate {model} {wrong_dims}
evaluate-wrong-y-dimension   | 2 | missing column(s) y_2            | evaluate {model} {y2}
evaluate-no-truth            | 2 | missing column(s) y_0, y_1, y_2  | evaluate {model} {inputs_only}
evaluate-unknown-bin-column  | 2 | no column 'nope'                 | evaluate {model} {test} --bin-column nope
evaluate-bins-0              | 2 | bins must be >= 1                | evaluate {model} {test} --bin-column x_0 --bins 0
evaluate-text-bin-column     | 0 | -                                | evaluate {calibrated} {flights} --bin-column flight
evaluate-unicode-path        | 0 | -                                | evaluate {calibrated} {unicode} --json
evaluate-parquet             | 0 | -                                | evaluate {calibrated} {parquet}
evaluate-one-row             | 0 | -                                | evaluate {calibrated} {one_row} --json
evaluate-huge-values         | 2 | is too large                     | evaluate {calibrated} {huge}
predict-out-not-npz          | 2 | must end in .npz; got sets.txt   | predict {model} {test} --out {tmp}/sets.txt
predict-out-is-directory     | 2 | is a directory                   | predict {model} {test} --out {dir}
predict-out-parent-is-file   | 2 | exists and is not a directory    | predict {model} {test} --out {train}/s.npz
predict-no-estimates         | 2 | missing column(s) x_0            | predict {model} {wrong_columns} --out {tmp}/s.npz
predict-inputs-only          | 2 | missing column(s) yhat_0         | predict {calibrated} {inputs_only} --out {tmp}/s.npz
predict-one-row              | 0 | -                                | predict {calibrated} {one_row} --out {tmp}/one.npz
monitor-uncalibrated         | 2 | not calibrated                   | monitor {model} {test} --out {tmp}/mon
plan-no-input                | 2 | either a data file or --runs G   | plan --delta 0.01
plan-both-inputs             | 2 | not both                         | plan {flights} --runs 5 --delta 0.01
plan-no-runs-column          | 2 | name the column of its runs      | plan {test} --delta 0.01
plan-runs-0                  | 2 | positive integer                 | plan --runs 0 --delta 0.01
plan-delta-2                 | 2 | delta must lie strictly          | plan --runs 5 --delta 2
plan-epsilon-0               | 2 | epsilon must lie strictly        | plan --runs 5 --delta 0.1 --epsilon 0
plan-unknown-column          | 2 | no column 'nope'                 | plan {flights} --group-column nope --delta 0.1
plan-flights                 | 0 | -                                | plan {flights} --delta 0.1 --epsilon 0.2
calibrate-unit-row-and-group | 2 | --unit row makes a claim         | calibrate {model} {cal_flights} {cal_ok} --unit row --group-column flight
calibrate-unit-run-no-runs   | 2 | --unit run needs the column      | calibrate {model} {cal} {cal_ok} --unit run
calibrate-gamma-without-runs | 2 | --guarantee and --gamma choose   | calibrate {model} {cal} {cal_ok} --gamma 0.2
calibrate-share-no-gamma     | 2 | needs gamma                      | calibrate {model} {cal_flights} {cal_ok} --group-column flight --guarantee share-of-runs --epsilon 0.9
calibrate-runs-too-few       | 2 | --unit row                       | calibrate {model} {cal_flights} {cal_ok}
monitor-delta-2              | 2 | delta                            | monitor {calibrated} {test} --out {tmp}/mon --delta 2
monitor-unknown-group        | 2 | no column 'nope'                 | monitor {calibrated} {test} --group-column nope
monitor-other-group          | 2 | name the column of the log's runs | monitor {flight_model} {flights} --group-column x_0
monitor-flights-missing      | 2 | no column 'flight'               | monitor {flight_model} {test} --out {tmp}/m2
monitor-out-is-file          | 2 | train.csv                        | monitor {calibrated} {test} --out {train}
demo-n-0                     | 2 | --n                              | demo --n 0 --out {tmp}/demo
demo-n-negative              | 2 | --n                              | demo --n -5 --out {tmp}/demo
demo-out-is-file             | 2 | train.csv                        | demo --out {train}
export-dtype-float16         | 2 | float16                          | export {model} --onnx {tmp}/m.onnx --dtype float16
export-without-no-domain     | 2 | --no-domain                      | export {calibrated} --onnx {tmp}/m.onnx
export-onnx-is-directory     | 2 | is a directory                   | export {model} --onnx {dir}
export-corrupt-model         | 2 | garbage.pt                       | export {garbage} --onnx {tmp}/m.onnx
calibrate-epsilon-0          | 2 | epsilon                          | calibrate {model} {cal} --epsilon 0 --delta 0.01 --out {tmp}/c.pt
calibrate-epsilon-1.5        | 2 | epsilon                          | calibrate {model} {cal} --epsilon 1.5 --delta 0.01 --out {tmp}/c.pt
calibrate-epsilon-nan        | 2 | epsilon                          | calibrate {model} {cal} --epsilon nan --delta 0.01 --out {tmp}/c.pt
calibrate-delta-negative     | 2 | delta                            | calibrate {model} {cal} --epsilon 0.05 --delta -1 --out {tmp}/c.pt
calibrate-bad-mode           | 2 | 'x' is not one of                | calibrate {model} {cal} {cal_ok} --mode x
calibrate-twice              | 2 | --recalibrate                    | calibrate {calibrated} {cal} {cal_ok}
calibrate-on-training-data   | 2 | training data                    | calibrate {model} {train} {cal_ok}
calibrate-one-row            | 2 | distinct row                     | calibrate {model} {one_row} {cal_ok}
calibrate-identical-rows     | 2 | 1 distinct row among 2855        | calibrate {model} {identical} {cal_ok}
calibrate-too-few            | 2 | 2 requirements are not met       | calibrate {model} {test} {cal_ok} --epsilon 0.001 --domain-flag-rate 0.001
calibrate-unknown-group      | 2 | no column 'nope'                 | calibrate {model} {cal} {cal_ok} --group-column nope
calibrate-few-flights        | 2 | groups of column 'flight' are too few | calibrate {model} {cal_flights} {cal_ok} --group-column flight
calibrate-mondrian-on-truth  | 2 | ground truth                     | calibrate {model} {cal} {cal_ok} --mondrian-column y_0
calibrate-bins-alone         | 2 | --mondrian-column                | calibrate {model} {cal} {cal_ok} --bins 3
calibrate-domain-alpha-0     | 2 | --domain-flag-rate               | calibrate {model} {cal} {cal_ok} --domain-flag-rate 0
calibrate-out-unwritable     | 2 | exists and is not a directory    | calibrate {model} {cal} {cal_ok} --out {unwritable}
calibrate-wrong-dimensions   | 2 | missing column(s) x_5            | calibrate {model} {wrong_dims} {cal_ok}
certify-missing-data         | 2 | does not exist                   | certify {calibrated} --data {tmp}/none.csv --out {tmp}/cert
certify-group-without-data   | 2 | --data                           | certify {calibrated} --group-column flight --out {tmp}/cert
certify-unknown-group        | 2 | run                              | certify {calibrated} --data {test} --group-column run
certify-text-bin-column      | 0 | -                                | certify {calibrated} --data {flights} --bin-column flight --out {tmp}/c
certify-delta-0              | 2 | delta                            | certify {calibrated} --data {test} --delta 0 --out {tmp}/cert
certify-radius-negative      | 2 | --lipschitz-radius               | certify {calibrated} --lipschitz-radius -1 --out {tmp}/cert
certify-calibration-as-test  | 2 | calibration data                 | certify {calibrated} --data {cal} --out {tmp}/cert
certify-wrong-dimensions     | 2 | missing column(s) x_5            | certify {calibrated} --data {wrong_dims} --out {tmp}/cert
certify-out-is-file          | 2 | train.csv                        | certify {calibrated} --out {train}
certify-other-train-data     | 2 | not the data the model was train | certify {calibrated} --data {test} --train-data {cal} --out {tmp}/cert
certify-garbage-model        | 2 | garbage.pt                       | certify {garbage} --out {tmp}/cert
certify-calibration-shuffled | 2 | 1,500 of 1,500 test rows are rows of the calibration data | certify {calibrated} --data {cal_shuffled} --out {tmp}/cert
certify-calibration-minus-1  | 2 | 1,499 of 1,499 test rows are rows of the calibration data | certify {calibrated} --data {cal_minus_one} --out {tmp}/cert
certify-calibration-twice    | 2 | 3,000 of 3,000 test rows are rows of the calibration data | certify {calibrated} --data {cal_twice} --out {tmp}/cert
certify-training-shuffled    | 2 | 400 of 400 test rows are rows of the training data | certify {calibrated} --data {train_shuffled} --out {tmp}/cert
certify-training-minus-1     | 2 | 399 of 399 test rows are rows of the training data | certify {calibrated} --data {train_minus_one} --out {tmp}/cert
certify-one-row-repeated     | 2 | only 1 distinct row among 2855 test rows | certify {calibrated} --data {identical} --out {tmp}/cert
certify-every-row-twice      | 0 | warning: 300 of 600 test rows repeat an earlier row | certify {calibrated} --data {test_twice} --out {tmp}/cert
certify-old-model-shuffled   | 0 | hint: only an exact copy of the calibration file | certify {old_calibrated} --data {cal_shuffled} --out {tmp}/cert
calibrate-training-minus-1   | 2 | 399 of 399 calibration rows are rows of the model's training data | calibrate {model} {train_minus_one} {cal_ok}
calibrate-training-shuffled  | 2 | 400 of 400 calibration rows are rows of the model's training data | calibrate {model} {train_shuffled} {cal_ok}
calibrate-every-row-twice    | 0 | warning: breaks that exchangeability | calibrate {model} {cal_twice} {cal_ok}
prove-bad-json               | 2 | not valid JSON                   | prove-containment {bad_json} --out {tmp}/c.json
prove-json-scalar            | 2 | expected one problem             | prove-containment {json_scalar} --out {tmp}/c.json
prove-json-schema            | 2 | problem 0                        | prove-containment {json_schema} --out {tmp}/c.json
prove-dimension-mismatch     | 2 | problem 0                        | prove-containment {json_dims} --out {tmp}/c.json
prove-nan-shape              | 2 | problem 0                        | prove-containment {json_nan} --out {tmp}/c.json
prove-singular-shape         | 2 | problem 0                        | prove-containment {json_singular} --out {tmp}/c.json
prove-inverted-box           | 2 | problem 0                        | prove-containment {json_inverted_box} --out {tmp}/c.json
prove-unknown-set-type       | 2 | problem 0                        | prove-containment {json_unknown_type} --out {tmp}/c.json
prove-huge-entries           | 0 | -                                | prove-containment {json_huge} --out {tmp}/c.json
prove-empty-list             | 2 | an empty list, no problem in it  | prove-containment {json_empty_list} --out {tmp}/c.json
prove-latin1-file            | 2 | not UTF-8                        | prove-containment {latin1} --out {tmp}/c.json
prove-out-is-directory       | 2 | is a directory                   | prove-containment {problems} --out {dir}
check-bad-json               | 2 | not valid JSON                   | check-certificate {bad_json}
check-problems-as-certs      | 2 | certificate 0                    | check-certificate {problems}
check-csv-file               | 2 | not valid JSON                   | check-certificate {test}
split-missing-data           | 2 | does not exist                   | split {tmp}/none.csv --out {tmp}/s
split-fractions-two          | 2 | --fractions must be three        | split {train} --out {tmp}/s --fractions 0.5,0.5
split-fractions-text         | 2 | --fractions must be three        | split {train} --out {tmp}/s --fractions a,b,c
split-fractions-sum          | 2 | summing to 1                     | split {train} --out {tmp}/s --fractions 0.5,0.6,0
split-unknown-group          | 2 | no column 'nope'                 | split {train} --out {tmp}/s --by nope
split-too-few-groups         | 2 | too few for split                | split {flights} --by flight --out {tmp}/s --fractions 0.8,0.1,0.1
split-over-the-input         | 2 | is also the input DATA           | split {train} --out {dir}/..
split-out-is-file            | 2 | train.csv                        | split {test} --out {train}
split-bad-format             | 2 | 'xlsx' is not one of             | split {test} --out {tmp}/s --format xlsx
split-name-groups-alone      | 2 | needs the columns that name a gr | split {flights} --name-groups g --out {tmp}/s
split-npz-by-flight          | 0 | -                                | split {flights} --by flight --format npz --out {tmp}/s
prove-deeply-nested          | 2 | nested too deeply to read        | prove-containment {json_deep} --out {tmp}/c.json
check-deeply-nested          | 2 | nested too deeply to read        | check-certificate {json_deep_object}
prove-5000-digit-integer     | 2 | more digits than can be read     | prove-containment {json_5000_digits} --out {tmp}/c.json
prove-1000-digit-integer     | 2 | (1000 digits) is not exactly a f | prove-containment {json_1000_digits} --out {tmp}/c.json
check-certify-certificate    | 2 | `ipcverify certify` writes       | check-certificate {certify_json}
train-x-column-twice         | 2 | 'x_0' is twice among the x       | train {train} --out {tmp}/m.pt --x-columns x_0,x_0
train-truth-as-state         | 2 | 'y_0' is both an x and a y       | train {train} --out {tmp}/m.pt --x-columns y_0,x_1
train-seed-negative          | 2 | seed must be an integer in [0,   | train {train} --out {tmp}/m.pt --seed -1
train-members-0              | 2 | got 0 -- leave it out for the re | train {train} --out {tmp}/m.pt --members 0
train-hidden-enormous        | 2 | choose narrower layers           | train {train} --out {tmp}/m.pt --hidden 100000000000
train-complex-npz            | 2 | is complex (dtype complex128)    | train {complex_npz} --out {tmp}/m.pt
train-numbers-as-text        | 2 | 'x_1' holds numbers stored as te | train {text_parquet} --out {tmp}/m.pt
train-spaces-in-header       | 2 | have spaces around them          | train {spaced} --out {tmp}/m.pt
calibrate-epsilon-1e-300     | 2 | at least 4.6e+300 are needed     | calibrate {model} {cal} {cal_ok} --epsilon 1e-300
calibrate-epsilon-1e-15      | 2 | at least 4.6e+15 are needed      | calibrate {model} {cal} {cal_ok} --epsilon 1e-15
calibrate-seed-negative      | 2 | seed must be a non-negative      | calibrate {model} {cal} {cal_ok} --seed -1 --mondrian-column x_0 --bins 2
demo-n-too-small             | 2 | between 100 and 10,000,000       | demo --n 3 --out {tmp}/demo
demo-n-enormous              | 2 | between 100 and 10,000,000       | demo --n 100000000000000 --out {tmp}/demo
demo-seed-negative           | 2 | --seed must be a non-negative    | demo --seed -1 --out {tmp}/demo
ingest-topics-corrupt-ros1   | 2 | its content is not a ROS bag's   | ingest topics {ros1_garbage}
ingest-bag-corrupt-ros1      | 2 | its content is not a ROS bag's   | ingest bag {ros1_garbage} --truth /gt --estimate /est --out {tmp}/o.csv
ingest-traj-nanoseconds      | 2 | look like nanoseconds            | ingest trajectories --truth {tum_ns} --estimate {tum_ns} --format tum --out {tmp}/o.csv
ingest-traj-euroc-as-tum     | 2 | a EuRoC file is --format euroc   | ingest trajectories --truth {euroc} --estimate {euroc} --format tum --out {tmp}/o.csv
ingest-traj-stride-tiny      | 2 | use a larger --stride            | ingest trajectories --truth {tum} --estimate {tum} --stride 1e-9 --out {tmp}/o.csv
empty-split-one-row          | 2 | calibration and test parts would | split {one_row} --out {tmp}/s
empty-split-no-train-row     | 2 | the train part would get no row  | split {one_row} --out {tmp}/s --fractions 0.5,0,0.5
empty-check-no-certificates  | 2 | an empty list, no certificate in | check-certificate {json_empty_list}
ignored-evaluate-bins-alone  | 2 | --bins sets the number of bins o | evaluate {model} {test} --bins -2
ignored-evaluate-bins-text   | 2 | not apply to the text column 'fl | evaluate {calibrated} {flights} --bin-column flight --bins 3
ignored-certify-bins-no-data | 2 | --bins is for binning the test d | certify {calibrated} --bins 5 --out {tmp}/c
ignored-certify-column-no-da | 2 | without --data TEST there is no  | certify {calibrated} --bin-column x_1 --out {tmp}/c
ignored-train-alpha-likeliho | 2 | --alpha belongs to the hinge los | train {train} --out {tmp}/m.pt --alpha 0.5
ignored-train-lam-and-alpha  | 2 | --alpha and --lam belong to the  | train {train} --out {tmp}/m.pt --loss likelihood --recipe v1 --alpha 0.5 --lam 1
ignored-prove-method-unused  | 2 | --method sdp applies to no probl | prove-containment {own_method} --method sdp --out {tmp}/c.json
ignored-export-no-domain     | 2 | has no domain-of-validity test t | export {model} --onnx {tmp}/m.onnx --no-domain
ignored-ingest-format        | 2 | --format is overridden by both - | ingest trajectories --truth {tum} --estimate {tum} --format tum --truth-format tum --estimate-format tum --out {tmp}/o.csv
ignored-ingest-state-fields  | 2 | --state-fields names fields of t | ingest bag {ros1_garbage} --truth /gt --estimate /est --state-fields a.b --out {tmp}/o.csv
ignored-ingest-child-frame   | 2 | --child-frame is overridden by b | ingest bag {ros1_garbage} --truth /gt --estimate /est --child-frame a --truth-child-frame b --estimate-child-frame c --out {tmp}/o.csv
suffix-export-onnx-txt       | 2 | --onnx must end in .onnx (an ONN | export {model} --onnx {notes}
suffix-train-out-csv         | 2 | --out must end in .pt (a model f | train {train} --out {tmp}/m.csv
suffix-calibrate-out-onnx    | 2 | --out must end in .pt (a model f | calibrate {model} {cal} --epsilon 0.05 --delta 0.01 --out {tmp}/c.onnx
suffix-prove-out-txt         | 2 | --out must end in .json (a JSON  | prove-containment {problems} --out {tmp}/c.txt
suffix-ingest-out-txt        | 2 | must end in .csv, .parquet or .p | ingest trajectories --truth {tum} --estimate {tum} --out {tmp}/o.txt
exists-train                 | 2 | model.pt exists; pass --force to | train {train} --out {model}
exists-calibrate             | 2 | calibrated.pt exists; pass --for | calibrate {model} {cal} --epsilon 0.05 --delta 0.01 --out {calibrated}
exists-predict               | 2 | bad.npz exists; pass --force to  | predict {calibrated} {test} --out {bad_npz}
exists-monitor               | 2 | already holds monitor.json; pass | monitor {calibrated} {test} --out {earlier}
exists-certify               | 2 | holds certificate.json and repor | certify {calibrated} --data {test} --out {earlier}
exists-split                 | 2 | already holds test.csv and split | split {test} --out {earlier}
exists-demo                  | 2 | already holds test.csv and sets. | demo --n 100 --out {earlier}
exists-export                | 2 | old.onnx exists; pass --force to | export {model} --onnx {old_onnx}
exists-prove                 | 2 | bad_json.json exists; pass --for | prove-containment {problems} --out {bad_json}
exists-ingest                | 2 | test.csv exists; pass --force to | ingest trajectories --truth {tum} --estimate {tum} --out {test}
message-an-x-column          | 2 | column x_6 looks like an x colum | evaluate {model} {extra_x}
message-row-0-based          | 2 | row 0 (0-based), column 'x_0': n | evaluate {calibrated} {blank}
"""  # noqa: E501 (one case per line)


def _cases() -> list[tuple[str, int, str | None, str]]:
    rows = []
    for line in TABLE.strip().splitlines():
        case, code, fragment, command = (cell.strip() for cell in line.split("|"))
        rows.append((case, int(code), None if fragment == "-" else fragment, command))
    return rows


CASES = _cases()


def _argv(command: str, files: dict[str, Path], tmp: Path) -> list[str]:
    paths = {k: shlex.quote(str(v)) for k, v in files.items()}
    cal_ok = f"--epsilon 0.05 --delta 0.01 --out {shlex.quote(str(tmp / 'c.pt'))}"
    return shlex.split(command.format(tmp=shlex.quote(str(tmp)), cal_ok=cal_ok, **paths))


@pytest.mark.parametrize(("code", "fragment", "command"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_and_odd_inputs_exit_with_one_error_line_and_no_traceback(
    files, tmp_path, run_cli, code, fragment, command
):
    res = run_cli(*_argv(command, files, tmp_path))
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert "Traceback" not in res.stderr + res.stdout
    assert res.code == code, res.stderr
    if fragment is None:
        assert errors == [], res.stderr
        assert res.stdout.strip(), "a success says what it did"
    elif fragment.startswith(("warning: ", "hint: ")):  # accepted, and said so
        kind, text = fragment.split(": ", 1)
        said = [line for line in res.stderr.splitlines() if line.startswith(kind + ":") and text in line]
        assert errors == [] and said, res.stderr
        assert res.stdout.strip(), "a success says what it did"
    else:
        assert len(errors) == 1 and fragment in errors[0], res.stderr
        lines = res.stderr.splitlines()
        assert not [line for line in lines if not line.startswith(("error:", "warning:", "hint:"))]
        assert not [line for line in lines[: lines.index(errors[0])] if line.startswith("hint:")], res.stderr
    assert not (files["dir"].parent / MARKER).exists()  # the pickle's code never ran


def test_the_table_covers_every_command_and_at_least_60_inputs():
    from ipcverify.cli import app

    covered = {shlex.split(c[3])[0] for c in CASES}
    assert set(app.commands) <= covered, set(app.commands) - covered
    assert len(CASES) >= 60


def test_the_cases_have_unique_ids():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


def test_an_unwritable_output_directory_is_a_user_error(files, tmp_path, run_cli):
    """A read-only directory (as a user without root rights meets it): exit 2 naming the path."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        probe = locked / "probe"
        try:  # root ignores permissions: then a path below a file is the unwritable output
            probe.write_text("x")
            probe.unlink()
            target = files["unwritable"]
        except PermissionError:
            target = locked / "m.pt"
        res = run_cli("predict", files["model"], files["test"], "--out", target.with_suffix(".npz"))
        assert res.code == 2 and res.stderr.startswith("error: ") and "Traceback" not in res.stderr
    finally:
        locked.chmod(0o700)
