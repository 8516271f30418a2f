"""Tests for jaxmotion.config and configs/data.py: parsing, errors, presets, loading, JSON."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any, Literal, Optional

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from configs.data import DataConfig
from jaxmotion.config import (ConfigError, apply_overrides, config_from_dict, config_to_dict,
                              flatten_config, format_config, load_config, load_config_json,
                              save_config_json)

REPO = Path(__file__).resolve().parents[1]


@dataclasses.dataclass(frozen=True)
class Inner:
    width: int = 16
    rate: float = 0.5
    name: str | None = None


@dataclasses.dataclass(frozen=True)
class Cfg:
    flag: bool = False
    count: int = 1
    lr: float = 1e-3
    label: str = "x"
    maybe: Optional[int] = 3
    ints: tuple[int, ...] = (1, 2)
    floats: tuple[float, ...] = ()
    words: tuple[str, ...] = ("a",)
    pair: tuple[int, float] = (0, 0.0)
    mode: Literal["fast", "slow"] = "fast"
    level: Literal[1, 2, 3] = 1
    items: list = dataclasses.field(default_factory=list)
    anything: Any = None
    inner: Inner = dataclasses.field(default_factory=Inner)


def err(cfg, overrides) -> str:
    with pytest.raises(ConfigError) as info:
        apply_overrides(cfg, overrides)
    return str(info.value)


@pytest.mark.parametrize("text,value", [("true", True), ("TRUE", True), ("Yes", True),
                                        ("1", True), ("false", False), ("No", False),
                                        ("0", False), (" False ", False)])
def test_bool(text, value):
    assert apply_overrides(Cfg(flag=not value), [f"flag={text}"]).flag is value


@pytest.mark.parametrize("text,value", [("42", 42), ("-3", -3), ("+7", 7), (" 5 ", 5)])
def test_int(text, value):
    assert apply_overrides(Cfg(), [f"count={text}"]).count == value


@pytest.mark.parametrize("text,value", [("1e-4", 1e-4), ("3", 3.0), ("-2.5", -2.5)])
def test_float(text, value):
    out = apply_overrides(Cfg(), [f"lr={text}"]).lr
    assert out == value and type(out) is float


def test_str_keeps_equals_and_quotes_protect_spaces():
    assert apply_overrides(Cfg(), ["label=a=b"]).label == "a=b"
    assert apply_overrides(Cfg(), ["label=' two words '"]).label == " two words "
    assert apply_overrides(Cfg(), ["label=data/synth"]).label == "data/synth"


def test_optional():
    assert apply_overrides(Cfg(), ["maybe=none"]).maybe is None
    assert apply_overrides(Cfg(), ["maybe=NULL"]).maybe is None
    assert apply_overrides(Cfg(maybe=None), ["maybe=9"]).maybe == 9
    assert apply_overrides(Cfg(), ["inner.name=null"]).inner.name is None
    assert apply_overrides(Cfg(), ["inner.name='none'"]).inner.name == "none"  # quoted: a str
    assert apply_overrides(Cfg(), ["inner.name=bob"]).inner.name == "bob"
    msg = err(Cfg(), ["maybe=abc"])
    assert "'maybe'" in msg and "int | None" in msg and "'abc'" in msg


@pytest.mark.parametrize("text", ["1,2,3", "(1,2,3)", "[1,2,3]", " 1 , 2 , 3 ", "1,2,3,"])
def test_int_tuple_forms(text):
    assert apply_overrides(Cfg(), [f"ints={text}"]).ints == (1, 2, 3)


def test_tuple_edge_cases():
    assert apply_overrides(Cfg(), ["ints=()"]).ints == ()
    assert apply_overrides(Cfg(), ["ints="]).ints == ()
    assert apply_overrides(Cfg(), ["ints=5,"]).ints == (5,)
    assert apply_overrides(Cfg(), ["ints=[7]"]).ints == (7,)
    assert apply_overrides(Cfg(), ["floats=1e-3,2"]).floats == (1e-3, 2.0)
    assert apply_overrides(Cfg(), ["words=(a, b c)"]).words == ("a", "b c")
    assert apply_overrides(Cfg(), ["pair=4,0.5"]).pair == (4, 0.5)
    msg = err(Cfg(), ["ints=1,x"])
    assert "'ints'" in msg and "tuple[int, ...]" in msg and "'1,x'" in msg and "1,2,3" in msg
    msg = err(Cfg(), ["pair=1,2,3"])
    assert "'pair'" in msg and "tuple[int, float]" in msg


def test_literal():
    assert apply_overrides(Cfg(), ["mode=slow"]).mode == "slow"
    assert apply_overrides(Cfg(), ["level=3"]).level == 3
    msg = err(Cfg(), ["mode=medium"])
    assert "'mode'" in msg and "'fast'" in msg and "'slow'" in msg and "'medium'" in msg
    msg = err(Cfg(), ["level=4"])
    assert "'level'" in msg and "1, 2, 3" in msg
    assert "'level'" in err(Cfg(), {"level": True})  # True == 1 but is not the choice 1


@pytest.mark.parametrize("key,text,expected", [
    ("count", "1.5", "int"), ("count", "1e3", "int"), ("count", "abc", "int"),
    ("lr", "fast", "float"), ("flag", "maybe", "bool"), ("inner.width", "wide", "int")])
def test_wrong_type_message(key, text, expected):
    msg = err(Cfg(), [f"{key}={text}"])
    assert f"'{key}'" in msg and f"expected {expected}" in msg and repr(text) in msg
    if expected == "bool":
        assert "true/false" in msg


def test_types_without_string_form_are_rejected():
    msg = err(Cfg(), ["items=1,2"])
    assert "'items'" in msg and "expected list" in msg
    assert apply_overrides(Cfg(), {"items": [1]}).items == [1]  # Python values still work


def test_nested_override_and_nested_config_cannot_be_set_directly():
    out = apply_overrides(Cfg(), ["inner.width=32", "inner.rate=2"])
    assert out.inner == Inner(width=32, rate=2.0)
    msg = err(Cfg(), ["inner=3"])
    assert "'inner'" in msg and "inner.width=" in msg and "inner.rate=" in msg
    assert "inner.name=" in msg and "set its fields" in msg
    assert "'inner'" in err(Cfg(), {"inner": Inner()})


def test_unknown_keys_list_valid_keys_and_suggest():
    msg = err(Cfg(), ["cuont=3"])
    assert "'cuont'" in msg and "Did you mean 'count'" in msg
    assert "flag, count, lr" in msg and "inner.*" in msg
    msg = err(Cfg(), ["inner.widht=3"])
    assert "'inner.widht'" in msg and "Did you mean 'inner.width'" in msg
    assert "width, rate, name" in msg
    msg = err(Cfg(), ["width=3"])  # a leaf that lives one level down
    assert "Did you mean 'inner.width'" in msg
    msg = err(Cfg(), ["count.x=3"])
    assert "'count.x'" in msg and "not a nested config" in msg


@pytest.mark.parametrize("bad", ["count", "=3", "inner..width=1", ".count=1", "count.=1"])
def test_malformed_override(bad):
    msg = err(Cfg(), [bad])
    assert repr(bad) in msg and "key=value" in msg and "flag=..." in msg


def test_mapping_overrides_coerce_and_later_wins():
    out = apply_overrides(Cfg(), {"lr": 1, "ints": [4, 5], "count": "7", "inner.rate": 3})
    assert out.lr == 1.0 and type(out.lr) is float and out.ints == (4, 5) and out.count == 7
    assert out.inner.rate == 3.0
    assert apply_overrides(Cfg(), ["count=2", "count=5"]).count == 5
    assert "'count'" in err(Cfg(), {"count": True})  # bool is not an int here
    assert "'count'" in err(Cfg(), {"count": 1.0})
    assert apply_overrides(Cfg(), "count=4").count == 4  # a lone string is one override


def test_never_mutates_and_stays_frozen():
    cfg = Cfg()
    out = apply_overrides(cfg, ["count=9", "inner.width=3"])
    assert cfg == Cfg() and out is not cfg and out.count == 9
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.count = 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.inner.width = 1
    assert apply_overrides(cfg, []) is cfg


def test_post_init_sees_final_values_and_errors_name_keys():
    cfg = DataConfig()  # each alone would break min_frames <= max_frames
    out = apply_overrides(cfg, ["max_frames=16", "min_frames=8"])
    assert (out.min_frames, out.max_frames) == (8, 16)
    msg = err(cfg, ["min_frames=500"])
    assert "min_frames" in msg and "DataConfig" in msg
    msg = err(cfg, ["crop.num_points=0"])
    assert "crop.num_points" in msg and "CropConfig" in msg


def test_data_config_defaults_match_docs():
    cfg = load_config("data")
    assert isinstance(cfg, DataConfig)
    assert cfg.crop.size == 4.0 and cfg.crop.num_points == 8192 and cfg.crop.z_percentile == 2.0
    assert cfg.crop.rotate is True and cfg.crop.rotation_range == math.pi
    assert (cfg.fps, cfg.max_frames, cfg.min_frames) == (30, 120, 30)
    assert cfg.affordance.joints == (0, 10, 11, 12, 20, 21) and cfg.affordance.sigma == 0.8
    assert (cfg.data_dir, cfg.seed, cfg.batch_size) == ("data/synth", 0, 32)


def test_presets_apply_first_wherever_they_appear():
    tiny = load_config("data", ["preset=tiny"])
    assert (tiny.crop.num_points, tiny.max_frames, tiny.min_frames, tiny.batch_size) == (
        256, 16, 8, 4)
    for overrides in (["batch_size=7", "preset=tiny"], ["preset=tiny", "batch_size=7"]):
        cfg = load_config("data", overrides)
        assert cfg.batch_size == 7 and cfg.crop.num_points == 256
    paper = load_config("data", ["preset=paper"])
    assert (paper.crop.num_points, paper.max_frames, paper.batch_size) == (8192, 120, 32)
    assert load_config("data", ["preset=default"]) == load_config("data")
    assert load_config("data", ["preset=tiny", "preset=tiny"]) == tiny


def test_preset_errors():
    with pytest.raises(ConfigError, match="unknown preset 'tinny'") as info:
        load_config("data", ["preset=tinny"])
    assert "Did you mean 'tiny'" in str(info.value)
    assert "default, paper, tiny" in str(info.value)
    with pytest.raises(ConfigError, match="more than once"):
        load_config("data", ["preset=tiny", "preset=paper"])
    with pytest.raises(ConfigError, match="malformed override 'preset'"):
        load_config("data", ["preset"])


def test_load_by_path_and_by_name(monkeypatch, tmp_path):
    by_name = load_config("data", ["seed=3"])
    assert load_config("configs/data.py", ["seed=3"]) == by_name
    assert load_config(str(REPO / "configs" / "data.py"), ["seed=3"]) == by_name
    monkeypatch.chdir(tmp_path)  # no ./configs here: falls back to the package's repo
    assert load_config("data", ["seed=3"]) == by_name
    with pytest.raises(ConfigError) as info:
        load_config("nope")
    assert "'nope' not found" in str(info.value) and "data" in str(info.value)


CUSTOM = '''
from __future__ import annotations
import dataclasses
from typing import ClassVar, Literal

@dataclasses.dataclass(frozen=True)
class Sub:
    k: int = 1

@dataclasses.dataclass(frozen=True)
class Top:
    unit: ClassVar[str] = "m"
    kind: Literal["a", "b"] = "a"
    sub: Sub = dataclasses.field(default_factory=Sub)

PRESETS = {"big": {"sub.k": "{K}"}}

def get_config():
    return Top()
'''


def test_cwd_configs_first_and_private_modules(monkeypatch, tmp_path):
    (tmp_path / "configs").mkdir()
    path = tmp_path / "configs" / "data.py"
    path.write_text(CUSTOM.replace("{K}", "5"))
    before = set(sys.modules)
    monkeypatch.chdir(tmp_path)
    cfg = load_config("data", ["preset=big", "kind=b"])  # hints resolve outside sys.modules
    assert type(cfg).__name__ == "Top" and (cfg.kind, cfg.sub.k) == ("b", 5)
    assert set(sys.modules) == before
    assert load_config("data", ["preset=big", "kind=b"]) == cfg  # same class when unchanged
    path.write_text(CUSTOM.replace("{K}", "6"))
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    assert load_config("data", ["preset=big"]).sub.k == 6  # re-run after a change
    assert config_from_dict(type(cfg), config_to_dict(cfg)) == cfg
    assert "'kind'" in str(pytest.raises(ConfigError, load_config, "data", ["kind=c"]).value)


@pytest.mark.parametrize("body,match", [
    ("X = 1\n", "must define get_config"),
    ("def get_config():\n    return {}\n", "not a dataclass"),
    ("import dataclasses\n@dataclasses.dataclass\nclass C:\n    a: int = 1\n"
     "def get_config():\n    return C()\n", "must be a frozen dataclass"),
    ("raise RuntimeError('boom')\n", "boom"),
])
def test_bad_config_files(tmp_path, body, match):
    path = tmp_path / "bad.py"
    path.write_text(body)
    with pytest.raises(ConfigError, match=match):
        load_config(str(path))


def test_json_round_trip_and_file(tmp_path):
    cfg = load_config("data", ["preset=tiny", "affordance.joints=0,20", "max_samples=5"])
    d = config_to_dict(cfg)
    assert d["affordance"]["joints"] == [0, 20] and d["crop"]["num_points"] == 256
    assert json.loads(json.dumps(d)) == d
    assert config_from_dict(DataConfig, json.loads(json.dumps(d))) == cfg
    path = save_config_json(cfg, tmp_path / "run" / "config.json")
    assert json.loads(path.read_text()) == d
    assert load_config_json(DataConfig, path) == cfg
    save_config_json(DataConfig(), path)  # overwrite in place
    assert load_config_json(DataConfig, path) == DataConfig()
    assert [p.name for p in path.parent.iterdir()] == ["config.json"]  # no temp files left


def test_save_config_json_is_atomic(tmp_path, monkeypatch):
    path = save_config_json(DataConfig(), tmp_path / "config.json")
    before = path.read_text()

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        save_config_json(DataConfig(seed=5), path)
    assert path.read_text() == before and len(list(tmp_path.iterdir())) == 1


def test_config_from_dict_errors():
    d = config_to_dict(DataConfig())
    with pytest.raises(ConfigError, match="unknown key 'crop.sise'.*Did you mean 'crop.size'"):
        config_from_dict(DataConfig, {**d, "crop": {**d["crop"], "sise": 1.0}})
    with pytest.raises(ConfigError, match="unknown key 'bach_size'.*batch_size"):
        config_from_dict(DataConfig, {**d, "bach_size": 1})
    with pytest.raises(ConfigError, match="'seed'.*expected int.*'3'"):
        config_from_dict(DataConfig, {**d, "seed": "3"})
    with pytest.raises(ConfigError, match="min_frames"):
        config_from_dict(DataConfig, {**d, "min_frames": 500})
    assert config_from_dict(DataConfig, {"seed": 4}) == DataConfig(seed=4)  # defaults fill in
    with pytest.raises(ConfigError, match="missing key 'count'"):
        config_from_dict(dataclasses.make_dataclass("NoDefault", [("count", int)],
                                                     frozen=True), {})
    with pytest.raises(ConfigError, match="'anything'.*object"):
        config_to_dict(Cfg(anything=object()))


_FIELDS = {
    "seed": st.integers(-2**40, 2**40), "batch_size": st.integers(1, 512),
    "dataset": st.sampled_from(["synth", "humanise", "humanml3d", "prox"]),
    "data_dir": st.text(st.characters(min_codepoint=48, max_codepoint=122), min_size=1),
    "max_samples": st.none() | st.integers(1, 10**6),
    "crop.size": st.floats(0.01, 100, allow_nan=False), "crop.rotate": st.booleans(),
    "crop.z_percentile": st.floats(0, 100), "crop.num_points": st.integers(1, 10**5),
    "affordance.joints": st.lists(st.integers(0, 21), min_size=1, max_size=6).map(tuple),
    "affordance.sigma": st.floats(1e-6, 10),
}


def _as_text(value) -> str:
    if isinstance(value, tuple):
        return "[" + ",".join(map(str, value)) + "]"
    return repr(value) if isinstance(value, float) else str(value)


@settings(max_examples=60, deadline=None)
@given(st.fixed_dictionaries({}, optional=_FIELDS))
def test_random_overrides_parse_and_round_trip(values):
    cfg = apply_overrides(DataConfig(), [f"{k}={_as_text(v)}" for k, v in values.items()])
    flat = flatten_config(cfg)
    assert all(flat[k] == v for k, v in values.items())
    assert apply_overrides(DataConfig(), values) == cfg
    assert config_from_dict(DataConfig, json.loads(json.dumps(config_to_dict(cfg)))) == cfg


def test_format_and_flatten():
    text = format_config(load_config("data", ["preset=tiny"]))
    assert text.splitlines()[0] == "DataConfig"
    assert "  crop: CropConfig" in text and "    num_points: 256" in text
    assert "  batch_size: 4" in text and "    joints: (0, 10, 11, 12, 20, 21)" in text
    assert list(flatten_config(Cfg()))[-3:] == ["inner.width", "inner.rate", "inner.name"]


def test_no_jax_import():
    code = "import sys, jaxmotion.config, configs.data; assert 'jax' not in sys.modules"
    subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=REPO, check=True)


def test_grounding_and_loader_settings_are_checked():
    from jaxmotion.config import load_config

    for bad in ("grounding_cases=0", "grounding_every=-1", "grounding_steps=0",
                "grounding_guidance=0", "loader_workers=-1"):
        with pytest.raises(ValueError, match=bad.split("=")[0]):
            load_config("configs/adm.py", [bad])
    cfg = load_config("configs/adm.py", ["grounding_every=500", "loader_workers=4"])
    assert cfg.grounding_every == 500 and cfg.loader_workers == 4
