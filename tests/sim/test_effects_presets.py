"""Presets and scene files; a disabled effect is never constructed nor called."""

import dataclasses
import json

import pytest

from vistac.cli import main
from vistac.config import apply
from vistac.errors import UserError
from vistac_sim.effects import EffectsCfg, build_pipeline
from vistac_sim.effects.finger_pull import FingerPullCfg
from vistac_sim.effects.fts3 import Fts3Cfg
from vistac_sim.effects.noise import ForceNoise
from vistac_sim.effects.presets import PRESETS, resolve
from vistac_sim.effects.registry import Effect, register_effect, registered
from vistac_sim.generate import configuration
from vistac_sim.generate.config import GenerateCfg

SENSOR_PARTS = {"fts3.hysteresis", "fts3.nonlinearity", "fts3.zero_offset", "fts3.drift",
                "fts3.sample_noise", "fts3.saturation", "fts3.quantisation"}


def _names(effects: EffectsCfg) -> set[str]:
    return {e["name"] for e in build_pipeline(effects).describe()}


def test_effects_config_is_assembled_from_the_registry():
    keys = [r.key for r in registered()]
    assert keys == [f.name for f in dataclasses.fields(EffectsCfg)] == [
        "noise", "fts3", "finger_pull", "placement_error", "overlay_error", "camera_jitter",
        "lighting", "shadows", "table", "object_material", "phone_camera", "exposure", "blur",
        "sensor_noise", "jpeg", "drawn_overlay"]  # the order effects run in within a stage
    assert EffectsCfg().fts3 is None and EffectsCfg(fts3=Fts3Cfg()).fts3 == Fts3Cfg()
    with pytest.raises(UserError, match="noise: must be >= 0"):
        EffectsCfg(noise=-0.1)
    with pytest.raises(ValueError, match="already registered"):
        register_effect("noise", lambda v: [], value=0.0)


def test_presets_parse_and_build():
    assert set(PRESETS) == {"clean", "lab", "harsh", "photo"}
    clean, _ = resolve("clean")
    assert clean == EffectsCfg() and _names(clean) == set()
    assert _names(resolve("clean", noise=0.05)[0]) == {"force_noise"}
    lab = _names(resolve("lab")[0])
    assert SENSOR_PARTS | {"finger_pull", "placement_error", "overlay_error"} <= lab
    assert lab <= _names(resolve("harsh")[0])
    lab_cfg, harsh_cfg = resolve("lab")[0], resolve("harsh")[0]
    assert harsh_cfg.fts3.hysteresis > lab_cfg.fts3.hysteresis
    assert harsh_cfg.finger_pull.mean > lab_cfg.finger_pull.mean
    assert lab_cfg.fts3.full_scale == 10.0 and lab_cfg.fts3.resolution == 0.001


def test_effects_round_trip_through_the_manifest_dict():
    cfg = GenerateCfg.from_preset("harsh", noise=0.02)
    again = apply(GenerateCfg(), json.loads(json.dumps(cfg.to_dict())))
    assert again == cfg


def test_yaml_scene_merges_over_the_preset(tmp_path):
    f = tmp_path / "scene.yaml"
    f.write_text("preset: lab\neffects:\n  fts3: {hysteresis: 0.03}\n  finger_pull: false\n"
                 "  noise: 0.01\nrecording: {hold_s: 1.5}\n")
    eff, rec = resolve(None, f)
    assert eff.fts3.hysteresis == 0.03
    assert eff.fts3.nonlinearity == resolve("lab")[0].fts3.nonlinearity  # kept from lab
    assert eff.finger_pull is None and eff.placement_error is not None
    assert eff.noise == 0.01 and rec.hold_s == 1.5
    assert resolve(None, f, noise=0.2)[0].noise == 0.2  # --noise wins
    assert resolve("clean", f)[0].placement_error is None  # --preset wins over the file's


def test_toml_scene_switches_a_subset_on(tmp_path):
    f = tmp_path / "scene.toml"
    f.write_text("[effects]\nfinger_pull = true\n\n[effects.fts3]\nsample_noise = 0.0\n"
                 "drift_std = 0\n\n[effects.placement_error]\nangle_std_deg = 5\n")
    eff, _ = resolve(None, f)
    assert eff.finger_pull == FingerPullCfg()
    assert eff.placement_error.angle_std_deg == 5.0
    names = _names(eff)
    assert "fts3.sample_noise" not in names and "fts3.drift" not in names
    assert {"fts3.hysteresis", "finger_pull", "placement_error"} <= names


@pytest.mark.parametrize("text, key", [
    ("effects:\n  fts3: {hysterisis: 0.03}\n", "effects.fts3.hysterisis"),
    ("effects:\n  finger_pul: true\n", "effects.finger_pul"),
    ("efects: {}\n", "efects"),
    ("recording: {hold: 2}\n", "recording.hold"),
    ("effects:\n  fts3: {hysteresis: high}\n", "effects.fts3.hysteresis"),
    ("effects:\n  finger_pull: 3\n", "effects.finger_pull"),
    ("preset: lob\n", "lob"),
])
def test_bad_scene_file_names_file_and_key(tmp_path, text, key):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(UserError) as info:
        resolve(None, f)
    assert str(f) in str(info.value) and key in str(info.value)


def test_unreadable_scene_files(tmp_path):
    for name, text in (("x.yaml", "effects: [unclosed\n"), ("x.toml", "[effects\n"),
                       ("x.json", "{}")):
        f = tmp_path / name
        f.write_text(text)
        with pytest.raises(UserError, match=str(f)):
            resolve(None, f)
    with pytest.raises(UserError, match="no such scene file"):
        resolve(None, tmp_path / "missing.yaml")


def test_cli_reports_a_bad_scene_file_in_one_line(tmp_path, capsys):
    f = tmp_path / "bad.toml"
    f.write_text("[effects.fts3]\nbias = 1\n")
    rc = main(["generate", "--out", str(tmp_path / "d"), "--n", "2", "--scene", str(f),
               "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and str(f) in err and "effects.fts3.bias" in err
    assert not (tmp_path / "d").exists()


def _all_effect_classes() -> list[type]:
    seen, todo = [], [Effect]
    while todo:
        for sub in todo.pop().__subclasses__():
            seen.append(sub)
            todo.append(sub)
    return seen


def _forbid(monkeypatch, classes) -> None:
    def refuse(self, *args, **kwargs):
        raise AssertionError(f"{type(self).__name__} must not be constructed nor called")

    for cls in classes:
        monkeypatch.setattr(cls, "__init__", refuse)
        monkeypatch.setattr(cls, "__call__", refuse)


def test_disabled_effects_are_never_constructed_nor_called(tmp_path, monkeypatch):
    assert len(registered()) == 16  # every effect module is imported (and registered)
    forbidden = [c for c in _all_effect_classes() if c is not ForceNoise]
    assert len(forbidden) >= 12
    _forbid(monkeypatch, forbidden)

    def no_session(*args, **kwargs):
        raise AssertionError("no time series without sensor effects or --recordings")

    monkeypatch.setattr(configuration, "simulate_session", no_session)
    with pytest.raises(AssertionError):  # the guard bites when an effect is switched on
        build_pipeline(EffectsCfg(fts3=Fts3Cfg()))
    out = tmp_path / "d"
    rc = main(["generate", "--out", str(out), "--n", "3", "--workers", "1", "--no-progress",
               "--n-objects", "2", "--preset", "clean", "--noise", "0.05"])
    assert rc == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert [e["name"] for e in manifest["effects"]] == ["force_noise"]
    assert manifest["config"]["effects"]["fts3"] is None
