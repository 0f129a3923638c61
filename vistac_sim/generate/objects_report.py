"""Per-object bookkeeping of a run: screening objects before it, the summary after it.

`screen_objects` builds each object once and draws grasps (seeded by the run's seed and the
object's place in the library) until one passes every check. An object that fails to build, or
gives no valid grasp in `grasp.max_redraws` draws, is skipped with its reason (an error with
`--strict`); the run's configurations are spread over the objects that remain, so the count asked
for is still delivered. `object_summary` lists per object the configurations and presses accepted
and the rejected draws by reason; `format_summary` prints it at the end of a run.
"""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pandas as pd
from tqdm import tqdm

from vistac.errors import UserError
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.scenes import NoValidGrasp, ObjectScene, draw_grasp
from vistac_sim.objects.decomposition import default_cache_dir
from vistac_sim.objects.library import ObjectSpec, build_object


def screen_objects(specs: list[ObjectSpec], cfg: GenerateCfg, progress: bool = False
                   ) -> tuple[list[ObjectSpec], list[dict], dict[str, list[str]]]:
    """Keep the objects that give a valid grasp; the others are returned with their reasons.

    Returns:
        The kept specs, the skipped objects (`object_id`, `path`, `reason`, `rejections`) and
        the repairs made to each mesh (by object id).

    Raises:
        UserError: with `objects.strict`, the first object skipped (named with its file); or
            when no object remains.
    """
    kept, skipped, repairs = [], [], {}
    for k, spec in enumerate(tqdm(specs, desc="check objects", unit="obj", disable=not progress)):
        rng = np.random.default_rng([cfg.seed, k, 0x5C4EE7])
        reason, rejections, notes = _screen_one(spec, cfg, rng)
        if notes:
            repairs[spec.object_id] = notes
        if reason is None:
            kept.append(spec)
            continue
        name = spec.object_id + (f" ({spec.path})" if spec.path else "")
        if cfg.objects.strict:
            raise UserError(f"{name}: {reason} (--strict)")
        skipped.append({"object_id": spec.object_id, "path": spec.path, "reason": reason,
                        "rejections": rejections})
    if not kept:
        raise UserError("no object gave a valid grasp: " + "; ".join(
            f"{s['object_id']}: {s['reason']}" for s in skipped))
    return kept, skipped, repairs


def _screen_one(spec: ObjectSpec, cfg: GenerateCfg, rng: np.random.Generator
                ) -> tuple[str | None, dict[str, int], list[str]]:
    try:
        obj = build_object(spec, cfg.hand.height, cfg.objects.min_wall, default_cache_dir(),
                           cfg.objects.min_height)
        scene = ObjectScene(obj, cfg, render=False)
    except UserError as exc:
        return str(exc), {}, []
    except Exception as exc:  # one object must never abort a run
        return f"cannot build the object ({type(exc).__name__}: {exc})", {}, []
    notes = list(obj.mesh.metadata.get("repairs", []))
    try:
        draw_grasp(scene, rng, cfg)
    except NoValidGrasp as exc:
        counts = dict(sorted(exc.redraws.items()))
        return f"no valid grasp in {sum(counts.values())} draws", counts, notes
    finally:
        scene.close()
    return None, {}, notes


def object_summary(configs: pd.DataFrame, presses: pd.DataFrame, objects: list[dict],
                   skipped: list[dict], repairs: dict[str, list[str]] | None = None
                   ) -> list[dict]:
    """Per object: status, configurations and presses accepted, rejected draws by reason.

    Args:
        configs: the run's configs table (`object_id`, `redraw_reasons`, `failed_objects`).
        presses: the run's presses table (`config_id`).
        objects: the specs of the objects used (`object_id`, `path`).
        skipped: objects and meshes skipped before the run (`object_id` or `path`, `reason`,
            optional `rejections`).
        repairs: what was repaired in each mesh, by object id.
    """
    repairs = repairs or {}
    per_config = presses.groupby("config_id").size()
    n_presses = configs["config_id"].map(per_config).fillna(0).astype(int)
    rejections: dict[str, Counter] = {o["object_id"]: Counter() for o in objects}
    for oid, text in zip(configs["object_id"], configs["redraw_reasons"], strict=True):
        for item in filter(None, text.split(",")):
            reason, count = item.split(":")
            rejections[oid][reason] += int(count)
    for text in configs.get("failed_objects", pd.Series(dtype=str)):
        for oid, counts in (json.loads(text) if text else {}).items():
            rejections.setdefault(oid, Counter()).update(counts)
    rows = []
    for o in objects:
        mine = configs["object_id"] == o["object_id"]
        rows.append({"object_id": o["object_id"], "path": o.get("path", ""), "status": "used",
                     "configurations": int(mine.sum()), "presses": int(n_presses[mine].sum()),
                     "rejections": dict(sorted(rejections[o["object_id"]].items())),
                     "repairs": repairs.get(o["object_id"], [])})
    for s in skipped:
        rows.append({"object_id": s.get("object_id", ""), "path": s.get("path", ""),
                     "status": "skipped", "reason": s["reason"], "configurations": 0,
                     "presses": 0, "rejections": s.get("rejections", {}),
                     "repairs": repairs.get(s.get("object_id", ""), [])})
    return rows


def format_summary(rows: list[dict]) -> str:
    """The per-object summary as text lines (one per object)."""
    lines = [f"{'object':<28} {'status':<8} {'configs':>7} {'presses':>7}  rejections / reason"]
    for r in rows:
        name = r["object_id"] or r["path"].rsplit("/", 1)[-1]
        rej = ", ".join(f"{k} {v}" for k, v in r["rejections"].items()) or "-"
        why = f"  {r['reason']}" if r["status"] == "skipped" else ""
        lines.append(f"{name[:28]:<28} {r['status']:<8} {r['configurations']:>7} "
                     f"{r['presses']:>7}  {rej}{why}")
    return "\n".join(lines)
