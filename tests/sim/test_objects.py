"""User meshes: loading, checks with clear errors, scaling, cached convex decomposition."""

import json

import numpy as np
import pytest
import shapely
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
    (tmp_path / ".killed.npz.999999999.tmp").write_bytes(b"half")  # a killed writer's
    pieces = decomposition.convex_decomposition(mesh, tmp_path)
    assert len(pieces) >= 2 and all(p.is_convex for p in pieces)
    assert [p.suffix for p in tmp_path.iterdir()] == [".npz"]  # no temporary outlives a write
    assert sum(p.volume for p in pieces) == pytest.approx(mesh.volume, rel=0.05)
    monkeypatch.setattr(coacd, "run_coacd", lambda *a, **k: pytest.fail("decomposed twice"))
    again = decomposition.convex_decomposition(mesh, tmp_path)
    assert len(again) == len(pieces)
    bigger = decomposition.convex_decomposition(meshes.scale_to_footprint(_l_mesh(), 0.07),
                                                tmp_path)  # another footprint: same cache entry
    assert sum(p.volume for p in bigger) == pytest.approx(
        sum(p.volume for p in pieces) * 1.4**3, rel=1e-6)


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


# ------------------------------------------------------------- repair, low parts, skipping (#10)
def _open_cup(radius=20.0, height=45.0):
    """A cylinder without its top cap: an open surface (a hole of 48 edges)."""
    cyl = trimesh.creation.cylinder(radius=radius, height=height, sections=48)
    keep = cyl.face_normals[:, 2] < 0.5
    return trimesh.Trimesh(cyl.vertices, cyl.faces[keep])


def _prism(tmp_path):
    """A triangular prism: wherever the closing axis leaves it, the far side is 40 deg or more
    off the axis, so with `max_push_angle_deg` 10 no grasp is valid (a box's far side is not)."""
    tri = trimesh.creation.extrude_polygon(
        shapely.Polygon([(0, 0), (40, 0), (20, 34.64)]), 30)
    tri.export(tmp_path / "prism.stl")


def _run(args, capsys=None):
    rc = main(["generate", "--workers", "1", "--no-progress", *map(str, args)])
    return rc, (capsys.readouterr() if capsys else None)


def test_open_and_badly_wound_meshes_are_repaired(tmp_path):
    cup = _open_cup()
    assert not cup.is_watertight
    cup.export(tmp_path / "cup.obj")
    mesh = meshes.load_mesh(tmp_path / "cup.obj")
    assert mesh.is_watertight and mesh.volume > 0
    assert "filled holes" in mesh.metadata["repairs"]
    box = trimesh.creation.box([30, 20, 10])
    faces = box.faces.copy()
    faces[::2] = faces[::2, ::-1]  # half the faces wound the wrong way
    soup = box.vertices[faces].reshape(-1, 3)  # every face with its own vertices (STL-like)
    fixed = meshes.repair_mesh(soup, np.arange(len(soup)).reshape(-1, 3))
    assert fixed.is_watertight and fixed.volume == pytest.approx(box.volume)
    assert np.all((fixed.face_normals * (fixed.triangles_center - fixed.centroid)).sum(1) > 0)


def test_mesh_that_stays_open_is_collided_through_its_decomposition(tmp_path, monkeypatch):
    box = trimesh.creation.box([40, 30, 30])
    a, b = box.edges_unique[0]
    fin = len(box.vertices)  # a fin on one edge: three faces share it, no fill can close it
    mid = box.vertices[[a, b]].mean(0)
    verts = np.vstack([box.vertices, mid + 10 * mid / np.linalg.norm(mid)])
    trimesh.Trimesh(verts, np.vstack([box.faces, [[a, b, fin]]]),
                    process=False).export(tmp_path / "finned.obj")
    mesh = meshes.load_mesh(tmp_path / "finned.obj")
    assert not mesh.is_watertight
    assert any("convex decomposition" in note for note in mesh.metadata["repairs"])
    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    rc, _ = _run(["--n", "2", "--repeats", "1", "--objects", tmp_path / "finned.obj", "--out",
                  tmp_path / "ds"])
    assert rc == 0
    manifest = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert manifest["counts"]["configs"] == 2
    assert any("convex decomposition" in n for n in manifest["per_object"][0]["repairs"])
    cached = list((tmp_path / "cache" / "coacd").glob("*.npz"))  # CoACD ran on the open mesh
    assert len(cached) == 1


def test_open_cup_generates_labels(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    _open_cup().export(tmp_path / "cup.obj")
    rc, io = _run(["--n", "3", "--repeats", "1", "--objects", tmp_path / "cup.obj", "--out",
                   tmp_path / "ds"], capsys)
    assert rc == 0
    summary = [line.split() for line in io.out.splitlines() if line.startswith("cup_000")]
    assert summary and summary[0][1:4] == ["used", "3", "3"]  # end-of-run summary per object
    manifest = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert manifest["counts"]["configs"] == 3


def test_flat_plate_is_pressed_at_half_its_height(tmp_path, monkeypatch):
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.objects.library import ObjectSpec, build_object

    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    trimesh.creation.box([60, 40, 4]).export(tmp_path / "plate.stl")
    cfg = GenerateCfg()
    obj = build_object(ObjectSpec("p", "mesh", 0, 0.06, 0.0, str(tmp_path / "plate.stl")),
                       cfg.hand.height)
    assert obj.mesh.bounds[1, 2] == pytest.approx(0.004)
    assert obj.press_height == pytest.approx(0.002)  # not the hand's 12 mm
    rc, _ = _run(["--n", "3", "--repeats", "2", "--objects", tmp_path / "plate.stl", "--out",
                  tmp_path / "ds"])
    assert rc == 0
    manifest = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert manifest["per_object"][0]["presses"] == 6


def test_object_without_valid_grasp_is_skipped_and_the_count_delivered(tmp_path, monkeypatch):
    from vistac_sim.generate.config import GenerateCfg, GraspCfg
    from vistac_sim.generate.objects_report import format_summary
    from vistac_sim.generate.run import generate
    from vistac_sim.objects.config import ObjectsCfg

    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "objs"
    folder.mkdir()
    trimesh.creation.box([30, 20, 40]).export(folder / "box.stl")
    _prism(folder)

    def cfg(strict=False):
        return GenerateCfg(n=5, repeats=2, grasp=GraspCfg(max_push_angle_deg=10),
                           objects=ObjectsCfg(paths=(str(folder),), strict=strict))

    manifest = generate(cfg(), tmp_path / "ds", workers=1, progress=False)
    assert manifest["counts"]["configs"] == 5 and manifest["counts"]["presses"] == 10
    rows = {r["path"].rsplit("/", 1)[-1]: r for r in manifest["per_object"]}
    assert rows["prism.stl"]["status"] == "skipped"
    assert "no valid grasp in 60 draws" in rows["prism.stl"]["reason"]
    assert rows["prism.stl"]["rejections"] == {"no_opposing_thumb": 60}
    assert rows["box.stl"]["status"] == "used"
    assert rows["box.stl"]["configurations"] == 5 and rows["box.stl"]["presses"] == 10
    summary = format_summary(manifest["per_object"])  # printed at the end of `vistac generate`
    assert "prism" in summary and "no valid grasp" in summary and "no_opposing_thumb 60" in summary
    with pytest.raises(UserError, match=r"prism.stl\): no valid grasp .*--strict"):
        generate(cfg(strict=True), tmp_path / "s", workers=1, progress=False)


def test_strict_refuses_a_broken_mesh_naming_the_file(tmp_path, bad_meshes, monkeypatch, capsys):
    monkeypatch.setenv("VISTAC_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "objs"
    folder.mkdir()
    trimesh.creation.box([30, 20, 40]).export(folder / "box.stl")
    (folder / "nan.obj").write_bytes(bad_meshes["nan"].read_bytes())
    rc, io = _run(["--n", "2", "--objects", folder, "--out", tmp_path / "s", "--strict"], capsys)
    assert rc == 2 and str(folder / "nan.obj") in io.err and "NaN" in io.err
    assert "Traceback" not in io.err


def test_manifest_lists_per_object_counts(tmp_path, monkeypatch):
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.run import generate
    from vistac_sim.objects.config import ObjectsCfg

    cfg = GenerateCfg(n=8, repeats=2, objects=ObjectsCfg(n_objects=3, families=("box", "L")))
    manifest = generate(cfg, tmp_path / "ds", workers=1, progress=False)
    rows = manifest["per_object"]
    assert [r["object_id"] for r in rows] == [o["object_id"] for o in manifest["objects"]]
    assert sum(r["configurations"] for r in rows) == 8
    assert sum(r["presses"] for r in rows) == 16
    total = sum(sum(r["rejections"].values()) for r in rows)
    assert total == manifest["redraws"]["total"]
    for r in rows:
        assert r["status"] == "used" and r["presses"] == 2 * r["configurations"]


def test_configuration_moves_on_when_its_object_fails_during_the_run(tmp_path, monkeypatch):
    from collections import Counter

    from vistac_sim.generate import configuration
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.rigs import NoValidGrasp
    from vistac_sim.generate.run import generate
    from vistac_sim.objects.config import ObjectsCfg

    real = configuration.draw_grasp

    def flaky(scene, rng, cfg):  # the first object passes the screen, then never again
        if scene.obj.object_id.endswith("_000"):
            raise NoValidGrasp(scene.obj.object_id, Counter(no_contact=60))
        return real(scene, rng, cfg)

    monkeypatch.setattr(configuration, "draw_grasp", flaky)
    cfg = GenerateCfg(n=6, repeats=1, objects=ObjectsCfg(n_objects=2, families=("box",)))
    manifest = generate(cfg, tmp_path / "ds", workers=1, progress=False)
    assert manifest["counts"]["configs"] == 6
    first, second = manifest["per_object"]
    assert first["configurations"] == 0 and first["rejections"]["no_contact"] % 60 == 0
    assert first["rejections"]["no_contact"] > 0 and second["configurations"] == 6
