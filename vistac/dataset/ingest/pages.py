"""Recordings as the study's operator saw them: each configuration's 50 Hz FTS-3 series (index
and thumb F_y, F_z) with its grasp segments, the chosen sample of each kept grasp and, for a
rejected grasp, the reason; one page (PNG) per recording and an index listing the recordings
with rejected grasps first (`vistac ingest --report DIR`, and `vistac inspect` of a dataset
with recordings).

The segments, samples and reasons are `preprocess` run on the series with the dataset's own
ingest settings (from its manifest; deterministic, so they are the ones `vistac ingest`
applied). An ingested dataset's recordings are read where it was ingested from (its manifest's
``sources.recordings``); a simulated dataset's (``--recordings``) from its ``recordings/``
folder, segmented with the default ingest settings. matplotlib is imported only to draw.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vistac.config import apply
from vistac.dataset.files import atomic_write_bytes
from vistac.dataset.ingest.config import IngestCfg
from vistac.dataset.ingest.preprocess import RecordedGrasp, preprocess
from vistac.dataset.ingest.readers import read_recording
from vistac.dataset.reader import DatasetTables
from vistac.dataset.recordings import recording_name
from vistac.errors import UserError

RATE_HZ = 50.0
"""The FTS-3 log's sample rate."""
SERIES = ((0, 1, "index F_y", "tab:green", "--"), (0, 2, "index F_z", "tab:green", "-"),
          (1, 1, "thumb F_y", "tab:red", "--"), (1, 2, "thumb F_z", "tab:red", "-"))
"""(finger, component, label, colour, style) of the plotted series."""


@dataclass
class RecordingPage:
    """One recording's page: where it is, its grasps and what became of them."""

    config_id: int
    source: Path
    grasps: list[RecordedGrasp]
    page: str = ""  # file name of the PNG under the report's recordings/ folder
    error: str = ""  # why the recording could not be read

    @property
    def rejected(self) -> list[RecordedGrasp]:
        return [g for g in self.grasps if g.reason is not None]


def recording_sources(tables: DatasetTables) -> tuple[list[tuple[int, Path]], IngestCfg, str]:
    """The (config_id, CSV path) of each recording, the ingest settings to segment them with
    and a note ('' when every recording was found)."""
    man = tables.manifest
    root = tables.root
    cfg = IngestCfg()
    ingest_cfg = (man.get("config") or {}).get("ingest")
    if ingest_cfg:
        try:
            cfg = apply(cfg, ingest_cfg, where=str(root / "manifest.json"))
        except UserError:
            pass  # settings of another version: the defaults
    c = tables.configs
    pairs: list[tuple[int, Path]] = []
    if man.get("generator") == "vistac ingest":
        folder = (man.get("sources") or {}).get("recordings")
        if not folder or "recording" not in c:
            return [], cfg, ""
        folder = Path(folder)
        ids = dict(zip(c["recording"].astype(str), c["config_id"].astype(int), strict=True))
        for row in (man.get("dropped_configs") or []):  # recordings without a kept grasp
            ids.setdefault(f"{row.get('name')}.csv", int(row.get("config_id", -1)))
        pairs = sorted(((cid, folder / name) for name, cid in ids.items() if name),
                       key=lambda p: p[0])
        if not folder.is_dir():
            return [], cfg, (f"{folder}: the recordings this dataset was ingested from are not "
                             "there any more; no recordings pages")
    elif (root / "recordings").is_dir() and "config_id" in c:
        pairs = [(int(cid), root / "recordings" / recording_name(int(cid)))
                 for cid in c["config_id"]]
    missing = [p for _, p in pairs if not p.is_file()]
    note = (f"{missing[0].parent}: {len(missing)} of {len(pairs)} recordings missing (first: "
            f"{missing[0].name})") if missing else ""
    return pairs, cfg, note


def plot_page(forces: np.ndarray, page: RecordingPage, out: Path) -> None:
    """One recording's page: the four series, its segments shaded (kept green, rejected red,
    with the reason), each kept grasp's chosen sample marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(len(forces)) / RATE_HZ
    fig, ax = plt.subplots(figsize=(9, 3.4))
    for fi, comp, label, colour, style in SERIES:
        ax.plot(t, forces[:, fi, comp], style, color=colour, lw=1, label=label)
    top = float(np.nanmax(np.abs(forces[:, :, 1:]))) if forces.size else 1.0
    for g in page.grasps:
        a, b = g.start / RATE_HZ, (g.end - 1) / RATE_HZ
        kept = g.reason is None
        ax.axvspan(a, b, color="tab:green" if kept else "tab:red", alpha=0.12, lw=0)
        ax.text(a, top * 1.02, f"#{g.repeat} " + ("kept" if kept else g.reason),
                fontsize=7, color="darkgreen" if kept else "darkred", va="bottom")
        if kept and g.sample is not None:
            ax.axvline(g.sample / RATE_HZ, color="k", lw=0.8)
    ax.set_ylim(-top * 1.1, top * 1.25)
    ax.set_xlabel(f"time (s, {RATE_HZ:g} Hz)", fontsize=8)
    ax.set_ylabel("force (N, sensor frame)", fontsize=8)
    status = (f"{len(page.rejected)} of {len(page.grasps)} grasps rejected"
              if page.rejected else f"{len(page.grasps)} grasps, all kept")
    ax.set_title(f"configuration {page.config_id}: {page.source.name} ({status})", fontsize=9)
    ax.tick_params(labelsize=8)
    ax.legend(fontsize=7, ncol=4, loc="lower right")
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)


def recording_pages(tables: DatasetTables, out: Path, max_pages: int) -> tuple[
        list[RecordingPage], list[str]]:
    """Write a page per recording (rejected first, at most `max_pages`) into folder `out`;
    returns every recording's page record (sorted rejected first) and notes."""
    pairs, cfg, note = recording_sources(tables)
    notes = [note] if note else []
    loaded: list[tuple[RecordingPage, np.ndarray | None]] = []
    for cid, path in pairs:
        if not path.is_file():
            continue
        try:
            forces = read_recording(path, cfg)
        except UserError as exc:
            loaded.append((RecordingPage(cid, path, [], error=str(exc)), None))
            continue
        loaded.append((RecordingPage(cid, path, preprocess(forces, cfg)), forces))
    loaded.sort(key=lambda pf: (not (pf[0].rejected or pf[0].error), pf[0].config_id))
    if loaded:
        out.mkdir(parents=True, exist_ok=True)
    for i, (p, forces) in enumerate(loaded):
        if forces is not None and i < max_pages:
            p.page = f"{p.config_id:06d}.png"
            plot_page(forces, p, out / p.page)
    pages = [p for p, _ in loaded]
    if len(pages) > max_pages:
        notes.append(f"{len(pages)} recordings: pages for the first {max_pages} (rejected "
                     "first; --max-pages)")
    return pages, notes


def index_lines(pages: list[RecordingPage], folder: str) -> list[str]:
    """The markdown index of the recordings (rejected grasps first), pages linked."""
    lines = ["| configuration | recording | grasps | kept | rejected (reason) | page |",
             "|---|---|---|---|---|---|"]
    for p in pages:
        why = p.error or ", ".join(f"#{g.repeat} {g.reason}" for g in p.rejected) or "-"
        link = f"[page]({folder}/{p.page})" if p.page else "-"
        lines.append(f"| {p.config_id} | {p.source.name} | {len(p.grasps)} | "
                     f"{len(p.grasps) - len(p.rejected)} | {why} | {link} |")
    return lines


INTRO = ("Each recording's 50 Hz series (index and thumb F_y, F_z), its grasp segments (green "
         "kept, red rejected, with the reason) and each kept grasp's chosen sample (black line); "
         "recordings with rejected grasps first.")


def write_recordings_report(tables: DatasetTables, out: Path, max_pages: int = 100
                            ) -> tuple[list[RecordingPage], list[str]]:
    """`vistac ingest --report`: the pages under ``out/recordings/`` and ``out/report.md``
    (their index); returns the pages and the notes (also in the report)."""
    out.mkdir(parents=True, exist_ok=True)
    pages, notes = recording_pages(tables, out / "recordings", max_pages)
    md = [f"# Recordings of `{tables.root}`", "", *[f"- note: {n}" for n in notes], "", INTRO,
          "", *index_lines(pages, "recordings"), ""]
    atomic_write_bytes(out / "report.md", "\n".join(md).encode())
    return pages, notes
