"""Synthetic recordings, images and spreadsheets for the `vistac ingest` tests (a test helper)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

N_COLS = 20  # docs/dataset-format.md: thumb F at 14-16, index F at 17-19
HEADER = ",".join(f"c{i}" for i in range(N_COLS))


# ------------------------------------------------------------------------- synthetic data
def press_series(plateaus, rng, noise=2.0, rest=25, rise=10, hold=40, fall=10, overshoot=0.05):
    """(T, 2, 3) force series in mN: rest, then per plateau (index, thumb) xyz vectors a press
    with a smooth rise, a peak `overshoot` above the plateau, the hold, a release, rest."""
    parts = [np.zeros((rest, 2, 3))]
    for p in plateaus:
        p = np.asarray(p, float)
        up = (1 - np.cos(np.linspace(0, np.pi, rise))) / 2
        relax = 1 + overshoot * np.exp(-np.arange(hold) / 5.0)
        down = (1 + np.cos(np.linspace(0, np.pi, fall))) / 2
        env = np.r_[up * (1 + overshoot), relax, down, np.zeros(rest)]
        parts.append(env[:, None, None] * p)
    series = np.concatenate(parts)
    return np.rint(series + rng.normal(0, noise, series.shape))


def write_csv(path: Path, series_mn: np.ndarray) -> Path:
    """A recording CSV in the contracts layout (other columns: filler integers)."""
    t = len(series_mn)
    table = np.zeros((t, N_COLS), dtype=np.int64)
    table[:, 0] = np.arange(t) * 20
    table[:, 1] = np.arange(t)
    table[:, 14:17] = series_mn[:, 1]  # thumb
    table[:, 17:20] = series_mn[:, 0]  # index
    body = "\n".join(",".join(map(str, r)) for r in table)
    path.write_text(HEADER + "\n" + body + "\n")
    return path


def write_png(path: Path, size: int = 32) -> Path:
    cv2.imwrite(str(path), np.full((size, size, 3), 200, np.uint8))
    return path


def direction(p) -> np.ndarray:
    """Unit (r_y, r_z) per finger of a (2, 3) force."""
    yz = np.asarray(p, float)[:, 1:]
    return yz / np.linalg.norm(yz, axis=1, keepdims=True)


PLATEAUS = {  # config id -> per press (index xyz, thumb xyz) in mN
    3: [[[10, 400, -1500], [0, -300, -1200]]] * 4,
    7: [[[0, -700, -2000], [5, 250, -1800]], [[0, -650, -2100], [5, 260, -1700]],
        [[0, -720, -1900], [5, 240, -1850]]],
    12: [[[0, 0, -900], [0, 100, -800]]] * 5,
}


def no_leftovers(out: Path) -> None:
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}.")]


def recordings_with_rejections(tmp_path: Path, with_good: bool = False) -> tuple[Path, Path]:
    """Folders ``rec`` and ``img``: recording 000001 with a saturated grasp between two good
    ones, 000002 with only a saturated one (dropped), and 000000 all good when `with_good`; one
    image per recording."""
    rng = np.random.default_rng(2)
    rec, img = tmp_path / "rec", tmp_path / "img"
    rec.mkdir()
    img.mkdir()
    good = [[0, 300, -1500], [0, -200, -1200]]
    sat = [[0, 300, -9990], [0, -200, -1200]]
    ids = [0, 1, 2] if with_good else [1, 2]
    if with_good:
        write_csv(rec / "000000.csv", press_series([good, good], rng))
    write_csv(rec / "000001.csv", press_series([good, sat, good], rng))
    write_csv(rec / "000002.csv", press_series([sat], rng))  # nothing usable: dropped
    for i in ids:
        write_png(img / f"{i:06d}.png")
    return rec, img
