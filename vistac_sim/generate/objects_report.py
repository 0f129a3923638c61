"""Per-object bookkeeping of a run: screening objects before it, the summary after it.

`screen_objects` keeps the objects whose screening passed: each object is built once, in a
worker, and grasps are drawn (seeded by the run's seed and the object's place in the library)
until one passes every check (`vistac_sim.generate.screening.screen_object`). An object that fails
to build, or
gives no valid grasp in `grasp.max_redraws` draws, is skipped with its reason (an error with
`--strict`); the run's configurations are spread over the objects that remain, so the count asked
for is still delivered. `object_summary` lists per object the configurations and presses accepted
and the rejected draws by reason; `format_summary` prints it at the end of a run.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

import numpy as np

from vistac.dataset.schema import failed_object_counts, redraw_counts
from vistac.errors import UserError
from vistac.progress import bar as progress_bar
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.objects.specs import ObjectSpec


def screen_objects(specs: list[ObjectSpec], cfg: GenerateCfg,
                   outcomes: Iterable[tuple[str | None, dict[str, int], list[str]]],
                   progress: bool = False
                   ) -> tuple[list[ObjectSpec], list[dict], dict[str, list[str]]]:
    """Keep the objects that give a valid grasp; the others are returned with their reasons.

    Args:
        specs: the object library.
        cfg: the run's config (`objects.strict`).
        outcomes: per spec, in order, what `vistac_sim.generate.screening.screen_object` found:
            None or the reason to skip it, its rejected draws, the repairs made to its mesh.
        progress: show a progress bar.

    Returns:
        The kept specs, the skipped objects (`object_id`, `path`, `reason`, `rejections`) and
        the repairs made to each mesh (by object id).

    Raises:
        UserError: with `objects.strict`, the first object skipped (named with its file); or
            when no object remains.
    """
    kept, skipped, repairs = [], [], {}
    bar = progress_bar(total=len(specs), desc="check objects", unit="obj", enabled=progress)
    for spec, (reason, rejections, notes) in zip(specs, outcomes, strict=True):
        bar.update()
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
    bar.close()
    if not kept:
        raise UserError("no object gave a valid grasp: " + "; ".join(
            f"{s['object_id']}: {s['reason']}" for s in skipped))
    return kept, skipped, repairs


def object_summary(configs: Mapping[str, np.ndarray], press_config_ids: np.ndarray,
                   objects: list[dict], skipped: list[dict],
                   repairs: dict[str, list[str]] | None = None) -> list[dict]:
    """Per object: status, configurations and presses accepted, rejected draws by reason.

    Args:
        configs: the run's configs columns `config_id`, `object_id`, `redraw_reasons` and
            `failed_objects`.
        press_config_ids: the presses table's `config_id` column.
        objects: the specs of the objects used (`object_id`, `path`).
        skipped: objects and meshes skipped before the run (`object_id` or `path`, `reason`,
            optional `rejections`).
        repairs: what was repaired in each mesh, by object id.
    """
    repairs = repairs or {}
    ids, counts = np.unique(np.asarray(press_config_ids), return_counts=True)
    presses_of = dict(zip(ids.tolist(), counts.tolist(), strict=True))
    n_configs: Counter = Counter()
    n_presses: Counter = Counter()
    rejections: dict[str, Counter] = {o["object_id"]: Counter() for o in objects}
    for cid, oid, cell in zip(np.asarray(configs["config_id"]).tolist(),
                              np.asarray(configs["object_id"]).tolist(),
                              configs["redraw_reasons"], strict=True):
        n_configs[oid] += 1
        n_presses[oid] += presses_of.get(cid, 0)
        rejections[oid].update(redraw_counts(cell))
    for cell in configs["failed_objects"]:
        for oid, counts in failed_object_counts(cell).items():
            rejections.setdefault(oid, Counter()).update(counts)
    rows = []
    for o in objects:
        oid = o["object_id"]
        rows.append({"object_id": oid, "path": o.get("path", ""), "status": "used",
                     "configurations": n_configs[oid], "presses": n_presses[oid],
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
