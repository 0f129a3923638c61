"""Simulator accuracy against time: how far cheaper settings move the labels, and what they save.

The same `--n` grasp configurations (object and grasp drawn from the seed as `vistac generate`
draws them, accepted by the reference) are pressed under each setting of the fidelity knobs and
compared with a high-fidelity reference run of the same configurations. Each knob family is one
panel, with the other knobs at their defaults; every default comes from the config dataclass that
owns it (`PhysicsCfg`, `RenderCfg`, `GenerateCfg`; the decomposition threshold from
`convex_decomposition`'s signature), so the sweep follows the defaults when they change.

- physics: time step x settle steps (the grid is multiples of the defaults). Reference: a
  quarter of the time step, four times the settle time. Error: angle between the noise-free unit
  labels (r_y, r_z) of setting and reference, per finger.
- decomposition: the concave procedural objects (`CONCAVE_FAMILIES`) collided through CoACD
  pieces at several thresholds instead of their exact convex pieces (the reference). Same error.
- image size: what the image shows of the finger: the finger's box in a segmentation render
  against its exact box, in mm on the table. Labels do not depend on the image.
- repeats: under the `lab` preset (grasp effects: one solve per repeat), the angle between the
  mean label of k repeats and the mean of `--ref-repeats` repeats (the cone's centre).

Seconds per sample are CPU seconds (`time.process_time`: robust to other jobs on the machine)
of the work the knob changes: presses (and normals) for physics, decomposition and repeats;
render and PNG encoding for image size. The default must lie on each panel's Pareto front.

Usage:
    python benchmarks/sim_fidelity.py --n 200 --out benchmarks/results
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import inspect
import time
from pathlib import Path

import numpy as np

from vistac.config import apply
from vistac.dataset import unit_labels
from vistac_sim.effects import build_pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import ConfigStreams
from vistac_sim.generate.rigs import ObjectRig, draw_grasp, solve
from vistac_sim.objects.decomposition import convex_decomposition, default_cache_dir
from vistac_sim.objects.library import BuiltObject, build_object, procedural_library
from vistac_sim.objects.outlines import CONCAVE_FAMILIES
from vistac_sim.objects.specs import object_index
from vistac_sim.physics.checks import RejectedSample
from vistac_sim.render.png import encode_png
from vistac_sim.render.topview import finger_boxes

DT_FACTORS = (0.5, 1.0, 2.0)
SETTLE_FACTORS = (1 / 3, 1 / 2, 2 / 3, 1.0, 2.0)
REF_DT, REF_SETTLE_TIME = 0.25, 4.0  # reference: time step x 1/4, settle time x 4
THRESHOLDS = (0.2, 0.1, 0.05, 0.03)
SIZE_FACTORS = (0.5, 0.75, 1.0, 1.5, 2.0)
REPEATS = (1, 2, 3, 6, 12)
ERROR_FLOOR_DEG = 0.01  # label differences below this count as none (far below any learnable one)


def default_threshold() -> float:
    return inspect.signature(convex_decomposition).parameters["threshold"].default


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between unit 2-vectors (..., 2)."""
    return np.degrees(np.abs(np.arctan2(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
                                        (a * b).sum(-1))))


class Configs:
    """The benchmark's configurations: per config, its object index and the drawn grasp."""

    def __init__(self, n: int, cfg: GenerateCfg, objects: list[BuiltObject]):
        self.cfg, self.objects = cfg, objects
        scenes = [ObjectRig(o, cfg, render=False) for o in objects]
        self.items = []
        for cid in range(n):
            k = object_index(cfg.seed, cid, len(objects))
            try:
                grasp = draw_grasp(scenes[k], ConfigStreams(cfg.seed, cid)["grasp"], cfg)[0]
            except RuntimeError:
                continue
            self.items.append((k, grasp))


def press_all(configs: Configs, cfg: GenerateCfg, objects: list[BuiltObject] | None = None
              ) -> tuple[np.ndarray, float]:
    """(n, 2, 2) clean unit labels (NaN where the setting rejects the grasp), CPU s per press."""
    scenes = [ObjectRig(o, cfg, render=False) for o in (objects or configs.objects)]
    labels = np.full((len(configs.items), 2, 2), np.nan)
    t0 = time.process_time()
    for i, (k, grasp) in enumerate(configs.items):
        try:
            res, _ = solve(scenes[k], grasp, cfg)
        except RejectedSample:
            continue
        labels[i] = unit_labels(res.force_sensor)
    return labels, (time.process_time() - t0) / max(len(configs.items), 1)


def label_error(labels: np.ndarray, ref: np.ndarray) -> dict:
    """Per finger, median and p95 of the angle to the reference label (deg); a configuration
    the setting rejects but the reference accepts counts as 180 deg (its label is lost).
    ``error_deg``, the Pareto axis, is the worse finger's p95, floored at `ERROR_FLOOR_DEG`."""
    have_ref = ~np.isnan(ref).any(axis=(1, 2))
    lost = np.isnan(labels).any(axis=(1, 2)) & have_ref
    ang = angle_between(np.nan_to_num(labels[have_ref]), ref[have_ref])  # (m, 2)
    ang[lost[have_ref]] = 180.0
    out = {"compared": int(have_ref.sum()), "rejected_vs_ref": int(lost.sum())}
    for j, f in enumerate(("index", "thumb")):
        out[f"median_{f}_deg"] = float(np.median(ang[:, j]))
        out[f"p95_{f}_deg"] = float(np.percentile(ang[:, j], 95))
    out["error_deg"] = max(ERROR_FLOOR_DEG, out["p95_index_deg"], out["p95_thumb_deg"])
    return out


def with_physics(cfg: GenerateCfg, timestep: float, settle_steps: int) -> GenerateCfg:
    # The approach phase scales with the settling phase (the same simulated time per phase).
    approach = max(1, int(round(cfg.physics.approach_steps * settle_steps
                                / cfg.physics.settle_steps)))
    return apply(cfg, {"physics": {"timestep": timestep,
                                   "settle_steps": max(1, int(round(settle_steps))),
                                   "approach_steps": approach}})


def physics_panel(n: int, cfg: GenerateCfg) -> tuple[list[dict], np.ndarray, Configs]:
    p = cfg.physics
    ref_cfg = with_physics(cfg, p.timestep * REF_DT, p.settle_steps / REF_DT * REF_SETTLE_TIME)
    objects = [build_object(s, cfg.hand.height, cfg.objects.min_wall)
               for s in procedural_library(cfg.objects, cfg.seed)]
    configs = Configs(n, ref_cfg, objects)
    ref, ref_t = press_all(configs, ref_cfg)
    rows = [{"panel": "physics", "setting": f"reference dt={ref_cfg.physics.timestep:g} "
             f"steps={ref_cfg.physics.settle_steps}", "reference": True, "default": False,
             "s_per_sample": ref_t, **label_error(ref, ref)}]
    for fd in DT_FACTORS:
        for fs in SETTLE_FACTORS:
            c = with_physics(cfg, p.timestep * fd, p.settle_steps * fs)
            labels, t = press_all(configs, c)
            rows.append({"panel": "physics", "setting": f"dt={c.physics.timestep:g} "
                         f"steps={c.physics.settle_steps}", "reference": False,
                         "default": fd == 1.0 and fs == 1.0, "s_per_sample": t,
                         **label_error(labels, ref)})
    return rows, ref, configs


def decomposition_panel(n: int, cfg: GenerateCfg, n_objects: int) -> list[dict]:
    specs = [s for s in procedural_library(cfg.objects, cfg.seed)
             if s.family in CONCAVE_FAMILIES][:n_objects]
    exact = [build_object(s, cfg.hand.height, cfg.objects.min_wall) for s in specs]
    configs = Configs(n, cfg, exact)
    ref, ref_t = press_all(configs, cfg)
    rows = [{"panel": "decomposition", "setting": "exact convex pieces", "reference": True,
             "default": False, "s_per_sample": ref_t, **label_error(ref, ref)}]
    for t in THRESHOLDS:
        t0 = time.process_time()
        objs = [BuiltObject(o.spec, o.mesh, convex_decomposition(o.mesh, default_cache_dir(), t),
                            o.section, o.rgb) for o in exact]
        made = time.process_time() - t0
        labels, sec = press_all(configs, cfg, objs)
        rows.append({"panel": "decomposition", "setting": f"CoACD threshold={t:g} "
                     f"({np.mean([len(o.pieces) for o in objs]):.1f} pieces)",
                     "reference": False, "default": t == default_threshold(),
                     "s_per_sample": sec, "decomposition_cpu_s_per_object": made / len(objs),
                     **label_error(labels, ref)})
    return rows


def image_panel(configs: Configs, cfg: GenerateCfg) -> list[dict]:
    rows = []
    for f in SIZE_FACTORS:
        c = apply(cfg, {"render": {"image_size": int(round(cfg.render.image_size * f))}})
        scenes = [ObjectRig(o, c) for o in configs.objects]
        errs, cpu = [], 0.0
        for k, grasp in configs.items:
            sc = scenes[k]
            try:
                sc.press.run(grasp)
            except RejectedSample:
                continue
            t0 = time.process_time()
            encode_png(sc.view.render(sc.press.data))
            cpu += time.process_time() - t0
            seg = sc.view.render(sc.press.data, segmentation=True)
            exact = finger_boxes(sc.model, sc.press.data, sc.ids, c.render)
            m_per_px = c.render.view_extent / c.render.image_size
            for j, finger in enumerate(("index", "thumb")):
                ys, xs = np.nonzero(np.isin(seg[..., 0], [sc.ids.pad[finger],
                                                          sc.ids.shaft[finger]]))
                if len(xs):
                    box = np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])
                    ex = exact[j].copy()
                    ex[2:] += ex[:2]
                    errs.append(np.abs(box - ex).max() * m_per_px * 1e3)
        for sc in scenes:
            sc.close()
        e = np.array(errs)
        rows.append({"panel": "image size", "setting": f"{c.render.image_size} px",
                     "reference": False, "default": f == 1.0,
                     "s_per_sample": cpu / max(len(configs.items), 1),
                     "compared": len(e), "median_box_error_mm": float(np.median(e)),
                     "error_deg": float("nan"), "p95_box_error_mm": float(np.percentile(e, 95))})
    return rows


def repeats_panel(configs: Configs, cfg: GenerateCfg, ref_repeats: int) -> list[dict]:
    lab = GenerateCfg.from_preset("lab")
    c = dataclasses.replace(copy.deepcopy(cfg), effects=lab.effects, recording=lab.recording)
    pipeline = build_pipeline(c.effects)
    scenes = [ObjectRig(o, c, render=False) for o in configs.objects]
    kmax = ref_repeats + max(REPEATS)  # the reference's presses are not reused
    labels = np.full((len(configs.items), kmax, 2, 2), np.nan)
    cpu = []
    for i, (k, grasp) in enumerate(configs.items):
        rng = ConfigStreams(c.seed, i)
        forces = []
        t0 = time.process_time()
        for _ in range(kmax):
            for _try in range(10):
                try:
                    forces.append(scenes[k].press.run(pipeline.apply_grasp(grasp,
                                                      rng["grasp_effects"])).force_sensor)
                    break
                except RejectedSample:
                    continue
        cpu.append((time.process_time() - t0) / kmax)
        if len(forces) == kmax:
            labels[i] = unit_labels(pipeline.apply_force(np.stack(forces), rng["force_effects"]))
    per_press = float(np.mean(cpu))
    ref = _mean_label(labels[:, -ref_repeats:])
    rows = []
    for k in REPEATS:
        err = label_error(_mean_label(labels[:, :k]), ref)
        rows.append({"panel": "repeats (lab preset)", "setting": f"{k} repeats",
                     "reference": False, "default": k == cfg.repeats,
                     "s_per_sample": k * per_press, **err})
    return rows


def _mean_label(labels: np.ndarray) -> np.ndarray:
    m = labels.mean(axis=1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--n", type=int, default=200, help="grasp configurations")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ref-repeats", type=int, default=24, help="repeats of the reference mean")
    p.add_argument("--decomposition-objects", type=int, default=8,
                   help="concave objects of the decomposition panel (CoACD is slow; cached)")
    p.add_argument("--panels", nargs="*", default=["physics", "decomposition", "image", "repeats"])
    p.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = p.parse_args()
    cfg = GenerateCfg(seed=args.seed)
    t0 = time.perf_counter()
    rows, _, configs = physics_panel(args.n, cfg)
    print(f"physics: {time.perf_counter() - t0:.0f} s", flush=True)
    if "decomposition" in args.panels:
        rows += decomposition_panel(args.n, cfg, args.decomposition_objects)
        print(f"decomposition: {time.perf_counter() - t0:.0f} s", flush=True)
    if "image" in args.panels:
        rows += image_panel(configs, cfg)
        print(f"image: {time.perf_counter() - t0:.0f} s", flush=True)
    if "repeats" in args.panels:
        rows += repeats_panel(configs, cfg, args.ref_repeats)
        print(f"repeats: {time.perf_counter() - t0:.0f} s", flush=True)
    from sim_fidelity_report import write_report

    defaults = {"timestep": cfg.physics.timestep, "settle_steps": cfg.physics.settle_steps,
                "coacd_threshold": default_threshold(), "image_size": cfg.render.image_size,
                "repeats": cfg.repeats}
    write_report(rows, args.out, {"n": args.n, "seed": args.seed, "configs": len(configs.items),
                                  "defaults": defaults, "wall_s": time.perf_counter() - t0})


if __name__ == "__main__":
    main()
