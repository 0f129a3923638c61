"""Every reasonable mesh gives labels: `vistac generate` on a collection of real meshes, one run
per mesh (as a new user would), then one folder run over all of them.

The collection: 22 meshes shipped in the `pybullet` wheel (3.2.7, its `pybullet_data` folder:
scans such as the bunny and the duck, CAD parts of robots and a differential, toys, a plate, a
tray, a mug), plus variants derived from the example meshes in `sim_assets/meshes` that break
them on purpose (holes punched, winding flipped, vertices duplicated) and low or open shapes
(flat plate, thin sheet, open bowl, open cup), plus two truly broken files (empty, NaN) that must
be refused with their file named. The wheel comes from PyPI (`pip download pybullet==3.2.7
--no-deps`) unless `--wheel` names it.

Writes `benchmarks/results/mesh_collection.csv` (one row per mesh: status, reason, repairs,
press height, configurations and presses accepted, rejected draws by reason) and `.md`.

    python benchmarks/mesh_collection.py [--n 6] [--wheel pybullet-3.2.7-....whl]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import trimesh

from vistac.errors import UserError
from vistac_sim.assets import EXAMPLE_MESHES
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.run import generate
from vistac_sim.objects.config import ObjectsCfg
from vistac_sim.objects.library import ObjectSpec, build_object
from vistac_sim.objects.meshes import load_mesh

ROOT = Path(__file__).resolve().parent
PYBULLET = "pybullet==3.2.7"
MEMBERS = [
    "bunny.obj", "duck.obj", "objects/mug.obj", "lego/lego.obj", "teddy2_VHACD_CHs.obj",
    "sphere_smooth.obj", "soccerball.obj", "torus/torus_textured.obj", "toys/concave_box.obj",
    "toys/cylinder.obj", "toys/prism.obj", "toys/shape_sorter.obj", "toys/cube.obj",
    "tray/tray_textured.obj", "jenga/jenga.obj", "domino/domino.obj",
    "quadruped/microtaur/plate.stl", "kuka_iiwa/meshes/link_3.stl",
    "differential/diff_spider.stl", "racecar/meshes/cone.obj", "gripper/meshes/WSG-FMF.stl",
    "racecar/meshes/left_front_wheel.STL",
]


def fetch_pybullet(folder: Path, wheel: str | None) -> list[Path]:
    """Extract MEMBERS from the pybullet wheel (downloaded from PyPI if not given)."""
    if wheel is None:
        found = sorted(folder.glob("pybullet-*.whl"))
        if not found:
            subprocess.run([sys.executable, "-m", "pip", "download", PYBULLET, "--no-deps",
                            "-d", str(folder)], check=True)
            found = sorted(folder.glob("pybullet-*.whl"))
        wheel = str(found[0])
    out = []
    with zipfile.ZipFile(wheel) as z:
        for m in MEMBERS:
            target = folder / "pybullet_data" / m
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(z.read(f"pybullet_data/{m}"))
            out.append(target)
    return out


def derived(folder: Path) -> list[Path]:
    """Broken, low and open variants of the example meshes and of simple shapes."""
    folder.mkdir(parents=True, exist_ok=True)
    knob = load_mesh(EXAMPLE_MESHES / "knob_m.obj")
    bracket = load_mesh(EXAMPLE_MESHES / "bracket_mm.stl")
    made: dict[str, trimesh.Trimesh] = {}
    top = knob.triangles_center[:, 2] > knob.bounds[1, 2] - 0.25 * knob.extents[2]
    made["knob_holes_punched.obj"] = trimesh.Trimesh(knob.vertices, knob.faces[~top])
    flipped = bracket.copy()
    flipped.faces = flipped.faces[:, ::-1]
    made["bracket_flipped_winding.stl"] = flipped
    half = bracket.copy()
    half.faces[::2] = half.faces[::2, ::-1]
    made["bracket_half_flipped.obj"] = half
    dup = bracket.triangles.reshape(-1, 3) * (1 + 1e-9)
    made["bracket_duplicated_vertices.obj"] = trimesh.Trimesh(
        dup, np.arange(len(dup)).reshape(-1, 3), process=False)
    made["flat_plate_60x40x3.stl"] = trimesh.creation.box([60, 40, 3])
    made["thin_sheet_60x40x0.8.stl"] = trimesh.creation.box([60, 40, 0.8])
    sphere = trimesh.creation.icosphere(4, radius=30)
    bowl = sphere.triangles_center[:, 2] < -3
    made["open_bowl.obj"] = trimesh.Trimesh(sphere.vertices, sphere.faces[bowl])
    cyl = trimesh.creation.cylinder(radius=20, height=45, sections=48)
    side = cyl.face_normals[:, 2] < 0.5
    made["open_cup.obj"] = trimesh.Trimesh(cyl.vertices, cyl.faces[side])
    tube = trimesh.creation.annulus(r_min=6, r_max=8, height=70)
    made["tube_lying.stl"] = tube.apply_transform(
        trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    paths = []
    for name, mesh in made.items():
        mesh.export(folder / name)
        paths.append(folder / name)
    (folder / "broken_empty.stl").write_bytes(b"")
    (folder / "broken_nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\n"
                                           "f 1 2 4\nf 1 3 4\nf 2 3 4\n")
    return paths + [folder / "broken_empty.stl", folder / "broken_nan.obj"]


def run_one(path: Path, n: int, work: Path) -> dict:
    """One `generate` run on one mesh; the row of the results table."""
    row: dict = {"mesh": path.parent.name + "/" + path.name, "status": "", "reason": "",
                 "repairs": "", "press_height_mm": np.nan, "configurations": 0, "presses": 0,
                 "rejections": "", "cpu_s": 0.0}
    t0 = time.process_time()
    try:
        mesh = load_mesh(path)
        row["repairs"] = "; ".join(mesh.metadata["repairs"])
        cfg = GenerateCfg(n=n, repeats=1, objects=ObjectsCfg(paths=(str(path),)))
        spec = ObjectSpec("probe", "mesh", 0, float(np.mean(cfg.objects.footprint)), 0.0,
                          str(path))
        row["press_height_mm"] = 1000 * build_object(spec, cfg.hand.height).press_height
        manifest = generate(cfg, work / path.stem, workers=1, progress=False)
        spec = ObjectSpec(**manifest["objects"][0])  # the footprint the run drew
        row["press_height_mm"] = round(1000 * build_object(spec, cfg.hand.height).press_height,
                                       2)
        obj = manifest["per_object"][0]
        row.update(status=obj["status"], reason=obj.get("reason", ""),
                   configurations=manifest["counts"]["configs"],
                   presses=manifest["counts"]["presses"],
                   rejections=json.dumps(obj["rejections"]))
    except UserError as exc:
        row.update(status="refused", reason=str(exc).replace(str(path), path.name))
    row["cpu_s"] = round(time.process_time() - t0, 1)
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=6, help="configurations per mesh")
    p.add_argument("--folder-n", type=int, default=60, help="configurations of the folder run")
    p.add_argument("--wheel", default=None, help="the pybullet wheel (else pip download)")
    p.add_argument("--work", default=None, help="folder for the collection and the datasets")
    p.add_argument("--before-src", default=None,
                   help="a source tree of vistac from before (e.g. `git archive a4f8fcf vistac "
                   "vistac_sim sim_assets`): adds what its mesh loader and 12 mm section said")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")
    work = Path(args.work or tempfile.mkdtemp(prefix="mesh_collection_"))
    work.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(work / "runs", ignore_errors=True)
    os.environ.setdefault("VISTAC_CACHE", str(work / "vistac_cache"))
    files = fetch_pybullet(work, args.wheel) + derived(work / "derived")
    rows = []
    for f in files:
        rows.append(run_one(f, args.n, work / "runs"))
        print(f"{rows[-1]['mesh']:<45} {rows[-1]['status']:<8} {rows[-1]['configurations']:>3} "
              f"{rows[-1]['rejections'] or rows[-1]['reason']}", flush=True)
    table = pd.DataFrame(rows)
    if args.before_src:
        table.insert(1, "before", before(files, args.before_src))
    folder = work / "all"
    folder.mkdir(exist_ok=True)
    for f in files:
        (folder / f"{f.parent.name}__{f.name}").write_bytes(f.read_bytes())
    cfg = GenerateCfg(n=args.folder_n, repeats=1, objects=ObjectsCfg(paths=(str(folder),)))
    t0 = time.process_time()
    manifest = generate(cfg, work / "runs" / "all", workers=1, progress=False)
    folder_cpu = time.process_time() - t0
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    table.to_csv(out / "mesh_collection.csv", index=False)
    write_report(out / "mesh_collection.md", table, manifest, args, folder_cpu)
    print(f"wrote {out / 'mesh_collection.csv'} and .md")
    return 0


def write_report(path: Path, table: pd.DataFrame, manifest: dict, args, folder_cpu: float):
    used = table["status"] == "used"
    counts = table["status"].value_counts().to_dict()
    folder = pd.DataFrame(manifest["per_object"])
    lines = [
        "# Mesh collection: every reasonable mesh gives labels",
        "",
        f"Source: {len(MEMBERS)} meshes of the `pybullet_data` folder in the PyPI wheel "
        f"`{PYBULLET}` (scans, CAD parts, toys, plate, tray, mug), plus variants of "
        "`sim_assets/meshes` broken on purpose and low/open shapes (`derived/`). Command: "
        f"`python benchmarks/mesh_collection.py --n {args.n} --folder-n {args.folder_n}"
        + (" --before-src SRC` (SRC: the tree before #10 parts 1-2); `before` says what the old "
           "loader and its section at 12 mm did with the file (it never got to grasps)."
           if args.before_src else "`."),
        "",
        f"One run per mesh ({args.n} configurations, 1 repeat): "
        + ", ".join(f"{v} {k}" for k, v in counts.items())
        + f"; {int(table.loc[used, 'configurations'].sum())} configurations delivered."
        + (f" Before: the old loader refused {int(table['before'].str.startswith('refused').sum())}"
           f" of the {len(table)} files." if "before" in table else ""),
        "",
        _markdown(table.drop(columns=["cpu_s"])),
        "",
        f"Folder run over all {len(table)} files ({args.folder_n} configurations asked, "
        f"{manifest['counts']['configs']} delivered, {folder_cpu:.0f} s CPU):",
        "",
        _markdown(folder.reindex(columns=["object_id", "path", "status", "reason",
                                          "configurations", "presses", "rejections"])
                  .assign(path=folder["path"].map(lambda s: Path(s).name if s else ""),
                          rejections=folder["rejections"].map(json.dumps))),
        "",
    ]
    path.write_text("\n".join(lines))


BEFORE = """
import sys, warnings
warnings.simplefilter("ignore")
from vistac.errors import UserError
from vistac_sim.objects.meshes import load_mesh, mesh_section, scale_to_footprint
for f in sys.argv[1:]:
    try:
        mesh_section(scale_to_footprint(load_mesh(f), 0.055), 0.012, f)
        print("loads")
    except UserError as e:
        print("refused: " + str(e).split(": ", 1)[1])
"""


def before(files: list[Path], src: str) -> list[str]:
    """What the old loader (and its section at the fingertip height) said about each file."""
    env = {**os.environ, "PYTHONPATH": src}
    out = subprocess.run([sys.executable, "-c", BEFORE, *map(str, files)], env=env,
                         capture_output=True, text=True, check=True, cwd=src).stdout
    return out.splitlines()


def _markdown(df: pd.DataFrame) -> str:
    cells = df.astype(object).where(df.notna(), "").astype(str)
    cells = cells.apply(lambda col: col.str.replace("|", "/", regex=False))
    head = "| " + " | ".join(df.columns) + " |\n|" + "---|" * len(df.columns)
    return head + "\n" + "\n".join("| " + " | ".join(r) + " |" for r in cells.values.tolist())


if __name__ == "__main__":
    raise SystemExit(main())
