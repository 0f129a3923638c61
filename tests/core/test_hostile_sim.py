"""Hostile input to the simulator side (issue 22): scene files built to hurt (alias bombs,
recursion, megabyte values, code tags), damaged state of interrupted and finished `generate`
runs, and odd file names and broken files given to `ingest`.

Each case runs in-process through `vistac.cli.main` and must end in its exit status with exactly
one line on stderr for an error (none for a success), never a traceback. Then a good command
into the same `--out` must work: the command's good run, or (`resume`) the good run with
--resume; a case whose message says to delete the folder (`delete`) is followed by that. As in
`test_bad_input`, a good rerun's outcome depends only on the command and on what the folder
holds, so it runs once per distinct pair.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from bad_input_env import GEN_OK, ING_OK, Case

from vistac.cli import main
from vistac.errors import MAX_MESSAGE
from vistac_sim.generate import shards
from vistac_sim.generate.verify import damaged_png

G = GEN_OK
GP = GEN_OK + " --chunk-size 1"  # the interrupted run of `partial`: two chunks
I = "ingest --recordings {rec} --images {img} --out {out}"  # noqa: E741


BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
    for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "effects: {noise: *i}\n"
SCENES = {
    "bomb.yaml": BOMB,
    "recursive.yaml": "effects: &a {noise: *a}\n",
    "deep.yaml": "effects: " + "[" * 20_000 + "]" * 20_000 + "\n",
    "huge.yaml": "# " + "x" * (2 << 20) + "\n",
    "long_value.yaml": "effects: {noise: '" + "x" * 200_000 + "'}\n",
    "long_key.yaml": "effects:\n  ? " + "k" * 100_000 + "\n  : 1\n",  # an explicit key
    "binary.yaml": b"\xff\xfe\x00\x81garbage\x00",
    "code.yaml": "effects: !!python/object/apply:os.system ['echo pwned']\n",
    "list.yaml": "- effects\n- recording\n",
    "scalar.yaml": "just words\n",
    "tabs.yaml": "effects:\n\tnoise: 0.1\n",
    "effects_number.yaml": "effects: 5\n",
    "preset.yaml": "preset: messy\n",
    "preset_list.yaml": "preset: [lab]\n",
    "overflow.yaml": "effects: {fts3: {hysteresis: 1e400}}\n",
    "exponent.yaml": "effects: {noise: 1e-2, fts3: {hysteresis: 2.5E-2, drift_std: 1.5e-3}}\n",
    "broken.toml": "[effects\nnoise = 0.1\n",
    "scene.json": '{"effects": {"noise": 0.1}}',
    "merge.yaml": "base: &b {noise: 0.1}\neffects: {<<: *b}\n",
}


def _name(file: str) -> str:
    return "scene_" + file.replace(".", "_")


CASES = [
    # ------------------------------------------------------------------ scene files
    Case("scene-alias-bomb", G + " --scene {scene_bomb_yaml}", "expands to"),
    Case("scene-recursive-alias", G + " --scene {scene_recursive_yaml}", "contains it"),
    Case("scene-nested-20000-deep", G + " --scene {scene_deep_yaml}", "nested too deeply"),
    Case("scene-2-MiB-file", G + " --scene {scene_huge_yaml}", "a scene file holds at most"),
    Case("scene-200-kB-value", G + " --scene {scene_long_value_yaml}", "effects.noise"),
    Case("scene-100-kB-key", G + " --scene {scene_long_key_yaml}", "unknown key"),
    Case("scene-binary", G + " --scene {scene_binary_yaml}", "cannot parse"),
    Case("scene-python-tag", G + " --scene {scene_code_yaml}", "cannot parse"),
    Case("scene-top-level-list", G + " --scene {scene_list_yaml}", "top level"),
    Case("scene-top-level-scalar", G + " --scene {scene_scalar_yaml}", "top level"),
    Case("scene-tabs", G + " --scene {scene_tabs_yaml}", "cannot parse"),
    Case("scene-effects-not-a-table", G + " --scene {scene_effects_number_yaml}",
         "expected a table"),
    Case("scene-unknown-preset", G + " --scene {scene_preset_yaml}", "unknown preset"),
    Case("scene-preset-a-list", G + " --scene {scene_preset_list_yaml}", "unknown preset"),
    Case("scene-number-overflows", G + " --scene {scene_overflow_yaml}", "finite"),
    Case("scene-broken-toml", G + " --scene {scene_broken_toml}", "cannot parse"),
    Case("scene-json-suffix", G + " --scene {scene_scene_json}", "scene files are"),
    Case("scene-a-folder", G + " --scene {root}", "no such scene file"),
    Case("scene-exponent-numbers", G + " --scene {scene_exponent_yaml}", "", code=0,
         check="exponents_read_as_numbers"),
    Case("scene-merge-key", G + " --scene {scene_merge_yaml}", "unknown key"),
    # ------------------------------------------------------------------ generate: resources
    Case("gen-repeats-above-range", G + " --repeats 10001", "--repeats"),
    Case("gen-n-above-range", G + " --n 10000001", "--n"),
    # ------------------------------------------------------------------ an interrupted run
    Case("resume-run-json-not-json", GP + " --resume", "run.json: damaged",
         setup="partial_bad_json", good=GP),
    Case("resume-run-json-missing", GP + " --resume", "run.json: missing",
         setup="partial_no_state", good=GP),
    Case("resume-run-json-a-list", GP + " --resume", "run.json: damaged",
         setup="partial_list_state", good=GP),
    Case("resume-run-json-binary", GP + " --resume", "run.json: damaged",
         setup="partial_binary_state", good=GP),
    Case("resume-other-settings", GP + " --resume --seed 7", "other settings", setup="partial",
         good=GP + " --resume"),
    Case("rerun-without-resume", GP, "add --resume", setup="partial", good=GP + " --resume"),
    Case("resume-image-deleted", GP + " --resume", "", code=0, setup="partial_image_deleted",
         check="images_whole"),
    Case("resume-image-truncated", GP + " --resume", "", code=0,
         setup="partial_image_truncated", check="images_whole"),
    Case("resume-image-zeroed", GP + " --resume", "", code=0, setup="partial_image_zeroed",
         check="images_whole"),
    Case("resume-shard-truncated", GP + " --resume", "", code=0, setup="partial_shard_truncated",
         check="images_whole"),
    Case("rerun-after-damaged-state", GP, "", code=0, setup="partial_bad_json",
         check="images_whole"),
    Case("rerun-after-damaged-state-mid-merge", GP, "", code=0,
         setup="partial_bad_json_mid_merge", check="images_whole"),
    Case("resume-killed-mid-merge", GP + " --resume", "", code=0, setup="partial_mid_merge",
         check="images_whole"),
    # ------------------------------------------------------------------ a finished dataset
    Case("resume-finished", G + " --resume", "", code=0, setup="finished",
         check="nothing_done"),
    Case("resume-finished-other-seed", G + " --resume --seed 9", "other settings",
         setup="finished", untouched=True),
    Case("rerun-finished", G, "already holds a complete dataset", setup="finished",
         untouched=True),
    Case("resume-finished-image-deleted", G + " --resume", "000001.png: missing",
         setup="finished_image_deleted", delete=True),
    Case("resume-finished-image-truncated", G + " --resume", "000000.png: truncated",
         setup="finished_image_truncated", delete=True),
    Case("resume-finished-manifest-damaged", G + " --resume", "manifest.json: damaged",
         setup="finished_manifest_damaged", delete=True),
    Case("resume-finished-manifest-incomplete", G + " --resume", "not the manifest",
         setup="finished_manifest_incomplete", delete=True),
    Case("resume-finished-table-truncated", G + " --resume", "does not read back",
         setup="finished_table_truncated", delete=True),
    # ------------------------------------------------------------------ ingest
    Case("ing-odd-name-keeps-ids", I.replace("{rec}", "{odd_rec}").replace("{img}", "{odd_img}"),
         "", code=0, check="ids_kept"),
    Case("ing-arabic-digits-name", I.replace("{rec}", "{arabic_rec}")
         .replace("{img}", "{arabic_img}"), "", code=0, check="ids_kept"),
    Case("ing-same-number-twice", I.replace("{rec}", "{twice_rec}")
         .replace("{img}", "{twice_img}"), "same configuration id"),
    Case("ing-recording-binary", I.replace("{rec}", "{binary_rec}"), "000003.csv"),
    Case("ing-recording-empty", I.replace("{rec}", "{empty_rec}"), "000003.csv"),
    Case("ing-recording-10-MB-cell", I.replace("{rec}", "{long_rec}"), "000003.csv"),
    Case("ing-image-not-an-image", I.replace("{img}", "{fake_img}"), "000002.png"),
]


# --------------------------------------------------------------------- shared data
@pytest.fixture(scope="module")
def hostile(env, tmp_path_factory, monkeypatch_module):
    root = tmp_path_factory.mktemp("hostile_sim")
    paths = dict(env["paths"], root=str(root))
    for file, text in SCENES.items():
        f = root / file
        f.write_bytes(text if isinstance(text, bytes) else text.encode())
        paths[_name(file)] = str(f)
    paths.update(_ingest_sources(Path(env["paths"]["data"]), root / "ingest"))
    partial = root / "partial"  # a run interrupted after committing both chunks
    monkeypatch_module.setattr(shards, "finalize", _interrupt)
    assert main(GP.format(out=partial).split()) == 130  # interrupted before its merge
    monkeypatch_module.undo()
    assert len(shards.finished_chunks(partial)) == 2
    return {"paths": paths, "partial": partial, "finished": Path(env["paths"]["data2"]),
            "reruns": {}}


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def _ingest_sources(data: Path, root: Path) -> dict[str, str]:
    """Folders of recordings and images (copies of the shared dataset's), each spoilt one way."""
    rec, img = data / "recordings", data / "images"
    out = {}

    def variant(name: str, renames: dict[str, str] | None = None) -> tuple[Path, Path]:
        r, i = root / f"{name}_rec", root / f"{name}_img"
        shutil.copytree(rec, r)
        shutil.copytree(img, i)
        for old, new in (renames or {}).items():
            (r / f"{old}.csv").rename(r / f"{new}.csv")
            (i / f"{old}.png").rename(i / f"{new}.png")
        out[f"{name}_rec"], out[f"{name}_img"] = str(r), str(i)
        return r, i

    variant("odd", {"000005": "grasp of Tuesday"})
    variant("arabic", {"000005": "\u0661\u0662"})  # "١٢": digits, but not ASCII ones
    r, i = variant("twice")
    shutil.copy(r / "000004.csv", r / "04.csv")
    shutil.copy(i / "000004.png", i / "04.png")
    r, _ = variant("binary")
    (r / "000003.csv").write_bytes(b"\x00\xff\x81" * 1000)
    r, _ = variant("empty")
    (r / "000003.csv").write_bytes(b"")
    r, _ = variant("long")
    lines = (r / "000003.csv").read_text().splitlines()
    cells = lines[5].split(",")
    cells[19] = "9" * 10_000_000
    lines[5] = ",".join(cells)
    (r / "000003.csv").write_text("\n".join(lines) + "\n")
    _, i = variant("fake")
    (i / "000002.png").write_text("not an image")
    return out


# --------------------------------------------------------------------- states to start from
def partial(hostile, out: Path) -> None:
    shutil.copytree(hostile["partial"], out)


def partial_bad_json(hostile, out: Path) -> None:
    partial(hostile, out)
    (out / ".partial" / "run.json").write_text('{"config": {"n": 2,')


def partial_mid_merge(hostile, out: Path) -> None:
    """Killed in its merge: a half-written table and a temporary of a dead process."""
    partial(hostile, out)
    (out / "configs.parquet").write_bytes(b"PAR1 half")
    (out / ".presses.parquet.999999999.tmp").write_bytes(b"half")


def partial_bad_json_mid_merge(hostile, out: Path) -> None:
    partial_mid_merge(hostile, out)
    (out / ".partial" / "run.json").write_text("{")


def partial_no_state(hostile, out: Path) -> None:
    partial(hostile, out)
    (out / ".partial" / "run.json").unlink()


def partial_list_state(hostile, out: Path) -> None:
    partial(hostile, out)
    (out / ".partial" / "run.json").write_text("[]")


def partial_binary_state(hostile, out: Path) -> None:
    partial(hostile, out)
    (out / ".partial" / "run.json").write_bytes(b"\xff\xfe\x00garbage")


def partial_image_deleted(hostile, out: Path) -> None:
    partial(hostile, out)
    (out / "images" / "000001.png").unlink()


def _truncate(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[:int(len(data) * keep)])


def partial_image_truncated(hostile, out: Path) -> None:
    partial(hostile, out)
    _truncate(out / "images" / "000000.png")


def partial_image_zeroed(hostile, out: Path) -> None:
    partial(hostile, out)
    path = out / "images" / "000001.png"
    path.write_bytes(bytes(path.stat().st_size))  # a crash of the machine: zeros, right size


def partial_shard_truncated(hostile, out: Path) -> None:
    partial(hostile, out)
    _truncate(shards.shard_paths(out, 0)[1])


def finished(hostile, out: Path) -> None:
    shutil.copytree(hostile["finished"], out)


def finished_image_deleted(hostile, out: Path) -> None:
    finished(hostile, out)
    (out / "images" / "000001.png").unlink()


def finished_image_truncated(hostile, out: Path) -> None:
    finished(hostile, out)
    _truncate(out / "images" / "000000.png", 0.9)


def finished_manifest_damaged(hostile, out: Path) -> None:
    finished(hostile, out)
    _truncate(out / "manifest.json")


def finished_manifest_incomplete(hostile, out: Path) -> None:
    finished(hostile, out)
    text = (out / "manifest.json").read_text()
    (out / "manifest.json").write_text(text.replace('"complete": true', '"complete": false'))


def finished_table_truncated(hostile, out: Path) -> None:
    finished(hostile, out)
    _truncate(out / "configs.parquet")


# --------------------------------------------------------------------- checks after success
def exponents_read_as_numbers(out: Path, stdout: str) -> None:
    import json

    effects = json.loads((out / "manifest.json").read_text())["config"]["effects"]
    assert effects["noise"] == 0.01
    assert effects["fts3"]["hysteresis"] == 0.025 and effects["fts3"]["drift_std"] == 0.0015


def images_whole(out: Path, stdout: str) -> None:
    images = sorted((out / "images").glob("*.png"))
    assert [p.name for p in images] == ["000000.png", "000001.png"]
    assert all(damaged_png(p) is None for p in images)
    assert (out / "manifest.json").exists()


def nothing_done(out: Path, stdout: str) -> None:
    assert stdout.strip().startswith("nothing to do:"), stdout


def ids_kept(out: Path, stdout: str) -> None:
    configs = pq.read_table(out / "configs.parquet").to_pandas()
    by_name = dict(zip(configs["recording"], configs["config_id"], strict=True))
    for name, cid in by_name.items():
        stem = Path(name).stem
        if stem.isascii() and stem.isdigit():
            assert cid == int(stem), (name, cid)  # a number name keeps its number
        else:
            assert cid == 8, (name, cid)  # the odd name follows the largest number (7)


# ------------------------------------------------------------------------------- the table
def test_the_table_has_enough_distinct_cases():
    assert len(CASES) >= 30
    assert len({c.id for c in CASES}) == len(CASES)
    assert {c.argv.split()[0] for c in CASES} == {"generate", "ingest"}


def _state(out: Path) -> tuple:
    if not out.exists():
        return ("absent",)
    return tuple(sorted((str(p.relative_to(out)), p.stat().st_size if p.is_file() else -1)
                        for p in out.rglob("*")))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_sim(case: Case, hostile, capsys):
    out = Path(hostile["paths"]["root"]) / "cases" / case.id
    out.parent.mkdir(exist_ok=True)
    if case.setup:
        globals()[case.setup](hostile, out)
    before = _state(out)
    rc = main(case.argv.format(out=out, **hostile["paths"]).split())
    captured = capsys.readouterr()
    assert rc == case.code, captured.err[-2000:]
    assert "Traceback" not in captured.err + captured.out
    if case.code == 2:
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1, captured.err[:2000]
        assert lines[0].startswith("vistac"), lines[0]
        assert case.needle in lines[0], lines[0]
        assert len(lines[0]) < MAX_MESSAGE + 100, len(lines[0])
    else:
        assert captured.err.strip() == "", captured.err[:2000]
        globals()[case.check](out, captured.out)
        return
    if case.untouched:
        assert _state(out) == before
        return
    if case.delete:
        assert "delete" in captured.err
        shutil.rmtree(out)
    command = case.argv.split()[0]
    good = case.good or {"generate": G, "ingest": ING_OK}[command]
    key = (good, case.setup if not case.delete else None, _state(out))
    if key not in hostile["reruns"]:
        argv = good.format(out=out, **hostile["paths"]).split()
        hostile["reruns"][key] = main(argv)
        capsys.readouterr()
    assert hostile["reruns"][key] == 0, f"good rerun failed after {case.id}"
