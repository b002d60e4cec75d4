import copy
import re

import pytest

gcmap = pytest.importorskip("gcmap", reason="gcmap is not built: build it and set PYTHONPATH=build/python")


def test_sections_are_attributes():
    c = gcmap.MappingConfig()
    assert c.preprocess.downsample == 0.25 and c.global_.mode == "full" and c.loop.enabled is True
    c.preprocess.downsample = 0.5
    c.global_.mode = "sliding-window"
    c.local.max_keyframes = 10
    c.loop.rings = 30.0  # an integral float is an integer
    assert c["preprocess.downsample"] == 0.5 and getattr(c, "global").mode == "sliding-window"
    assert c.local.max_keyframes == 10 and c.loop.rings == 30
    assert "downsample" in dir(c.preprocess)
    assert c != gcmap.MappingConfig() and c == c.copy() and copy.deepcopy(c) == c


def test_every_yaml_key_is_reachable():
    keys = gcmap.MappingConfig.keys()
    assert len(keys) == len(set(keys)) > 40
    c = gcmap.MappingConfig()
    yaml = c.to_yaml()
    for key in keys:
        section, field = key.split(".")
        assert f"  {field}: " in yaml
        assert getattr(getattr(c, section), field) == c.get(key)


def test_yaml_round_trip():
    c = gcmap.MappingConfig({"preprocess": {"max_range": 80.0}, "global.factor": "se3", "loop.enabled": False})
    back = gcmap.MappingConfig.from_yaml(c.to_yaml())
    assert back == c and back.preprocess.max_range == 80.0 and back.global_.factor == "se3"
    assert back.to_dict()["loop"]["enabled"] is False
    partial = gcmap.MappingConfig.from_yaml("odometry:\n  max_iterations: 12\n")
    assert partial.odometry.max_iterations == 12 and partial.preprocess.downsample == 0.25


def test_load(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("local:\n  th_min: 0.2\n")
    assert gcmap.MappingConfig.load(str(path)).local.th_min == 0.2
    with pytest.raises(FileNotFoundError, match="missing.yaml"):
        gcmap.MappingConfig.load(str(tmp_path / "missing.yaml"))


@pytest.mark.parametrize("key, value, message", [
    ("preprocess.downsample", -1.0, re.escape("preprocess.downsample must be in [0.01, 100] m, got -1")),
    ("preprocess.downsample", "fine", "preprocess.downsample must be a number, got 'fine'"),
    ("local.max_keyframes", 2.5, "local.max_keyframes must be an integer, got 2.5"),
    ("loop.enabled", 1, "loop.enabled must be true or false, got 1"),
    ("global.mode", "partial", "global.mode must be one of full, sliding-window, got 'partial'"),
    ("preprocess.downsampel", 1.0, "unknown key 'preprocess.downsampel'"),
])
def test_bad_values_raise_value_error_naming_the_key(key, value, message):
    c = gcmap.MappingConfig()
    before = c.to_yaml()
    with pytest.raises(ValueError, match=message):
        c.set(key, value)
    with pytest.raises(ValueError, match=message):
        gcmap.MappingConfig({key: value})
    assert c.to_yaml() == before  # a rejected change leaves the config as it was


@pytest.mark.parametrize("key, value, message", [
    ("preprocess.downsample", 1e-300, "preprocess.downsample must be in [0.01, 100] m, got 1e-300"),
    ("global.voxel_resolution", 1e-300, "global.voxel_resolution must be in [0.01, 100] m, got 1e-300"),
    ("loop.rings", 2000000000, "loop.rings must be in [1, 200], got 2000000000"),
    ("loop.sectors", 2000000000, "loop.sectors must be in [2, 360], got 2000000000"),
    ("preprocess.num_neighbors", 2000000000, "preprocess.num_neighbors must be in [4, 100], got 2000000000"),
])
def test_values_out_of_range_name_the_key(key, value, message):
    c = gcmap.MappingConfig()
    section, field = key.split(".")
    for change in (lambda: c.set(key, value), lambda: setattr(getattr(c, section), field, value),
                   lambda: gcmap.MappingConfig({key: value})):
        with pytest.raises(ValueError, match=re.escape(message)):
            change()
    assert c == gcmap.MappingConfig()
    with pytest.raises(ValueError, match=re.escape("config: " + message)):
        gcmap.MappingConfig.from_yaml(f"{section}:\n  {field}: {value}\n")


def test_attribute_errors():
    c = gcmap.MappingConfig()
    with pytest.raises(AttributeError, match="preprocess.downsampel"):
        c.preprocess.downsampel = 1.0
    with pytest.raises(ValueError, match=re.escape("odometry.voxel_resolution must be in [0.01, 100] m, got 0")):
        c.odometry.voxel_resolution = 0.0
    assert c.odometry.voxel_resolution == 0.7


def test_yaml_errors_name_the_key():
    with pytest.raises(ValueError, match="unknown key 'local.nope'"):
        gcmap.MappingConfig.from_yaml("local:\n  nope: 1\n")
    with pytest.raises(ValueError, match="local.th_max"):
        gcmap.MappingConfig.from_yaml("local:\n  th_max: 2.0\n")
    with pytest.raises(ValueError, match="YAML syntax error"):
        gcmap.MappingConfig.from_yaml("local: [\n")
