"""The Python API (`vistac.api`): light to import, the same bytes and errors as the CLI, quiet.

The CLI is a thin layer over these functions, so each test holds the API against the command
that wraps it: the same dataset bytes for the same seed, the same config from a preset or scene
file, the same one-line error, and nothing on stdout from the library.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import vistac
from vistac.cli import main
from vistac.config import ConfigError
from vistac.errors import UserError
from vistac_sim.objects.config import ObjectsCfg

ROOT = Path(vistac.__file__).resolve().parent.parent
TINY = dict(n=6, seed=3, repeats=2, chunk_size=3)


def test_import_vistac_and_its_api_names_load_neither_mujoco_nor_torch():
    code = ("import sys, vistac\n"
            "names = [vistac.generate, vistac.open_dataset, vistac.train, vistac.evaluate,\n"
            "         vistac.tune, vistac.ingest, vistac.Dataset, vistac.Run, vistac.UserError]\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    loaded = set(out.stdout.split())
    assert "vistac" in loaded and not {"mujoco", "torch", "pandas"} & loaded


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        vistac.nonsense  # noqa: B018


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "manifest.json"}


def _manifest(root: Path) -> dict:
    m = json.loads((root / "manifest.json").read_text())
    m.pop("wall_time_s")
    return m


def test_generate_through_the_api_writes_the_cli_bytes_and_nothing_on_stdout(tmp_path,
                                                                             capsys):
    ds = vistac.generate(vistac.GenerateCfg.from_preset("clean", noise=0.05, **TINY,
                                                        objects=ObjectsCfg(n_objects=3)),
                         tmp_path / "api", workers=1)
    assert capsys.readouterr().out == ""  # the library prints nothing; the CLI prints
    argv = ["generate", "--out", str(tmp_path / "cli"), "--noise", "0.05", "--n", "6",
            "--seed", "3", "--repeats", "2", "--chunk-size", "3", "--n-objects", "3",
            "--workers", "1", "--no-progress"]
    assert main(argv) == 0
    assert "wrote" in capsys.readouterr().out
    api, cli = _files(tmp_path / "api"), _files(tmp_path / "cli")
    assert api.keys() == cli.keys() and len([k for k in api if k.endswith(".png")]) == 6
    assert [k for k in api if api[k] != cli[k]] == []
    assert _manifest(tmp_path / "api") == _manifest(tmp_path / "cli")

    # the handle reads what was written
    assert isinstance(ds, vistac.Dataset) and len(ds) == 6
    assert ds.manifest["seed"] == 3 and ds.manifest["config"]["effects"]["noise"] == 0.05
    assert len(ds.presses) == 12 and set(ds.presses["config_id"]) == set(ds.config_ids)
    first = ds.config_ids[0]
    img = ds.image(first)
    assert img.shape == (227, 227, 3) and img.dtype.name == "uint8"
    # the index finger is drawn green, the thumb red: both colours are in the image
    green = (img[..., 1] > 150) & (img[..., 0] < 80)
    red = (img[..., 0] > 150) & (img[..., 1] < 80)
    assert green.sum() > 20 and red.sum() > 20
    reopened = vistac.open_dataset(tmp_path / "cli")
    assert reopened.configs.equals(ds.configs)
    with pytest.raises(UserError, match="no configuration 999"):
        ds.image(999)


def _cli_cfg(argv: list[str]):
    from vistac.cli import build_parser
    from vistac_sim.generate.command import generate_cfg_from_args

    argv = ["generate", "--out", "unused", *argv]
    return generate_cfg_from_args(build_parser(argv).parse_args(argv))


def test_presets_and_scene_files_are_constructors_equal_to_the_cli_options(tmp_path):
    lab = vistac.GenerateCfg.from_preset("lab", noise=0.05, n=3, recordings=True)
    assert lab.to_dict() == _cli_cfg(["--preset", "lab", "--noise", "0.05", "--n", "3",
                                      "--recordings"]).to_dict()
    assert lab.effects.fts3 is not None and lab.recording.write
    assert lab.to_dict() != vistac.GenerateCfg.from_preset("lab", n=3).to_dict()

    scene = tmp_path / "scene.yaml"
    scene.write_text("preset: harsh\neffects:\n  fts3: {hysteresis: 0.03}\n  lighting: false\n")
    from_file = vistac.GenerateCfg.from_file(scene, n=5)
    assert from_file.to_dict() == _cli_cfg(["--scene", str(scene), "--n", "5"]).to_dict()
    assert from_file.effects.fts3.hysteresis == 0.03 and from_file.effects.lighting is None
    assert from_file.effects.camera_jitter is not None  # kept from the file's preset


def test_config_errors_are_user_errors_with_the_message_the_cli_prints(tmp_path, capsys):
    with pytest.raises(UserError, match="unknown preset 'nope'"):
        vistac.GenerateCfg.from_preset("nope")
    with pytest.raises(UserError, match=r"^n: must be >= 1, got 0$"):
        vistac.GenerateCfg(n=0)
    missing = tmp_path / "missing"
    with pytest.raises(UserError) as exc:
        vistac.train(vistac.TrainCfg(epochs=1), data=missing, out=tmp_path / "run")
    assert main(["train", "--data", str(missing), "--out", str(tmp_path / "run2")]) == 2
    assert capsys.readouterr().err.strip() == f"vistac train: error: {exc.value}"
    assert str(exc.value).startswith(f"--data {missing}")
    with pytest.raises(UserError, match="not a dataset directory"):
        vistac.open_dataset(missing)
    with pytest.raises(UserError, match="not a run folder"):
        vistac.evaluate(tmp_path)
    with pytest.raises(ConfigError, match=r"^split: must be one of"):  # a field, not --split
        vistac.evaluate(tmp_path, split="holdout")


@pytest.fixture(scope="module")
def tiny_learn_data(tmp_path_factory):
    from learn_fixtures import make_dataset

    return make_dataset(tmp_path_factory.mktemp("api") / "ds", n=8, repeats=3, size=64)


def test_train_and_evaluate_through_the_api(tiny_learn_data, tmp_path, capsys):
    cfg = vistac.TrainCfg.from_protocol("study", model="smallconv", epochs=2, n_rotations=2,
                                        batch_size=4, lr=1e-3, device="cpu",
                                        cache_dir=str(tmp_path / "cache"))
    run = vistac.train(cfg, data=tiny_learn_data, out=tmp_path / "run")
    assert isinstance(run, vistac.Run) and run.path == tmp_path / "run"
    assert run.best_epoch in (1, 2) and len(run.history) == 2
    assert run.config["train"]["data"] == str(tiny_learn_data)
    ev = vistac.evaluate(run, no_plots=True)
    assert capsys.readouterr().out == ""
    saved = json.loads((tmp_path / "run" / "eval" / "test" / "metrics.json").read_text())
    assert ev.path == tmp_path / "run" / "eval" / "test" and ev.metrics == saved["metrics"]
    assert "% in cone" in ev.table and ev.table == saved["table"]
    # a run folder works as well as the handle, and Run.open reads the same selection back
    again = vistac.evaluate(str(tmp_path / "run"), split="val", no_plots=True)
    assert again.path.name == "val" and again.metrics.keys() == {"index"}
    opened = vistac.Run.open(tmp_path / "run")
    assert (opened.best_epoch, opened.objective) == pytest.approx((run.best_epoch,
                                                                   run.objective))


def test_ingest_through_the_api_writes_the_cli_bytes(tmp_path, capsys):
    """Recordings written by the simulator, read back through `vistac.ingest` and `vistac
    ingest`: the same tables; the API prints nothing."""
    cfg = vistac.GenerateCfg.from_preset("lab", recordings=True, n=4, seed=2, repeats=3,
                                         objects=ObjectsCfg(n_objects=2))
    sim = vistac.generate(cfg, tmp_path / "sim", workers=1)
    src = vistac.IngestSources(recordings=sim.path / "recordings", images=sim.path / "images")
    api = vistac.ingest(src, tmp_path / "api")
    assert capsys.readouterr().out == ""
    assert main(["ingest", "--recordings", str(sim.path / "recordings"), "--images",
                 str(sim.path / "images"), "--out", str(tmp_path / "cli")]) == 0
    assert "wrote" in capsys.readouterr().out
    for name in ("configs.parquet", "presses.parquet"):
        assert (api.path / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert api.manifest["generator"] == "vistac ingest" and len(api) == len(sim)
    with pytest.raises(UserError, match="not an empty folder"):
        vistac.ingest(src, tmp_path / "api")
