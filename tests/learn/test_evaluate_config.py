"""`EvaluateCfg` (issue 33): one test-time augmentation choice, one rule for the default output
folder, errors that name fields in Python and options on the command line."""

from __future__ import annotations

import pytest

from vistac.cli import main
from vistac.config import ConfigError
from vistac_learn.evaluate.config import EvaluateCfg, default_out_dir


@pytest.fixture
def run(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.json").write_text("{}")
    return tmp_path / "run"


def test_the_default_folder_follows_the_choice_not_the_recipe(run, tmp_path):
    for tta, name in (("recipe", "test"), ("on", "test-tta"), ("off", "test-no-tta")):
        cfg = EvaluateCfg(run=str(run), tta=tta)
        assert cfg.out_dir == default_out_dir(cfg) == run / "eval" / name
        bl = EvaluateCfg(baseline="pinch", data=str(tmp_path), split="val", tta=tta)
        assert bl.out_dir == tmp_path / "eval" / f"pinch-{name.replace('test', 'val')}"
    assert EvaluateCfg(run=str(run), out=str(tmp_path / "o")).out_dir == tmp_path / "o"


def test_the_choice_of_test_time_augmentation():
    cfg = EvaluateCfg(baseline="geometric", data="d")
    assert (cfg.averaged(True), cfg.averaged(False), cfg.averaged()) == (True, False, False)
    on, off = (EvaluateCfg(baseline="geometric", data="d", tta=t) for t in ("on", "off"))
    assert on.averaged(False) and on.averaged() and not off.averaged(True)
    with pytest.raises(ConfigError, match="tta: expected one of 'recipe', 'on', 'off'"):
        EvaluateCfg(baseline="geometric", data="d", tta=True)


@pytest.mark.parametrize("kw, api, cli", [
    ({}, "run: required, or baseline (geometric or pinch) with data",
     "--run: required, or --baseline (geometric or pinch) with --data"),
    ({"baseline": "geometric"}, "baseline: needs data", "--baseline: needs --data"),
    ({"baseline": "pinch", "data": "d", "run": "RUN"},
     "baseline: give either run or baseline, not both",
     "--baseline: give either --run or --baseline, not both"),
])
def test_errors_name_fields_and_the_cli_names_options(kw, api, cli, run, capsys):
    kw = {k: (str(run) if v == "RUN" else v) for k, v in kw.items()}
    with pytest.raises(ConfigError) as exc:
        EvaluateCfg(**kw)
    assert str(exc.value).startswith(api) and "--" not in str(exc.value)
    argv = ["evaluate", *[w for k, v in kw.items() for w in (f"--{k}", v)]]
    assert main(argv) == 2
    assert cli in capsys.readouterr().err
