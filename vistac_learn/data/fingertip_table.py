"""A dataset's located fingertips, cached (`fingertip_table`, `FingertipTable`), those of some
given images (`located_in`), and the simulator's own tips in image coordinates
(`simulator_tips`; as a table, with the drawn radius: `simulator_fingertips`) to compare them
with. The locating itself is `vistac_learn.data.fingertips`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.files import remove_stale_temporaries, write_table
from vistac.dataset.schema import PIXEL_CENTRE
from vistac.errors import UserError
from vistac.progress import bar as progress_bar
from vistac.projection import Projection, displace, overlay_from_columns, rotz
from vistac_learn.data import fingertips
from vistac_learn.data.fingertips import FIELDS, Fingertip, LocatorCfg
from vistac_learn.data.locator import locate_fingertips
from vistac_learn.data.variants import read_rgb


def simulator_tips(tables: DatasetTables, row: int, size: int
                   ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The simulator's fingertip centre (pixels) and unit finger axis (image u, v) of each finger
    of a configuration as the image draws it, from ``configs.parquet`` (what the locator is
    measured against), in the locator's coordinates: pixel centres at integers (the projection's
    continuous coordinates less `PIXEL_CENTRE`; comparing the two unconverted put every located
    tip 0.71 px off).

    The fingertip lies at the hand's height above the table (the manifest's ``hand.height``),
    is moved as the drawn finger was (`vistac.projection.displace` about the sensor site, the
    ``overlay_<finger>_*`` columns) and projected by the image's camera
    (`vistac.projection.Projection.from_columns`: the plain top view, a tilted one, or the
    ``photo`` preset's perspective phone camera).

    Args:
        tables: The dataset.
        row: Configuration row.
        size: Side of the (square) image in pixels.
    """
    return {f: (t.tip, t.axis) for f, t in _drawn_tips(tables, row, size).items()}


def simulator_fingertips(tables: DatasetTables, size: int) -> FingertipTable:
    """A fingertip table of the simulator's fingertips as every image draws them
    (`simulator_tips`), with the drawn fingertip's radius: what a perfect locator would find."""
    cids = tables.configs["config_id"].to_numpy()
    return FingertipTable(pd.DataFrame([record(int(cids[r]), _drawn_tips(tables, r, size))
                                        for r in range(len(tables.configs))]))


def _drawn_tips(tables: DatasetTables, row: int, size: int) -> dict[str, Fingertip]:
    """`simulator_tips` with the radius in pixels of the fingertip as drawn: the pad's radius
    at its place in the image, times the drawn width (``drawn_<finger>_width``), plus half the
    drawn outline (``drawn_outline_px``)."""
    c = tables.configs.iloc[row]
    proj = Projection.from_columns(c, size)
    hand = tables.hand
    out = {}
    for f in FINGERS:
        tip = np.array([c[f"tip_{f}_x"], c[f"tip_{f}_y"], hand.get("height", 0.0)], float)
        step = np.array([c[f"approach_{f}_x"], c[f"approach_{f}_y"], 0.0], float)
        overlay = overlay_from_columns(c, f)
        if any(overlay):  # turned about the sensor site, on the pad's front
            site = tip + hand.get("tip_radius", 0.0) * step / np.linalg.norm(step)
            tip, step = displace(tip, site, overlay), rotz(overlay[2]) @ step
        axis = proj.direction(tip, step)
        radius = (hand.get("tip_radius", np.nan) * float(proj.px_per_m_at(tip))
                  * _column(c, f"drawn_{f}_width", 1.0) + _column(c, "drawn_outline_px", 0.0) / 2)
        out[f] = Fingertip(proj.project(tip) - PIXEL_CENTRE, axis / np.linalg.norm(axis),
                           float(radius))
    return out


def _column(row: pd.Series, key: str, default: float) -> float:
    """A configuration's value of an optional column (absent or NaN: `default`)."""
    v = row.get(key)
    return float(v) if v is not None and np.isfinite(float(v)) else default


class FingertipTable:
    """The located fingertips of every configuration of a dataset (one row per configuration).

    Columns: ``<finger>_<field>`` for `FIELDS`, ``<finger>_ok`` and ``<finger>_reason``.
    """

    def __init__(self, frame: pd.DataFrame):
        self.frame = frame

    def get(self, row: int, finger: str) -> Fingertip:
        """The fingertip of one configuration row."""
        fr = self.frame
        if not bool(fr[f"{finger}_ok"].iat[row]):
            return Fingertip.missing(str(fr[f"{finger}_reason"].iat[row]))
        v = [float(fr[f"{finger}_{k}"].iat[row]) for k in FIELDS]
        return Fingertip(np.array(v[:2]), np.array(v[2:4]), v[4])

    def failures(self, rows: np.ndarray, finger: str) -> int:
        """Configurations among `rows` whose finger was not found."""
        return int((~self.frame[f"{finger}_ok"].to_numpy()[rows]).sum())


def record(config_id: int, found: dict[str, Fingertip]) -> dict:
    """One row of a fingertip table."""
    rec = {"config_id": config_id}
    for f in FINGERS:
        t = found[f]
        rec |= dict(zip((f"{f}_{k}" for k in FIELDS), (*t.tip, *t.axis, t.radius), strict=True))
        rec |= {f"{f}_ok": t.ok, f"{f}_reason": t.reason}
    return rec


def located_in(tables: DatasetTables, rows: np.ndarray, images: list[np.ndarray],
               cfg: LocatorCfg | None = None) -> FingertipTable:
    """A fingertip table (not cached) of the given images of some rows, e.g. perturbed copies;
    the dataset's other rows are marked not found."""
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    cfg = cfg or LocatorCfg()
    by_row = {int(r): img for r, img in zip(rows, images, strict=True)}
    missing = {f: Fingertip.missing("not among the located images") for f in FINGERS}
    cids = tables.configs["config_id"].to_numpy()
    recs = [record(int(cids[r]), locate_fingertips(by_row[r], colours, cfg) if r in by_row
                    else missing) for r in range(len(tables.configs))]
    return FingertipTable(pd.DataFrame(recs))


def locator_fingerprint(cfg: LocatorCfg) -> str:
    """What a located fingertip depends on besides the image: the locator's version, its
    settings and, when the segmenter is used, a digest of its weights (retrained weights locate
    anew). Part of every cache key of results made from located fingertips."""
    key = json.dumps({"v": fingertips.LOCATOR_VERSION, **asdict(cfg)}, sort_keys=True)
    if cfg.segmenter != "off":
        from vistac_learn.data.segmenter import weights_digest

        key += weights_digest()
    return key


def cache_path(tables: DatasetTables, cfg: LocatorCfg, cache_dir: Path | None,
               kind: str = "fingertips") -> Path:
    """Where a table located in a dataset's images is cached (`kind`: ``fingertips``, or the
    finger boxes', `vistac_learn.data.located_boxes`): keyed by the locator and the images."""
    h = hashlib.sha256()
    h.update(locator_fingerprint(cfg).encode())
    h.update(tables.image_fingerprint().encode())  # labels do not move a fingertip
    folder = cache_dir if cache_dir is not None else tables.root / "cache"
    return Path(folder) / f"{kind}-{h.hexdigest()[:20]}.parquet"


def _read_cache(path: Path, tables: DatasetTables) -> FingertipTable | None:
    """The cached table at `path`, or None when absent or damaged (truncated, other columns,
    other configurations): a damaged cache is located again and rewritten, never an error."""
    if not path.is_file():
        return None
    try:
        frame = pd.read_parquet(path)
        cols = ["config_id", *(f"{f}_{k}" for f in FINGERS for k in (*FIELDS, "ok", "reason"))]
        ids = frame["config_id"].to_numpy()
        if not all(c in frame for c in cols) or len(frame) != len(tables.configs) \
                or not (ids == tables.configs["config_id"].to_numpy()).all() \
                or not all(frame[f"{f}_ok"].dtype == bool for f in FINGERS):
            return None
    except Exception:  # a damaged file: pyarrow's errors have no common base
        return None
    return FingertipTable(frame)


def fingertip_table(tables: DatasetTables, cfg: LocatorCfg = LocatorCfg(),
                    cache_dir: str | Path | None = None, progress: bool = False
                    ) -> FingertipTable:
    """The fingertips of every configuration, located once and cached as a small Parquet table.

    The table grows by one row per configuration (about 100 bytes), whatever the image size.

    Raises:
        UserError: An unreadable image or an unwritable cache folder.
    """
    path = cache_path(tables, cfg, Path(cache_dir) if cache_dir is not None else None)
    cached = _read_cache(path, tables)
    if cached is not None:
        return cached
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    rows = []
    for row in progress_bar(range(len(tables.configs)), desc="locating fingertips",
                            unit="img", enabled=progress, leave=False):
        found = locate_fingertips(read_rgb(tables.image_path(row)), colours, cfg)
        rows.append(record(int(tables.configs["config_id"].iat[row]), found))
    frame = pd.DataFrame(rows)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path.parent)  # what a killed run left
        write_table(path, frame)
    except OSError as exc:
        raise UserError(f"{path.parent}: cannot write the fingertip cache ({exc}); "
                        "choose another with --cache-dir") from exc
    return FingertipTable(frame)
