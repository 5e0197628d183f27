"""Robot model files (suds-robot/1): what loads, what is refused and why, and the round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.robot_model import dump_model, load_model, model_from_dict
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import builtin_model, is_model_file, load_system, make_system

SNAKE5 = Path(__file__).resolve().parents[3].parent / "shared" / "robots" / "snake5.yaml"
EEL4 = Path(__file__).resolve().parents[2] / "data" / "robots" / "eel4.yaml"  # the tests' own robot

SPEC_EXAMPLE = """
format: suds-robot/1
name: lamprey7                   # system id written into recordings (metadata `system`)
gait_hz: 1.5
drag: {c_par: 0.8, c_perp: 1.9}
links:
  - {length: 0.15}
  - {length: 0.12}
  - {length: 0.12}
  - {length: 0.12, c_par: 1.1}
  - {length: 0.12}
  - {length: 0.10}
  - {length: 0.09}
body: {link: 1, offset: [0.03, 0.0, 0.1]}
joints:
  - {name: neck, actuated: true, gait: {amplitude: 0.6, phase: 0.0}}
  - {name: j2, actuated: true, gait: {amplitude: 0.6, phase: 0.9}}
  - {name: j3, actuated: true, gait: {amplitude: 0.6, phase: 1.8, offset: 0.05}}
  - {name: j4, stiffness: 0.04, damping: 0.002}
  - {name: j5, stiffness: 0.03, rest: 0.02}
  - {name: tail, stiffness: 0.02, k3: 0.01, coulomb: 0.001}
environment: {flow: [0.0, 0.0]}
"""


def _doc() -> dict:  # type: ignore[type-arg]
    return yaml.safe_load(SPEC_EXAMPLE)


def test_spec_example_loads_with_every_value(tmp_path: Path) -> None:
    path = tmp_path / "lamprey7.yaml"
    path.write_text(SPEC_EXAMPLE)
    m = load_model(path)
    assert m.name == "lamprey7" and m.n_links == 7 and m.gait_hz == 1.5
    assert m.joint_names == ("neck", "j2", "j3", "j4", "j5", "tail")
    assert m.actuated == (0, 1, 2) and m.passive == (3, 4, 5)
    assert m.link_length == (0.15, 0.12, 0.12, 0.12, 0.12, 0.10, 0.09)
    assert m.c_par == (0.8, 0.8, 0.8, 1.1, 0.8, 0.8, 0.8) and m.c_perp == (1.9,) * 7
    assert m.body_link == 0 and m.pose_offset == (0.03, 0.0, 0.1)
    assert m.stiffness[3:] == (0.04, 0.03, 0.02) and m.damping[3] == 0.002  # type: ignore[index]
    assert m.rest[4] == 0.02 and m.k3[5] == 0.01 and m.coulomb[5] == 0.001  # type: ignore[index]
    assert m.gait == ((0.6, 1.0, 0.0, 0.0), (0.6, 1.0, 0.9, 0.0), (0.6, 1.0, 1.8, 0.05))


def test_snake5_file_loads() -> None:
    if not SNAKE5.exists():
        pytest.skip(f"{SNAKE5} not available")
    system = load_system(str(SNAKE5))
    assert isinstance(system, RFTChain) and system.name == "snake5"
    m = system.model
    assert m.link_length == (1.3, 1.0, 1.0, 1.0, 0.8) and m.c_perp == (2.0, 2.0, 2.0, 2.0, 2.6)
    assert m.body_link == 1 and m.pose_offset == (0.1, 0.05, 0.0)
    assert system.joint_names == ("joint_1", "joint_2", "joint_3", "joint_4")
    assert m.actuated == (0, 1) and m.stiffness[2:] == (6.0, 3.0)  # type: ignore[index]


def test_defaults_body_link_is_the_middle_and_joint_names_are_numbered() -> None:
    doc = {"format": "suds-robot/1", "name": "c4", "links": [{"length": 1.0}] * 4,
           "joints": [{"actuated": True}, {"stiffness": 1.0}, {"damping": 0.5}]}
    m = model_from_dict(doc)
    assert m.body_link == 1 and m.joint_names == ("joint_1", "joint_2", "joint_3")
    assert m.c_par == (1.0,) * 4 and m.c_perp == (2.0,) * 4 and m.gait_hz == 1.0


@pytest.mark.parametrize("name", ["purcell3", "swimmer9", "nlink6"])
def test_export_round_trip_gives_identical_trajectories(name: str, tmp_path: Path) -> None:
    path = tmp_path / f"{name}.yaml"
    path.write_text(dump_model(builtin_model(name)))
    assert load_model(path) == builtin_model(name)
    cfg = SimConfig(cycles=2, seed=3)
    a, b = simulate(make_system(name), cfg), simulate(load_system(str(path)), cfg)
    np.testing.assert_array_equal(a.r, b.r)
    np.testing.assert_array_equal(a.pose, b.pose)
    assert a.joint_names == b.joint_names and a.actuated == b.actuated


def _edit(path: str, value: object) -> dict:  # type: ignore[type-arg]
    """The spec example with the value at ``path`` (dots and [i]) replaced; ``...`` deletes it."""
    doc = _doc()
    keys = path.replace("[", ".").replace("]", "").split(".")
    node = doc
    for k in keys[:-1]:
        node = node[int(k)] if k.isdigit() else node[k]
    last: object = int(keys[-1]) if keys[-1].isdigit() else keys[-1]
    if value is ...:
        del node[last]  # type: ignore[index]
    else:
        node[last] = value  # type: ignore[index]
    return doc


@pytest.mark.parametrize(("path", "value", "named"), [
    ("format", "suds-robot/2", "`format`"),
    ("format", ..., "`format`"),
    ("name", "lamprey 7", "`name`"),
    ("gait_hz", 0, "`gait_hz`"),
    ("gait_hz", True, "`gait_hz`"),
    ("drag.c_perp", -1.0, "`drag.c_perp`"),
    ("drag.c_prep", 1.0, "`drag.c_prep`"),
    ("links[2].length", 0.0, "`links[2].length`"),
    ("links[2].length", ..., "`links[2].length`"),
    ("links[3].width", 0.1, "`links[3].width`"),
    ("links[1].c_perp", "big", "`links[1].c_perp`"),
    ("body.link", 8, "`body.link`"),
    ("body.link", 0, "`body.link`"),
    ("body.offset", [0.0, 0.0], "`body.offset`"),
    ("joints[0].actuated", "yes", "`joints[0].actuated`"),
    ("joints[0].gait.frequency", 2.0, "`joints[0].gait.frequency`"),
    ("joints[3].stiffness", -0.1, "`joints[3].stiffness`"),
    ("joints[3].sping", 1.0, "`joints[3].sping`"),
    ("joints[4].rest", float("nan"), "`joints[4].rest`"),
    ("joints[1].name", "neck", "`joints[].name`"),
    ("environment.flow", [0.1], "`environment.flow`"),
    ("environment.current", [0.1, 0.0], "`environment.current`"),
    ("colour", "red", "`colour`"),
])
def test_bad_values_are_refused_naming_the_key(path: str, value: object, named: str) -> None:
    with pytest.raises(SudsConfigError, match=named.replace("[", r"\[").replace("]", r"\]")) as info:
        model_from_dict(_edit(path, value), "robot.yaml")
    assert info.value.code == "bad_model_file"
    assert str(info.value).startswith("robot.yaml: ")


def test_wrong_joint_count_is_refused() -> None:
    doc = _doc()
    doc["joints"].pop()
    with pytest.raises(SudsConfigError, match=r"`joints`: expected a list of 6 joints.*got 5"):
        model_from_dict(doc)


def test_no_actuated_joint_is_refused() -> None:
    doc = _doc()
    for j in doc["joints"][:3]:
        j["actuated"] = False
        j["stiffness"] = 1.0
    with pytest.raises(SudsConfigError, match=r"`joints\[\]\.actuated`: expected at least one actuated joint"):
        model_from_dict(doc)


def test_passive_joint_with_nothing_holding_it_is_refused() -> None:
    doc = _doc()
    doc["joints"][4] = {"name": "j5", "rest": 0.1}
    with pytest.raises(SudsConfigError, match=r"`joints\[4\]`: expected an actuated joint, or a passive one held"):
        model_from_dict(doc)


def test_file_level_errors(tmp_path: Path) -> None:
    missing = tmp_path / "none.yaml"
    with pytest.raises(SudsConfigError, match="cannot read the model file"):
        load_model(missing)
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: suds-robot/1\nlinks: [\n")
    with pytest.raises(SudsConfigError, match=r"bad.yaml: not valid YAML \(line \d+\)"):
        load_model(bad)
    dup = tmp_path / "dup.yaml"
    dup.write_text(SPEC_EXAMPLE + "gait_hz: 2.0\n")
    with pytest.raises(SudsConfigError, match="duplicate key 'gait_hz'"):
        load_model(dup)
    listy = tmp_path / "list.yaml"
    listy.write_text("- 1\n- 2\n")
    with pytest.raises(SudsConfigError, match="expected a mapping"):
        load_model(listy)


def test_model_file_or_system_id() -> None:
    assert is_model_file("robots/snake5.yaml") and is_model_file("x.yml")
    assert not is_model_file("purcell3") and not is_model_file("nlink7")
    with pytest.raises(SudsConfigError, match="unknown system 'purcel3'"):
        load_system("purcel3")


def test_model_differences_are_listed_in_one_error() -> None:
    from suds_ros.core.errors import MODEL_MISMATCH
    from suds_ros.core.physics.robot_model import check_joints, model_differences

    model = load_model(EEL4)
    assert model_differences(model, ("neck", "waist", "tail"), ("neck", "waist")) == []
    diffs = model_differences(model, ("waist", "neck", "fin"), ("neck",))
    assert diffs == ["missing joints (in the model, not in the recording): tail",
                     "extra joints (in the recording, not in the model): fin",
                     "roles differ: waist (recording passive, model actuated)",
                     "joint order differs: recording waist, neck; model neck, waist"]
    pattern = "^the recording's joints .* do not match the model 'eel4': missing joints"
    with pytest.raises(SudsConfigError, match=pattern) as info:
        check_joints(model, ("waist", "neck", "fin"), ("neck",))
    assert info.value.code == MODEL_MISMATCH and "\n" not in str(info.value)
