"""One source of defaults: the dataclasses of the settings files carry no values of their own."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from case_studies.quad_landing.cli import main
from case_studies.quad_landing.reproduction.config import REPRODUCE_SECTIONS, IpcParams, load_reproduce_config
from case_studies.quad_landing.settings import (
    DEFAULTS_PATH,
    REPRODUCE_PATH,
    ConfigError,
    TomlSection,
    check_positive,
    read_toml,
    sections_by_name,
)
from case_studies.quad_landing.sim.camera.pinhole import CameraParams
from case_studies.quad_landing.sim.config import SIM_SECTIONS, load_config
from case_studies.quad_landing.sim.dynamics import QuadParams
from case_studies.quad_landing.sim.lqr import LqrParams, SettleParams
from ipcverify.training._train import TrainConfig

SECTIONS = [(DEFAULTS_PATH, name, cls) for name, cls in SIM_SECTIONS.items()] + [
    (REPRODUCE_PATH, name, cls) for name, cls in REPRODUCE_SECTIONS.items()
]
IDS = [f"{path.name}:{name}" for path, name, _ in SECTIONS]
CHANGED_SIM = {
    "quad": {"mass": 1.6},
    "sim": {"ground_z": 0.1},
    "lqr": {"r_thrust": 2.0},
    "settle": {"hold_time": 0.5},
    "camera": {"fx": 250.0},
    "marker": {"marker_id": 3},
    "pad": {"yaw": 0.5},
    "render": {"noise_std": 1.0},
    "detector": {"min_marker_perimeter_rate": 0.05},
    "paths": {"duration": 12.0},
    "collect": {"warmup_time": 0.5},
}
CHANGED_REPRODUCE = {
    "scenario": {"prior_radius": 0.2},
    "approach": {"hover_points": 3},
    "landing": {"climb": 0.4},
    "ipc": {"epochs": 7, "coverage_quantile": 0.99},
    "sizes": {"paper_runs": 12},
}


def _toml(tree: dict) -> str:
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    return "".join(f"[{s}]\n" + "".join(f"{k} = {value(v)}\n" for k, v in t.items()) for s, t in tree.items())


@pytest.mark.parametrize(("path", "name", "cls"), SECTIONS, ids=IDS)
def test_section_dataclasses_have_no_default_values(path, name, cls):
    assert issubclass(cls, TomlSection) and cls.toml_file == path and cls.toml_section == name
    with_default = [
        f.name
        for f in dataclasses.fields(cls)
        if f.init and (f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING)
    ]
    assert with_default == [], f"{cls.__name__} duplicates the values of [{name}] in {path.name}"


def test_a_section_names_its_file_and_table_in_its_class_statement():
    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Box(TomlSection, file=REPRODUCE_PATH, section="box"):
        side: float

    assert (Box.toml_file, Box.toml_section) == (REPRODUCE_PATH, "box")
    assert "toml_section" not in vars(TomlSection)  # the base names no table
    with pytest.raises(TypeError, match="both its file and its section"):
        type("Half", (TomlSection,), {}, file=DEFAULTS_PATH)
    with pytest.raises(ValueError, match="names no section"):
        sections_by_name(Box, type("Bare", (TomlSection,), {}))
    with pytest.raises(ValueError, match=r"QuadParams and Twin both read \[quad\]"):
        sections_by_name(QuadParams, type("Twin", (TomlSection,), {}, file=DEFAULTS_PATH, section="quad"))
    assert list(SIM_SECTIONS) == list(read_toml(DEFAULTS_PATH))  # one class a table, in the file's order


@pytest.mark.parametrize(("path", "name", "cls"), SECTIONS, ids=IDS)
def test_every_shipped_key_is_read_and_every_field_is_shipped(path, name, cls):
    shipped = set(read_toml(path)[name])
    assert shipped <= cls.toml_keys()
    own = {f.name for f in dataclasses.fields(cls) if f.init} - {"train"}
    assert own <= shipped  # no field waits for a value the file does not give


def test_loaded_values_are_the_shipped_values():
    for path, loaded in (
        (DEFAULTS_PATH, load_config().as_dict()),
        (REPRODUCE_PATH, load_reproduce_config().as_dict()),
    ):
        for name, table in read_toml(path).items():
            if name == "quick":
                continue
            for key, value in table.items():
                assert loaded[name][key] == value, f"{path.name} [{name}] {key}"


def test_a_changed_toml_file_changes_the_loaded_objects(tmp_path):
    sim_file, rep_file = tmp_path / "sim.toml", tmp_path / "reproduce.toml"
    sim_file.write_text(_toml(CHANGED_SIM))
    rep_file.write_text(_toml(CHANGED_REPRODUCE) + "[quick.sizes]\nmc_runs = 4\n")
    sim, rep = load_config(sim_file).as_dict(), load_reproduce_config(rep_file).as_dict()
    for loaded, changed, path in (
        (sim, CHANGED_SIM, DEFAULTS_PATH),
        (rep, CHANGED_REPRODUCE, REPRODUCE_PATH),
    ):
        for name, table in read_toml(path).items():
            for key, value in table.items() if name != "quick" else ():
                assert loaded[name][key] == changed.get(name, {}).get(key, value)
    assert load_reproduce_config(rep_file).ipc.train.epochs == 7
    quick = load_reproduce_config(rep_file, quick=True)  # the shipped [quick] overlay, then the file's
    assert quick.sizes.mc_runs == 4 and quick.sizes.paper_runs == 12


def test_defaults_reads_the_shipped_file(tmp_path, monkeypatch):
    table = read_toml(DEFAULTS_PATH)["quad"]
    other = tmp_path / "defaults.toml"
    other.write_text(_toml({"quad": {**table, "mass": 2.0}}))
    assert QuadParams.defaults().mass == table["mass"]
    monkeypatch.setattr(QuadParams, "toml_file", other)
    assert QuadParams.defaults().mass == 2.0 and QuadParams.defaults(mass=1.7).mass == 1.7
    with pytest.raises(ConfigError, match="unknown key quad.weight"):
        QuadParams.defaults(weight=1.0)


def test_ipc_section_builds_a_train_config_and_the_rest():
    shipped = read_toml(REPRODUCE_PATH)["ipc"]
    train_keys = {f.name for f in dataclasses.fields(TrainConfig)}
    ipc = IpcParams.defaults()
    # the training keys of [ipc] are the TrainConfig, nothing else mirrors it
    # (the fields [ipc] leaves out are those of its recipe, ipcverify's default "tight")
    assert ipc.recipe == shipped["recipe"] == "tight"
    assert ipc.train == TrainConfig.recipe("tight", **{k: v for k, v in shipped.items() if k in train_keys})
    assert not {f.name for f in dataclasses.fields(IpcParams)} & train_keys
    assert {k for k in shipped if k not in train_keys} == {
        "recipe",
        "hidden",
        "epsilon",
        "delta",
        "coverage_quantile",
    }
    # any TrainConfig field may be set from [ipc]; the table round-trips
    tuned = IpcParams.defaults(val_fraction=0.2)
    assert tuned.train.val_fraction == 0.2 and IpcParams.from_table(tuned.to_table()) == tuned
    with pytest.raises(ConfigError, match=r"\[ipc\]: lr must be > 0"):
        IpcParams.defaults(lr=0.0)
    with pytest.raises(ConfigError, match="ipc.epochs must be an integer"):
        IpcParams.defaults(epochs=2.5)
    with pytest.raises(ConfigError, match="unknown key ipc.optimizer"):
        IpcParams.defaults(optimizer="sgd")


def test_cli_help_shows_the_defaults_of_the_toml_files(capsys):
    sim, rep = read_toml(DEFAULTS_PATH), read_toml(REPRODUCE_PATH)
    for args, expected in (
        (
            ["collect", "--help"],
            [f"defaults.toml: {sim['collect']['buffer_size']}]", f"defaults.toml: {sim['collect']['n']}]"],
        ),
        (
            ["reproduce", "--help"],
            [f"reproduce.toml: {rep['sizes']['mc_runs']}, with --quick {rep['quick']['sizes']['mc_runs']}]"],
        ),
    ):
        with pytest.raises(SystemExit) as exit_:
            main(args)
        assert exit_.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        for piece in expected:
            assert piece in text


@pytest.mark.parametrize(
    ("cls", "field", "value"),
    [
        (QuadParams, "mass", 0.0),
        (QuadParams, "gravity", float("nan")),
        (CameraParams, "fx", -1.0),
        (LqrParams, "r_thrust", float("inf")),
        (SettleParams, "hold_time", 0),
    ],
)
def test_a_section_field_that_must_be_positive_is_checked_by_the_one_rule(cls, field, value):
    with pytest.raises(ConfigError, match=rf"^{cls.toml_section}\.{field} must be a number > 0, got "):
        dataclasses.replace(cls.defaults(), **{field: value})


def test_the_positive_rule_accepts_numpy_scalars_and_rejects_text():
    check_positive("quad.mass", np.float32(0.5))
    check_positive("sizes.mc_runs", np.int64(3), integer=True)
    with pytest.raises(ConfigError, match="quad.mass must be a number > 0, got '1'"):
        check_positive("quad.mass", "1")
