"""`vistac inspect`'s report folders: a dataset's (summary, contact sheet, distributions,
recordings pages) and a run's (worst configurations beside the metrics), each with a
`report.md` that embeds its figures by relative links (it renders on a code host and on a
dataset hub). Nothing is printed here; the lines are returned for the CLI.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vistac.dataset.card import write_card
from vistac.dataset.files import atomic_write_bytes
from vistac.dataset.ingest.pages import INTRO, index_lines, recording_pages
from vistac.dataset.schema import CARD, MANIFEST
from vistac.errors import UserError
from vistac_learn.inspect import distributions
from vistac_learn.inspect.config import InspectCfg
from vistac_learn.inspect.readable import read_readable
from vistac_learn.inspect.sheet import contact_sheet
from vistac_learn.inspect.summary import redraw_reasons, rejected_grasps, summary_lines

REPORT = "report.md"
SHEET = "contact_sheet.png"
LEGEND = ("At each fingertip: the black arrow is the mean label of the configuration's presses "
          "(the force of the object on the fingertip, drawn in the image from the finger's "
          "sensor frame), the orange lines each press (the cone); the captions give config_id, "
          "split and object family. A label in the wrong frame points into the object or "
          "along the finger instead of away from the contact.")


@dataclass
class InspectReport:
    """What `vistac inspect` made.

    Attributes:
        out: The report folder.
        lines: The summary (what the CLI prints).
        files: The files written under `out`.
        card: The dataset card written for a dataset that had none (None otherwise).
        seconds: Wall time.
    """

    out: Path
    lines: list[str]
    files: list[str] = field(default_factory=list)
    card: Path | None = None
    seconds: float = 0.0


def _check_out(out: Path, inspected: Path) -> None:
    out_r, ins_r = out.resolve(), inspected.resolve()
    if out_r == ins_r or ins_r in out_r.parents:
        raise UserError(f"{out}: inside {inspected}; the report goes outside what it inspects "
                        "(choose another --out)")
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder; choose another --out")


def inspect_dataset(root: str | Path, cfg: InspectCfg | None = None) -> InspectReport:
    """Inspect dataset folder `root` into `cfg.out_dir(root)` (see the module).

    Raises:
        UserError: `root` holds nothing of a dataset, or the report folder is unusable.
    """
    t0, cfg = time.perf_counter(), cfg or InspectCfg()
    root = Path(root)
    out = cfg.out_dir(root)
    _check_out(out, root)
    readable = read_readable(root)
    out.mkdir(parents=True, exist_ok=True)
    t = readable.tables
    rep = InspectReport(out, [])
    if not (root / CARD).exists() and t.manifest.get("complete") is True:  # finished only
        rep.card = write_card(root, t.manifest)
    sheet: dict = {"rows": [], "not_found": {}}
    if len(t.configs) and "image" in t.configs:
        sheet = contact_sheet(t, out / SHEET, per_group=cfg.per_group, max_tiles=cfg.max_tiles,
                              columns=cfg.columns, size=cfg.tile, seed=cfg.seed,
                              missing=set(readable.missing_images.tolist()))
    if sheet.get("unreadable"):
        readable.notes.append(f"{root / 'images'}: {len(sheet['unreadable'])} of the contact "
                              f"sheet's images unreadable (first: {sheet['unreadable'][0]})")
    stats = distributions.label_stats(t)
    figures = {}
    for by in ("family", "split"):
        name = f"labels_by_{by}.png"
        if distributions.plot_labels(stats, by, out / name):
            figures[by] = name
    reasons = {"rejected grasp draws (simulation)": redraw_reasons(readable),
               "rejected recorded grasps (ingest)": rejected_grasps(readable)}
    if distributions.plot_reasons(reasons, out / "reasons.png"):
        figures["reasons"] = "reasons.png"
    effects = distributions.plot_effects(t.configs, out / "effects.png") \
        if len(t.configs) else []
    pages, page_notes = recording_pages(t, out / "recordings", cfg.max_pages)
    readable.notes += page_notes
    rep.lines = summary_lines(readable, sheet["not_found"])
    med = distributions.angle_summary(stats)
    for f, m in med.items():
        if np.isfinite(m["angle_deg"]):
            rep.lines.append(f"{f}: median |label angle| {m['abs_angle_deg']:.1f} deg, median "
                             f"cone width {m['cone_width_deg']:.1f} deg"
                             + (f", median |F| {m['force_n']:.2f} N"
                                if np.isfinite(m["force_n"]) else ""))
    if pages:
        n_rej = sum(1 for p in pages if p.rejected or p.error)
        rep.lines.append(f"recordings: {len(pages)} ({n_rej} with rejected grasps), pages in "
                         f"{out / 'recordings'}")
    md = [f"# Dataset report: `{root}`", "", *[f"- {line}" for line in rep.lines], ""]
    if sheet["rows"]:
        md += ["## Contact sheet", "", LEGEND, "", f"![contact sheet]({SHEET})", ""]
    for by in ("family", "split"):
        if by in figures:
            md += [f"## Labels by {by}", "", f"![labels by {by}]({figures[by]})", ""]
    if "reasons" in figures:
        md += ["## Rejections by reason", "", "![reasons](reasons.png)", ""]
    if effects:
        md += ["## Image effects' draws", "", "![effects](effects.png)", ""]
    if pages:
        md += ["## Recordings", "", INTRO, "", *index_lines(pages, "recordings"), ""]
    atomic_write_bytes(out / REPORT, "\n".join(md).encode())
    rep.files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    rep.seconds = time.perf_counter() - t0
    return rep


def inspect_run_folder(run: str | Path, cfg: InspectCfg | None = None) -> InspectReport:
    """Inspect run folder `run` into `cfg.out_dir(run)`: the worst configurations of its
    evaluation on `cfg.split` beside its metrics table.

    Raises:
        UserError: not a run, no evaluation, or its dataset unreadable.
    """
    from vistac_learn.inspect.runs import inspect_run

    t0, cfg = time.perf_counter(), cfg or InspectCfg()
    run = Path(run)
    out = cfg.out_dir(run)
    _check_out(out, run)
    out.mkdir(parents=True, exist_ok=True)
    res = inspect_run(run, out, worst=cfg.worst, columns=min(cfg.columns, 4), size=cfg.tile,
                      split=cfg.split)
    worst, fingers = res["worst"], res["fingers"]
    lines = [f"run {run}: evaluation {res['evaluation']} on {res['data']}",
             *str(res["metrics"].get("table", "")).splitlines()]
    if len(worst):
        lines.append(f"worst {len(worst)} configurations (angle to the mean label, deg): "
                     + ", ".join(f"{cid} {e:.1f}" for cid, e in worst["error_deg"].items()))
    table = ["| config_id | " + " | ".join(f"{f} (deg)" for f in fingers) + " |",
             "|---|" + "---|" * len(fingers)]
    table += [f"| {cid} | " + " | ".join(f"{r[f'{f}_angle_to_mean_deg']:.1f}" for f in fingers)
              + " |" for cid, r in worst.iterrows()]
    md = [f"# Run report: `{run}`", "", f"Evaluation: `{res['evaluation']}`", "", "```",
          str(res["metrics"].get("table", "")), "```", "",
          "## Worst configurations", "",
          "Black: the mean label and (orange) the presses; blue: the model's prediction "
          f"(averaged over rotations); captions: config_id and the angle to the mean label per "
          f"finger ({', '.join(fingers)}).", "", "![worst configurations](worst.png)", "",
          *table, ""]
    atomic_write_bytes(out / REPORT, "\n".join(md).encode())
    rep = InspectReport(out, lines)
    rep.files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    rep.seconds = time.perf_counter() - t0
    return rep


def inspect_path(path: str | Path, cfg: InspectCfg | None = None) -> InspectReport:
    """A run folder (it has ``config.json``) or a dataset folder, inspected."""
    p, cfg = Path(path), cfg or InspectCfg()
    if (p / "config.json").is_file() and not (p / MANIFEST).exists():
        return inspect_run_folder(p, cfg)
    return inspect_dataset(p, cfg)

