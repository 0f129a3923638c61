"""User meshes: loading, checks with clear errors, scaling, cached convex decomposition."""

import json

import numpy as np
import pytest
import trimesh
from shapely.geometry import box
from shapely.ops import unary_union

from vistac.cli import main
from vistac.errors import UserError
from vistac_sim.objects import decomposition, meshes


def _l_mesh(scale=1.0):
    poly = unary_union([box(0, 0, 40, 10), box(0, 0, 10, 30)])
    return trimesh.creation.extrude_polygon(poly, 30).apply_scale(scale)


@pytest.fixture
def bad_meshes(tmp_path):
    files = {}
    files["empty"] = tmp_path / "empty.stl"
    files["empty"].write_bytes(b"")
    files["points"] = tmp_path / "points.ply"
    files["points"].write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n"
                                "0 1 0\n")
    rng = np.random.default_rng(0)
    soup = trimesh.Trimesh(rng.normal(size=(30, 3)), np.arange(30).reshape(10, 3), process=False)
    files["soup"] = tmp_path / "soup.obj"
    soup.export(files["soup"])
    files["nan"] = tmp_path / "nan.obj"
    files["nan"].write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\n"
                            "f 2 3 4\n")
    files["flat"] = tmp_path / "flat.obj"
    files["flat"].write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    files["garbage"] = tmp_path / "garbage.glb"
    files["garbage"].write_bytes(b"this is not a mesh at all" * 10)
    return files


@pytest.mark.parametrize("kind, reason", [
    ("empty", ""), ("points", "no triangles"), ("soup", "not a surface"),
    ("nan", "NaN"), ("flat", "zero volume"), ("garbage", "cannot read"),
])
def test_bad_mesh_error_names_file_and_reason(bad_meshes, kind, reason):
    with pytest.raises(UserError) as err:
        meshes.load_mesh(bad_meshes[kind])
    assert str(bad_meshes[kind]) in str(err.value)
    assert reason in str(err.value)


def test_scaling_ignores_units():
    a = meshes.scale_to_footprint(_l_mesh(1.0), 0.05)  # "millimetres"
    b = meshes.scale_to_footprint(_l_mesh(0.001), 0.05)  # "metres"
    np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-12)
    lo, hi = a.bounds
    assert max(hi[:2] - lo[:2]) == pytest.approx(0.05)
    assert lo[2] == pytest.approx(0.0)


def test_decomposition_is_cached_by_mesh_hash(tmp_path, monkeypatch):
    import coacd

    mesh = meshes.scale_to_footprint(_l_mesh(), 0.05)
    pieces = decomposition.convex_decomposition(mesh, tmp_path)
    assert len(pieces) >= 2 and all(p.is_convex for p in pieces)
    assert sum(p.volume for p in pieces) == pytest.approx(mesh.volume, rel=0.05)
    monkeypatch.setattr(coacd, "run_coacd", lambda *a, **k: pytest.fail("decomposed twice"))
    again = decomposition.convex_decomposition(mesh, tmp_path)
    assert len(again) == len(pieces)


def test_generate_skips_bad_meshes_in_a_folder_and_strict_aborts(tmp_path, bad_meshes,
                                                                 monkeypatch):
    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    folder = bad_meshes["empty"].parent
    _l_mesh().export(folder / "good_l.stl")
    trimesh.creation.box(extents=[30, 20, 40]).export(folder / "good_box.obj")
    out = tmp_path / "ds"
    rc = main(["generate", "--n", "6", "--repeats", "2", "--objects", str(folder), "--out",
               str(out), "--workers", "1", "--no-progress"])
    assert rc == 0
    manifest = json.loads((out / "manifest.json").read_text())
    skipped = {s["path"].split("/")[-1] for s in manifest["skipped_meshes"]}
    assert skipped == {p.name for p in bad_meshes.values()}
    assert {o["family"] for o in manifest["objects"]} == {"mesh"}
    rc = main(["generate", "--n", "6", "--objects", str(folder), "--out", str(tmp_path / "s"),
               "--workers", "1", "--no-progress", "--strict"])
    assert rc == 2
    assert not (tmp_path / "s" / "manifest.json").exists()


def test_example_meshes_generate(tmp_path, monkeypatch):
    from vistac_sim.assets import EXAMPLE_MESHES

    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "ds"
    assert main(["generate", "--n", "4", "--repeats", "2", "--objects", str(EXAMPLE_MESHES),
                 "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["skipped_meshes"] == [] and len(manifest["objects"]) == 2
