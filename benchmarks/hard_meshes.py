"""Hard meshes and hostile physics settings: what is kept, what is refused, and how right it is.

1. ``meshes``: every mesh of `vistac_sim.objects.stress.STRESS_MESHES` (thin plate, needle,
   2 mm and 300 mm objects, comb with 2 mm slots, 5-degree wedge, near-duplicate vertices,
   slivers in m and mm, an open scan, a knot) written to a file and built the user's way, at
   friction 0, 0.8 and 10: `--draws` configurations each; kept share, rejected draws by reason
   (or the skip reason), redraws per kept configuration, the frictionless label's angle to the
   mesh normal (median, p95), a sticking label's angle to the closing axis at friction 10, the
   CPU time per kept configuration relative to a 50 mm procedural box, and the repairs.
2. ``settings``: the analytic press (`vistac_sim.physics.analytic`: three faces, pushes 0-35
   deg, friction 0.3 and 0.8) under each physics setting of `SETTINGS`; the label error against
   Coulomb's law (median, p95, max) and the presses refused. `PhysicsCfg`'s edges
   (`vistac_sim.physics.config.BIASED`) quote these figures.
3. ``two_face``: drawn grasps on the procedural library at friction 0.8: the share of kept pads
   whose label lies more than 2 deg off the single-face rule min(push angle, atan mu) (the
   two-face exception of docs/physics.md), and how many of them press with several contacts.

Writes `hard_meshes.json` (with provenance) and `hard_meshes.md` into `--results`:

    .venv/bin/python benchmarks/hard_meshes.py --draws 10 --two-face-draws 400
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import trimesh
from shapely.geometry import box

from vistac.config import apply
from vistac.errors import UserError
from vistac.provenance import provenance
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import NoValidGrasp, ObjectRig, draw_grasp
from vistac_sim.geometry import angle_deg
from vistac_sim.objects.decomposition import default_cache_dir
from vistac_sim.objects.library import (
    ObjectSpec,
    build_object,
    extruded_object,
    procedural_library,
)
from vistac_sim.objects.stress import STRESS_MESHES
from vistac_sim.physics.analytic import FACES, analytic_press
from vistac_sim.physics.checks import RejectedSample

RESULTS = Path(__file__).parent / "results"
FRICTIONS = (0.0, 0.8, 10.0)
SETTINGS = {
    "default": {},
    "approach_steps=1": {"approach_steps": 1},
    "approach_steps=5": {"approach_steps": 5},
    "approach_steps=15": {"approach_steps": 15},
    "settle_steps=1": {"settle_steps": 1},
    "settle_steps=10": {"settle_steps": 10},
    "settle_steps=30": {"settle_steps": 30},
    "solimp=(0.5, 0.9, 10)": {"solimp": (0.5, 0.9, 10.0)},
    "solimp=(0.9, 0.95, 0.001)": {"solimp": (0.9, 0.95, 0.001)},
    "noslip_iterations=0": {"noslip_iterations": 0},
    "timestep=0.005": {"timestep": 0.005},
    "timestep=0.1": {"timestep": 0.1},
}
PUSHES = (0.0, 10.0, 20.0, 30.0, 35.0)


def _cpu() -> float:
    return time.process_time()


def press_mesh(name: str, friction: float, draws: int, folder: Path) -> dict:
    """One row of the mesh table (see the module's docstring)."""
    m = STRESS_MESHES[name]
    path = folder / f"{name}{m.suffix}"
    if not path.exists():
        trimesh.Trimesh(*m.build(), process=False).export(path)
    row = {"mesh": name, "friction": friction, "kept": 0, "draws": 0, "reasons": {},
           "skip": "", "repairs": []}
    t0 = _cpu()
    try:
        cfg = apply(GenerateCfg(), {"physics": {"friction": friction}, "objects": {
            "paths": [str(path)], "footprint": [m.footprint, m.footprint]}})
        obj = build_object(ObjectSpec(name, "mesh", 0, m.footprint, 0.0, str(path)),
                           cfg.hand.height, cache_dir=default_cache_dir())
        rig = ObjectRig(obj, cfg, render=False)
    except UserError as exc:
        row["skip"] = str(exc).replace(str(folder) + "/", "")
        return row
    row["repairs"] = list(obj.mesh.metadata.get("repairs", []))
    row["build_cpu_s"] = _cpu() - t0
    t0 = _cpu()
    reasons: Counter = Counter()
    off, stick = [], []
    rng = np.random.default_rng(0)
    for _ in range(draws):
        try:
            grasp, res, normal, redraws = draw_grasp(rig, rng, cfg)
        except NoValidGrasp as exc:
            reasons.update(exc.redraws)
            continue
        reasons.update(redraws)
        row["kept"] += 1
        off += angle_deg(res.force_sensor, normal).tolist()
        push = np.einsum("kji,kj->ki", res.rotation, np.c_[grasp.push_dirs, np.zeros(2)])
        stick += angle_deg(res.force_sensor, -push).tolist()
    row["draws"] = row["kept"] + sum(reasons.values())
    row["reasons"] = dict(reasons.most_common())
    row["cpu_per_kept_s"] = (_cpu() - t0) / max(row["kept"], 1)
    if off:
        row["label_to_normal_deg"] = [float(np.median(off)), float(np.percentile(off, 95))]
        row["label_to_closing_axis_deg"] = [float(np.median(stick)),
                                            float(np.percentile(stick, 95))]
    return row


def reference_cost(draws: int) -> float:
    """CPU s per kept configuration on a 50 mm procedural box at friction 0.8."""
    cfg = GenerateCfg()
    rig = ObjectRig(extruded_object(ObjectSpec("box", "ref", 0, 0.05, 0.04),
                                    box(-0.025, -0.025, 0.025, 0.025)), cfg, render=False)
    rng = np.random.default_rng(0)
    t0 = _cpu()
    for _ in range(draws):
        draw_grasp(rig, rng, cfg)
    return (_cpu() - t0) / draws


def settings_bias(name: str, changes: dict) -> dict:
    """Label error of the analytic press under one physics setting."""
    errors, refused = [], Counter()
    for friction in (0.3, 0.8):
        cfg = apply(GenerateCfg(), {"physics": changes})
        for face in FACES:
            for push in PUSHES:
                try:
                    errors.append(abs(analytic_press(face, push, friction, cfg).error_deg))
                except RejectedSample as exc:
                    refused[exc.reason] += 1
    e = np.array(errors) if errors else np.array([np.nan])
    return {"setting": name, "presses": len(errors) + sum(refused.values()),
            "refused": dict(refused), "error_median_deg": float(np.median(e)),
            "error_p95_deg": float(np.percentile(e, 95)), "error_max_deg": float(e.max())}


def two_face(draws: int) -> dict:
    """The single-face rule's exceptions on procedural shapes at friction 0.8: pads whose label
    lies more than 2 deg off min(angle(push, normal), atan mu), and of those, how many press
    with several contacts or across collision faces more than 1 deg apart."""
    cfg = GenerateCfg()
    cone = np.degrees(np.arctan(cfg.physics.friction))
    pads, off_rule, several, spread = 0, [], 0, 0
    per = max(1, draws // 32)
    for spec in procedural_library(cfg.objects, 0):
        rig = ObjectRig(build_object(spec, cfg.hand.height), cfg, render=False)
        rng = np.random.default_rng(1)
        for _ in range(per):
            try:
                grasp, res, normal, _ = draw_grasp(rig, rng, cfg)
            except NoValidGrasp:
                continue
            push = np.einsum("kji,kj->ki", res.rotation, np.c_[grasp.push_dirs, np.zeros(2)])
            expected = np.minimum(angle_deg(-push, normal), cone)
            got = angle_deg(res.force_sensor, normal)
            for k, cn in enumerate(res.contact_normals):
                pads += 1
                if abs(got[k] - expected[k]) > 2.0:
                    off_rule.append(float(abs(got[k] - expected[k])))
                    several += len(cn) > 1
                    spread += float(angle_deg(cn, cn[:1]).max()) > 1.0
    return {"pads": pads, "off_rule_pads": len(off_rule), "share": len(off_rule) / max(pads, 1),
            "off_rule_deg": sorted(off_rule), "with_several_contacts": int(several),
            "across_faces_1deg": int(spread)}


def markdown(out: dict) -> str:
    lines = ["| mesh | friction | kept / draws | rejected draws (or skip) | force to mesh normal, "
             "median / p95 deg (friction 0: the label's error) | sticking: force to closing "
             "axis, median / p95 deg | CPU per kept, x box |", "|---|---|---|---|---|---|---|"]
    ref = out["reference_cpu_per_kept_s"]
    for r in out["meshes"]:
        if r["skip"]:
            lines.append(f"| {r['mesh']} | {r['friction']:g} | skipped | {r['skip']} | | | |")
            continue
        reasons = ", ".join(f"{n} {k}" for k, n in r["reasons"].items()) or "none"
        lab = r.get("label_to_normal_deg")
        stick = r.get("label_to_closing_axis_deg")
        lines.append(
            f"| {r['mesh']} | {r['friction']:g} | {r['kept']} / {r['draws']} | {reasons} | "
            + (f"{lab[0]:.3f} / {lab[1]:.3f}" if lab else "") + " | "
            + (f"{stick[0]:.2f} / {stick[1]:.2f}" if stick and r["friction"] >= 10 else "")
            + (f" | {r['cpu_per_kept_s'] / ref:.1f} |" if r["kept"] else " | none kept |"))
    lines += ["", "| physics setting | presses | refused | error median / p95 / max deg |",
              "|---|---|---|---|"]
    for s in out["settings"]:
        refused = ", ".join(f"{n} {k}" for k, n in s["refused"].items()) or "none"
        lines.append(f"| {s['setting']} | {s['presses']} | {refused} | "
                     f"{s['error_median_deg']:.2f} / {s['error_p95_deg']:.2f} / "
                     f"{s['error_max_deg']:.2f} |")
    t = out.get("two_face")
    if t:
        lines += ["", f"Pads more than 2 deg off the single-face rule at friction 0.8: "
                  f"{t['off_rule_pads']} of {t['pads']} ({100 * t['share']:.2f} %), off by "
                  + ", ".join(f"{x:.1f}" for x in t["off_rule_deg"]) + " deg; "
                  f"{t['with_several_contacts']} of them with several contacts, "
                  f"{t['across_faces_1deg']} across faces more than 1 deg apart."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=10, help="configurations per mesh and friction")
    ap.add_argument("--two-face-draws", type=int, default=400)
    ap.add_argument("--parts", nargs="+", default=["meshes", "settings", "two_face"],
                    choices=["meshes", "settings", "two_face"])
    ap.add_argument("--meshes", nargs="+", default=sorted(STRESS_MESHES))
    ap.add_argument("--results", type=Path, default=RESULTS)
    ap.add_argument("--name", default="hard_meshes", help="stem of the result files")
    ap.add_argument("--table-only", action="store_true",
                    help="rewrite NAME.md from NAME.json, running nothing")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    if args.table_only:
        out = json.loads((args.results / f"{args.name}.json").read_text())
        (args.results / f"{args.name}.md").write_text(markdown(out))
        return
    out: dict = {"provenance": provenance(), "meshes": [], "settings": []}
    out["reference_cpu_per_kept_s"] = reference_cost(args.draws)
    if "meshes" in args.parts:
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.meshes:
                for friction in FRICTIONS:
                    row = press_mesh(name, friction, args.draws, Path(tmp))
                    out["meshes"].append(row)
                    print(json.dumps(row), flush=True)
    if "settings" in args.parts:
        for name, changes in SETTINGS.items():
            row = settings_bias(name, changes)
            out["settings"].append(row)
            print(json.dumps(row), flush=True)
    if "two_face" in args.parts:
        out["two_face"] = two_face(args.two_face_draws)
        print(json.dumps(out["two_face"]), flush=True)
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / f"{args.name}.json").write_text(json.dumps(out, indent=1) + "\n")
    table = markdown(out)
    (args.results / f"{args.name}.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
