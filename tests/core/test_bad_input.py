"""Bad input to every command: exit status 2, one line naming the option, no traceback, and a
good rerun into the same folder that works (issue 11).

Every case runs in-process through `vistac.cli.main`. After the bad command, the good command
of the same sub-command is run into the same `--out` folder. A good rerun's outcome depends only
on the command and on what the folder holds, so it is run once per distinct (command, folder
contents) and remembered: most bad commands are refused before they touch the folder, and the
one good run into an absent folder stands for all of them; a case that leaves something behind
(a diverged run, a run stopped before its first shard) gets its own rerun. Demo cases check that
nothing was created instead (a demo run takes minutes).

The shared data: one tiny dataset made by `vistac generate` (8 configurations of 64 px, with
recordings, which `ingest` cases read back), a second one (a "different dataset") and a
one-epoch run on the first.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from bad_input_env import EVAL_OK, GEN_OK, ING_OK, TRAIN_OK, Case

from vistac.cli import main

GOOD = {"generate": GEN_OK, "ingest": ING_OK, "train": TRAIN_OK, "evaluate": EVAL_OK,
        "models": "models --out-features 2", "demo": None}


G = "generate --out {out} --n 4 --image-size 32 --workers 1 --no-progress"
I = "ingest --recordings {rec} --images {img} --out {out}"  # noqa: E741
T = "train --data {data} --out {out} --epochs 1 --size 16 --quiet"
E = "evaluate --run {run} --no-plots --out {out}"
D = "demo --out {out}"

CASES = [
    # ------------------------------------------------------------------ generate
    Case("gen-image-size-0", G + " --image-size 0", "--image-size"),
    Case("gen-image-size-7", G + " --image-size 7", "--image-size"),
    Case("gen-image-size-huge", G + " --image-size 5000", "--image-size"),
    Case("gen-image-size-tip-too-small", G + " --image-size 20", "--image-size"),
    Case("gen-image-size-text", G + " --image-size big", "--image-size"),
    Case("gen-chunk-size-0", G + " --chunk-size 0", "--chunk-size"),
    Case("gen-n-objects-0", G + " --n-objects 0", "--n-objects"),
    Case("gen-n-0", G + " --n 0", "--n"),
    Case("gen-n-text", G + " --n x", "--n"),
    Case("gen-repeats-0", G + " --repeats 0", "--repeats"),
    Case("gen-seed-negative", G + " --seed -1", "--seed"),
    Case("gen-seed-2^32", G + " --seed 4294967296", "--seed"),
    Case("gen-footprint-zero", G + " --footprint 0 0", "--footprint"),
    Case("gen-footprint-negative", G + " --footprint -0.01 0.05", "--footprint"),
    Case("gen-footprint-reversed", G + " --footprint 0.06 0.04", "--footprint"),
    Case("gen-footprint-nan", G + " --footprint nan 0.05", "--footprint"),
    Case("gen-footprint-inf", G + " --footprint 0.04 inf", "--footprint"),
    Case("gen-footprint-beyond-view", G + " --footprint 0.04 0.5", "--footprint"),
    Case("gen-footprint-one-value", G + " --footprint 0.04", "--footprint"),
    Case("gen-workers-negative", G + " --workers -2", "--workers"),
    Case("gen-split-nan", G + " --split nan 0.5 0.5", "--split"),
    Case("gen-split-sum", G + " --split 0.5 0.5 0.5", "--split"),
    Case("gen-split-negative", G + " --split -0.1 0.6 0.5", "--split"),
    Case("gen-split-above-one", G + " --split 1.2 -0.1 -0.1", "--split"),
    Case("gen-split-two-values", G + " --split 0.5 0.5", "--split"),
    Case("gen-split-by", G + " --split-by shelf", "--split-by"),
    Case("gen-noise-inf", G + " --noise inf", "--noise"),
    Case("gen-noise-nan", G + " --noise nan", "--noise"),
    Case("gen-noise-negative", G + " --noise -0.1", "--noise"),
    Case("gen-friction-negative", G + " --friction -1", "--friction"),
    Case("gen-friction-nan", G + " --friction nan", "--friction"),
    Case("gen-approach-spread", G + " --approach-spread 95", "--approach-spread"),
    Case("gen-family", G + " --families blob", "--families"),
    Case("gen-objects-missing", G + " --objects {missing}", "--objects"),
    Case("gen-preset", G + " --preset messy", "--preset"),
    Case("gen-scene-missing", G + " --scene {missing}.yaml", "missing.yaml"),
    Case("gen-scene-hold-negative", G + " --scene {scene_hold}", "recording.hold_s"),
    Case("gen-scene-rate-zero", G + " --scene {scene_rate}", "recording.rate_hz"),
    Case("gen-scene-fts3-nan", G + " --scene {scene_nan}", "effects.fts3.hysteresis"),
    Case("gen-scene-shadow-map", G + " --scene {scene_shadow}", "effects.shadows.map_size"),
    Case("gen-textures-missing", G + " --preset photo --textures {missing}", "--textures"),
    Case("gen-textures-unused", G + " --textures {missing}", "--textures"),
    Case("gen-scene-jitter", G + " --scene {scene_jitter}", "recording.timing_jitter"),
    Case("gen-scene-unknown-key", G + " --scene {scene_unknown}", "optics"),
    Case("gen-unknown-option", G + " --bogus", "--bogus"),
    Case("gen-engine", G + " --engine spark", "--engine"),
    Case("gen-max-concurrent-0", G + " --engine ray --max-concurrent 0", "--max-concurrent"),
    Case("gen-ray-writes-local", G + " --ray-writes workers", "--ray-writes"),
    Case("gen-out-is-file", G.replace("{out}", "{file}"), "--out"),
    Case("gen-out-under-file", G.replace("{out}", "{file}/d"), "--out"),
    Case("gen-resume-nothing", G + " --resume", "nothing to resume"),
    Case("gen-no-out", "generate --n 2", "--out"),
    Case("gen-killed-before-first-shard", G, "", code=0, setup="stale_partial"),
    # ------------------------------------------------------------------ ingest
    Case("ing-threshold-nan", I + " --threshold nan", "--threshold"),
    Case("ing-threshold-negative", I + " --threshold -1", "--threshold"),
    Case("ing-min-samples-0", I + " --min-samples 0", "--min-samples"),
    Case("ing-saturation-0", I + " --saturation 0", "--saturation"),
    Case("ing-min-force-inf", I + " --min-force inf", "--min-force"),
    Case("ing-columns-negative", I + " --columns -1 15 16 17 18 19", "--columns"),
    Case("ing-columns-short", I + " --columns 14 15", "--columns"),
    Case("ing-image-size-8", I + " --image-size 8", "--image-size"),
    Case("ing-seed-negative", I + " --seed -1", "--seed"),
    Case("ing-split-sum", I + " --split 0.6 0.3 0.3", "--split"),
    Case("ing-split-by-object", I + " --split-by object", "--split-by"),
    Case("ing-unit", I + " --unit kN", "--unit"),
    Case("ing-no-source", "ingest --images {img} --out {out}", "--recordings"),
    Case("ing-images-missing", "ingest --recordings {rec} --images {missing} --out {out}",
         "missing"),
    Case("ing-mixed-sizes", "ingest --recordings {rec} --images {mixed} --out {out}",
         "000001.png"),
    Case("ing-out-is-file", I.replace("{out}", "{file}"), "--out"),
    # ------------------------------------------------------------------ train
    Case("train-model", T + " --model resnet-huge", "--model"),
    Case("train-select", T + " --select accuracy", "--select"),
    Case("train-lr-nan", T + " --lr nan", "--lr"),
    Case("train-lr-inf", T + " --lr inf", "--lr"),
    Case("train-lr-zero", T + " --lr 0", "--lr"),
    Case("train-lr-negative", T + " --lr -0.1", "--lr"),
    Case("train-epochs-0", T + " --epochs 0", "--epochs"),
    Case("train-batch-size-0", T + " --batch-size 0", "--batch-size"),
    Case("train-weight-decay", T + " --weight-decay -1", "--weight-decay"),
    Case("train-seed-negative", T + " --seed -5", "--seed"),
    Case("train-n-rotations-0", T + " --n-rotations 0", "--n-rotations"),
    Case("train-rotation-step-0", T + " --rotation-step 0", "--rotation-step"),
    Case("train-jitter-nan", T + " --jitter nan", "--jitter"),
    Case("train-margin", T + " --margin 2", "--margin"),
    Case("train-appearance", T + " --appearance 1.5", "--appearance"),
    Case("train-appearance-axes", T + " --appearance-axes 0", "--appearance-axes"),
    Case("train-size-8", T + " --size 8", "--size"),
    Case("train-size-too-small-for-model", T + " --model smallconv --variant edge-index "
         "--finger index --size 32", "--size"),
    Case("train-fraction-0", T + " --train-fraction 0", "--train-fraction"),
    Case("train-fraction-nan", T + " --train-fraction nan", "--train-fraction"),
    Case("train-val-split-same", T + " --val-split train", "--val-split"),
    Case("train-rotations-tip", T + " --rotations fixed", "--rotations"),
    Case("train-freeze-no-init", T + " --freeze features", "--freeze"),
    Case("train-init-missing", T + " --init {missing}", "--init"),
    Case("train-variant", T + " --variant sketch", "--variant"),
    Case("train-device", T + " --device tpu", "--device"),
    Case("train-protocol", T + " --protocol thesis", "--protocol"),
    Case("train-optimizer", T + " --optimizer sgd", "--optimizer"),
    Case("train-target", T + " --target median", "--target"),
    Case("train-train-split", T + " --train-split dev", "--train-split"),
    Case("train-checkpoint-every", T + " --checkpoint-every -1", "--checkpoint-every"),
    Case("train-data-missing", T.replace("{data}", "{missing}"), "--data"),
    Case("train-data-interrupted", T.replace("{data}", "{partial}"), "--data"),
    Case("train-out-is-file", T.replace("{out}", "{file}"), "--out"),
    Case("train-out-not-a-run", T, "--out", setup="foreign_folder", untouched=True),
    Case("gen-out-not-empty", G, "not empty", setup="foreign_folder", untouched=True),
    Case("ing-out-not-empty", I, "--out", setup="foreign_folder", untouched=True),
    Case("train-cache-dir-file", T + " --cache-dir {file}", "--cache-dir"),
    Case("train-resume-nothing", T + " --resume", "no run to resume"),
    Case("train-diverges", T + " --lr 1e6 --schedule constant", "--lr"),
    Case("train-diverges-after-a-checkpoint", T.replace("--epochs 1", "--epochs 2")
         + " --lr 1e6 --schedule constant --checkpoint-every 1 --batch-size 3", "epoch 1"),
    Case("train-resume-other-data", T.replace("{data}", "{data2}") + " --resume", "--data",
         setup="copy_run", good=TRAIN_OK + " --resume"),
    Case("train-resume-other-settings", T + " --resume --batch-size 3", "batch_size",
         setup="copy_run", good=TRAIN_OK + " --resume"),
    Case("train-resume-more-epochs", T.replace("--epochs 1", "--epochs 3") + " --resume",
         "--epochs", setup="copy_run", good=TRAIN_OK + " --resume"),
    Case("train-killed-before-checkpoint", T, "", code=0, setup="run_without_checkpoint"),
    # ------------------------------------------------------------------ evaluate
    Case("eval-split", E + " --split holdout", "--split"),
    Case("eval-rotations", E + " --rotations spin", "--rotations"),
    Case("eval-device", E + " --device tpu", "--device"),
    Case("eval-n-rotations-0", E + " --n-rotations 0", "--n-rotations"),
    Case("eval-n-rotations-huge", E + " --n-rotations 1000", "--n-rotations"),
    Case("eval-run-missing", E.replace("{run}", "{missing}"), "--run"),
    Case("eval-no-run", "evaluate --no-plots --out {out}", "--run"),
    Case("eval-run-and-baseline", E + " --baseline geometric --data {data}", "--baseline"),
    Case("eval-baseline-no-data", "evaluate --baseline geometric --out {out}", "--baseline"),
    Case("eval-baseline-name", "evaluate --baseline oracle --data {data} --out {out}",
         "--baseline"),
    Case("eval-data-missing", E + " --data {missing}", "--data"),
    Case("eval-other-dataset", E + " --data {data2}", "--data"),
    Case("eval-checkpoint", E + " --checkpoint first", "--checkpoint"),
    Case("eval-finger", E + " --finger pinky", "--finger"),
    Case("eval-out-is-file", E.replace("{out}", "{file}"), "--out"),
    Case("eval-max-missing-pct", E + " --max-missing-pct 101", "--max-missing-pct"),
    Case("train-max-missing-pct", T + " --max-missing-pct -1", "--max-missing-pct"),
    Case("train-aux-weight", T + " --aux-weight -1", "--aux-weight"),
    Case("train-loader-workers", T + " --loader-workers -1", "--loader-workers"),
    Case("eval-tta", E + " --tta both", "--tta"),
    # ------------------------------------------------------------------ demo
    Case("demo-model", D + " --model nope", "--model"),
    Case("demo-n-1", D + " --n 1", "--n"),
    Case("demo-epochs-0", D + " --epochs 0", "--epochs"),
    Case("demo-seed-negative", D + " --seed -1", "--seed"),
    Case("demo-workers-negative", D + " --workers -1", "--workers"),
    Case("demo-out-is-file", D.replace("{out}", "{file}"), "--out"),
    # ------------------------------------------------------------------ models, the CLI
    Case("models-in-channels-0", "models --in-channels 0", "--in-channels"),
    Case("models-out-features-negative", "models --out-features -1", "--out-features"),
    Case("models-out-features-text", "models --out-features two", "--out-features"),
    Case("cli-no-command", "", "COMMAND"),
    Case("cli-unknown-command", "simulate --n 3", "simulate"),
]


def _argv(template: str, paths: dict, out: Path) -> list[str]:
    return template.format(out=out, **paths).split()


def _state(out: Path) -> tuple:
    """What a folder holds (relative paths and sizes), or ("absent",)."""
    if not out.exists():
        return ("absent",)
    return tuple(sorted((str(p.relative_to(out)), p.stat().st_size if p.is_file() else -1)
                        for p in out.rglob("*")))


# --------------------------------------------------------------------- states to start from
def stale_partial(env, out: Path) -> None:
    """A generate run killed before its first shard: `.partial/` with run.json, no shard."""
    (out / ".partial" / "shards").mkdir(parents=True)
    (out / ".partial" / "run.json").write_text('{"config": {"n": 99}}')
    (out / "images").mkdir()
    (out / "images" / ".000000.png.999999999.tmp").write_bytes(b"half")


def foreign_folder(env, out: Path) -> None:
    """A folder with somebody's files."""
    out.mkdir()
    (out / "notes.txt").write_text("mine")


def copy_run(env, out: Path) -> None:
    """A finished run (1 epoch, as TRAIN_OK) to resume."""
    shutil.copytree(env["paths"]["run"], out)


def run_without_checkpoint(env, out: Path) -> None:
    """A train run killed after writing its config, before its first checkpoint."""
    shutil.copytree(env["paths"]["run"], out)
    shutil.rmtree(out / "checkpoints")
    (out / "checkpoints").mkdir()
    (out / "checkpoints" / ".last.pt.999999999.tmp").write_bytes(b"half")


# ------------------------------------------------------------------------------- the table
def test_every_bounded_or_chosen_option_has_a_bad_case():
    """Each option of generate, ingest, train and evaluate that takes a number or one of a set
    of choices is given a bad value by at least one case (so a new option needs its case)."""
    import argparse

    from vistac.cli import build_parser

    missing = []
    for command in ("generate", "ingest", "train", "evaluate"):
        actions = next(a for a in build_parser([command])._actions
                       if isinstance(a, argparse._SubParsersAction)).choices[command]._actions
        used = {w for c in CASES if c.argv.split()[:1] == [command]
                for w in c.argv.split() if w.startswith("--")}
        missing += [f"{command} {a.option_strings[0]}" for a in actions if a.option_strings
                    and (a.type in (int, float) or a.choices) and a.option_strings[0] not in used]
    assert missing == []
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(case: Case, env, capsys):
    out = env["root"] / "cases" / case.id
    out.parent.mkdir(exist_ok=True)
    if case.setup:
        globals()[case.setup](env, out)
    before = _state(out)
    rc = main(_argv(case.argv, env["paths"], out))
    captured = capsys.readouterr()
    err = captured.err + captured.out
    assert rc == case.code, err
    assert "Traceback" not in err
    if case.code == 2:
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1, captured.err
        assert case.needle in lines[0], lines[0]
        assert lines[0].startswith("vistac"), lines[0]
    if case.untouched:
        assert _state(out) == before
        return
    if case.code == 0:  # a rerun into a folder a killed run left: the command was the rerun
        assert not list(out.rglob(".*.tmp")), "a killed run's temporary was left"
        return
    command = case.argv.split()[0] if case.argv else ""
    if command == "demo":  # refused before it made anything
        assert not out.exists()
        return
    good = case.good or GOOD.get(command) or GOOD["models"]
    key = (good, case.setup, _state(out))
    if key not in env["reruns"]:
        env["reruns"][key] = main(_argv(good, env["paths"], out))
        capsys.readouterr()
        if "{out}" in good:
            assert out.exists() and not list(out.rglob(".*.tmp")), \
                "a temporary file outlived a clean exit"
    assert env["reruns"][key] == 0, f"good rerun failed after {case.id}"
