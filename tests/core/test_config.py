"""vistac.config: fields declared once, checked on construction, applied from files and flags."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import pytest

from vistac.config import Config, ConfigError, apply, param, to_dict
from vistac.config_options import add_options, flag_labels, from_options, option_values
from vistac.errors import UserError


@dataclass(frozen=True)
class Part(Config):
    """A switchable part."""

    std: float = param(0.5, ge=0, help="a std")
    fingers: tuple[str, ...] = param(("index",), choices=("index", "thumb"))


@dataclass(frozen=True)
class Tree(Config):
    """A small config tree."""

    n: int = param(3, ge=1, help="how many")
    rate: float = param(0.1, gt=0, lt=1, why="a fraction")
    mode: Literal["a", "b"] = param("a", help="the mode")
    span: tuple[float, float] = param((0.0, 1.0), flag="--range", metavar=("LO", "HI"))
    name: str | None = param(None)
    on: bool = param(False, help="a switch")
    part: Part | None = param(None)
    inner: Part = field(default_factory=Part)


def test_construction_checks_types_bounds_and_choices():
    assert Tree().n == 3
    with pytest.raises(ConfigError, match=r"n: must be >= 1, got 0"):
        Tree(n=0)
    with pytest.raises(ConfigError, match=r"rate: must be < 1, got 1.5 \(a fraction\)"):
        Tree(rate=1.5)
    with pytest.raises(ConfigError, match="n: expected an integer, got 2.5"):
        Tree(n=2.5)
    with pytest.raises(ConfigError, match="n: expected an integer, got True"):
        Tree(n=True)
    with pytest.raises(ConfigError, match="mode: expected one of 'a', 'b'"):
        Tree(mode="c")
    with pytest.raises(ConfigError, match="span: expected a list of 2 numbers"):
        Tree(span=(1.0,))
    with pytest.raises(ConfigError, match="fingers: must be one of index, thumb, got 'pinky'"):
        Part(fingers=("pinky",))
    assert isinstance(ConfigError("k", "r"), UserError)


def test_values_keep_their_type_and_lists_become_tuples():
    t = Tree(rate=0.5, span=[0, 2])
    assert t.span == (0, 2) and isinstance(t.span, tuple)
    assert type(Tree(rate=1 - 0.5).rate) is float
    assert to_dict(Tree(span=[1, 2]))["span"] == [1, 2]  # an int stays an int in a manifest


def test_apply_switches_parts_and_names_file_and_key():
    t = apply(Tree(), {"part": True, "inner": {"std": 2}})
    assert t.part == Part() and t.inner.std == 2
    t = apply(t, {"part": {"std": 1.5}})
    assert t.part.std == 1.5 and t.part.fingers == ("index",)
    assert apply(t, {"part": True}).part.std == 1.5  # `true` keeps the parameters it has
    assert apply(t, {"part": False}).part is None and apply(t, {"part": None}).part is None
    assert Tree().part is None  # apply never changes its input
    cases = [({"nn": 1}, "f.yaml: tree.nn: unknown key (known: n, rate,"),
             ({"part": {"std": -1}}, "f.yaml: tree.part.std: must be >= 0, got -1"),
             ({"part": 3}, "f.yaml: tree.part: expected a table of settings, got 3"),
             ({"inner": {"fingers": "index"}}, "f.yaml: tree.inner.fingers: expected a list")]
    for data, message in cases:
        with pytest.raises(UserError) as info:
            apply(Tree(), data, "f.yaml", prefix="tree")
        assert message in str(info.value)
        assert "\n" not in str(info.value)


def test_flags_share_the_schema():
    parser = argparse.ArgumentParser()
    paths = ("n", "rate", "mode", "span", "name", "on", "inner.std")
    add_options(parser, Tree, paths)
    args = parser.parse_args(["--n", "5", "--range", "1", "2", "--on", "--std", "0.25"])
    assert option_values(args, Tree, paths) == {
        "n": 5, "rate": 0.1, "mode": "a", "span": [1.0, 2.0], "name": None, "on": True,
        "inner": {"std": 0.25}}
    t = apply(Tree(), option_values(args, Tree, paths), labels=flag_labels(Tree, paths))
    assert (t.n, t.span, t.on, t.inner.std) == (5, (1.0, 2.0), True, 0.25)
    bad = parser.parse_args(["--std", "-1"])
    with pytest.raises(UserError, match=r"^--std: must be >= 0, got -1.0$"):
        apply(Tree(), option_values(bad, Tree, paths), labels=flag_labels(Tree, paths))
    flat = ("n", "rate", "mode", "span", "name", "on")
    with pytest.raises(UserError, match=r"^--range: expected a list of 2 numbers"):
        from_options(Tree, argparse.Namespace(**(vars(args) | {"range": [1.0]})), flat)
    with pytest.raises(SystemExit):  # argparse knows the choices
        parser.parse_args(["--mode", "c"])


def test_a_default_config_tree_round_trips_through_json_like_dicts():
    t = apply(Tree(), {"part": {"fingers": ["index", "thumb"]}, "name": "x"})
    again = apply(Tree(), to_dict(t))
    assert again == t and dataclasses.asdict(again) == dataclasses.asdict(t)


def test_mesh_paths_are_stored_absolute(tmp_path, monkeypatch):
    from vistac_sim.objects.config import ObjectsCfg

    monkeypatch.chdir(tmp_path)
    cfg = ObjectsCfg(paths=("meshes/a.stl", "~/b.obj"))
    assert cfg.paths == (str(tmp_path / "meshes" / "a.stl"),
                         str((tmp_path.home() / "b.obj").resolve()))


def test_configs_are_frozen_and_a_changed_one_is_a_new_checked_one():
    from vistac_sim.generate.config import GenerateCfg

    @dataclass
    class Loose(Config):
        n: int = param(1)

    with pytest.raises(TypeError, match="frozen"):
        Loose()
    cfg = GenerateCfg()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.physics.friction = 0.0  # a part shared by copies cannot change under them
    changed = apply(cfg, {"physics": {"friction": 0.0}})
    assert changed.physics.friction == 0.0 and cfg.physics.friction != 0.0
    with pytest.raises(UserError, match="^physics.friction: must be >= 0"):
        apply(cfg, {"physics": {"friction": -1.0}})


def test_apply_takes_a_made_part_in_place():
    t = apply(Tree(), {"part": Part(std=2.0), "inner": Part(std=3.0)})
    assert t.part == Part(std=2.0) and t.inner.std == 3.0
    with pytest.raises(UserError, match="expected a table of settings"):
        apply(Tree(), {"part": Tree()})  # a config of another class is no part


@dataclass(frozen=True)
class Pair(Config):
    """Two fields, one check across them."""

    low: int = param(0)
    high: int = param(1)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.high <= self.low:
            raise ConfigError("high", "must be above {low}", ("low",))


def test_a_cross_field_error_names_fields_and_the_cli_names_options():
    with pytest.raises(ConfigError) as info:
        Pair(low=2, high=1)
    assert str(info.value) == "high: must be above low"
    paths = ("low", "high")
    parser = argparse.ArgumentParser()
    add_options(parser, Pair, paths)
    args = parser.parse_args(["--low", "2", "--high", "1"])
    with pytest.raises(UserError, match=r"^--high: must be above --low$"):
        from_options(Pair, args, paths)
    with pytest.raises(UserError, match=r"^--high: must be above --low$"):
        apply(Pair(), option_values(args, Pair, paths), labels=flag_labels(Pair, paths))


def test_train_config_errors_name_fields_not_options():
    from vistac_learn.train.config import TrainCfg

    cases = [({"model": "resnet-huge"}, "model: 'resnet-huge' is unknown"),
             ({"freeze": "features"}, "freeze: needs init RUN"),
             ({"val_split": "train"}, "val_split: must differ from train_split (train)")]
    for changes, message in cases:
        with pytest.raises(ConfigError) as info:
            TrainCfg(data="d", out="o", **changes)
        assert str(info.value).startswith(message) and "--" not in str(info.value)
