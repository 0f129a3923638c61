"""The samples of one split as a torch `Dataset`, rendered item by item from the dataset's images.

A sample is (configuration, rotation[, press]). Its image is decoded from the dataset's PNG and
turned into the model's input by a view (`vistac_learn.data.views`) when the item is asked for;
nothing per rotation or per augmentation is stored, so memory stays flat as the dataset grows
(one batch of decoded images at a time, plus the per-configuration tables), except that a
sample which is the same at every epoch (no augmentation, no random rotation: the study's
protocol, every validation and test split) is rendered once and kept, up to `RENDER_CACHE_BYTES`
per set, so that later epochs pay only for the network. Batches come from a
torch `DataLoader` (`vistac_learn.data.loading`); a batch's samples are rendered by two threads
while the training step waits (`SampleSet.__getitems__`).

An item is a pure function of (epoch, index): ``ds[i]`` is sample i at epoch 0 and
``ds[epoch, i]`` sample i at an epoch, whatever was asked for before and in whichever loader
worker; a resumed run, a shuffled order or several workers see the same samples.

Rotations (`RotationCfg`): ``none`` (one sample per configuration), ``fixed`` (n samples per
configuration at angles k * step, the study's 20 x 18 degrees) or ``random`` (n samples per
configuration, each at an angle drawn anew every epoch). Augmentation (`AugmentCfg`, training
only): mirror, for the tip view crop jitter, and optionally appearance perturbations toward
photographs (`vistac_learn.data.perturb`), drawn per sample from (seed, epoch, sample), so a
resumed run replays exactly what an uninterrupted one saw.

Targets from the repeats of a configuration (`target`):

- ``"mean"`` (default): the mean of the repeats' unit vectors, renormalised (a zero mean falls
  back to (0, -1)); the least noisy target.
- ``"press"``: one repeat per sample, drawn anew each epoch from (seed, epoch).
- ``"all"``: every press is its own sample.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch
from torch.utils.data import get_worker_info

from vistac.config import Config, param
from vistac.dataset import FINGERS, DatasetTables
from vistac.errors import UserError
from vistac_learn.data.contacts import contact_truth
from vistac_learn.data.fingertip_table import FingertipTable
from vistac_learn.data.fingertips import Fingertip, read_rgb
from vistac_learn.data.located_boxes import BoxTable, box_table, missing_boxes
from vistac_learn.data.perturb import (
    Scene,
    is_flat_render,
    map_direction,
    map_points,
    perturb_axes,
    random_axes,
    segment,
)
from vistac_learn.data.rotations import ROTATION_MODES, RotationCfg  # noqa: F401 (re-exported)
from vistac_learn.data.views import IDENTITY, Aug, SampleInfo, View

Item = dict[str, np.ndarray]  # one sample: what `SampleSet.__getitem__` returns
Key = int | tuple[int, int]  # sample index, or (epoch, sample index)

TARGETS = ("mean", "press", "all")
RENDER_CACHE_BYTES = 1 << 30
"""Rendered samples a `SampleSet` keeps when they are the same at every epoch (1 GiB: 100 000
study inputs of 100 x 100 pixels); the rest are rendered each time."""
FINGER_CHOICES = (*FINGERS, "both")  # the values of a `--finger` option


def fingers_of(finger: str) -> tuple[str, ...]:
    """Fingers named by a `--finger` option: ``index``, ``thumb`` or ``both``."""
    if finger == "both":
        return FINGERS
    if finger in FINGERS:
        return (finger,)
    raise UserError(f"--finger must be {', '.join(FINGER_CHOICES)}, not {finger!r}")


@dataclass(frozen=True)
class AugmentCfg(Config):
    """Training-time augmentation, drawn per sample (identity at evaluation)."""

    mirror: bool = param(True, help="flip half of the samples left-right (r_y -> -r_y)")
    shift: float = param(0.1, ge=0, le=1, help="tip view: crop-centre jitter, fingertip radii")
    turn: float = param(2.0, ge=0, le=45, help="tip view: crop-angle jitter, degrees")
    scale: float = param(0.05, ge=0, lt=0.5, help="tip view: crop-side jitter, fraction")
    appearance: float = param(0.0, ge=0, le=1, help="share of the images perturbed toward "
                              "photographs (`vistac_learn.data.perturb.random_axes`)")
    appearance_axes: float = param(0.5, gt=0, le=1, help="a perturbed image: probability of "
                                   "each appearance axis (at least one is drawn)")

    def draw(self, rng: np.random.Generator, angle: float) -> Aug:
        """One sample's parameters."""
        u = rng.uniform(-1.0, 1.0, 4)
        mirror = bool(self.mirror and rng.random() < 0.5)
        seed = int(rng.integers(2**31)) if self.appearance > 0 and \
            rng.random() < self.appearance else -1
        return Aug(angle=angle, mirror=mirror,
                   shift=(float(u[0] * self.shift), float(u[1] * self.shift)),
                   turn=float(u[2] * self.turn), scale=float(1.0 + u[3] * self.scale),
                   appearance=seed)


def moved_fingertip(t: Fingertip, hom: np.ndarray) -> Fingertip:
    """A located fingertip moved by an image homography (centre, axis and radius; a missing
    one stays missing)."""
    if not t.ok:
        return t
    tip = map_points(hom, t.tip[None])[0]
    edge = map_points(hom, (t.tip + t.radius * np.array([-t.axis[1], t.axis[0]]))[None])[0]
    return Fingertip(tip, map_direction(hom, t.tip, t.axis), float(np.hypot(*(edge - tip))))


def perturb_sample(rgb: np.ndarray, info: SampleInfo, finger_rgb: dict[str, tuple],
                   rng: np.random.Generator, p_axis: float = 0.5
                   ) -> tuple[np.ndarray, SampleInfo]:
    """A clean render perturbed toward a photograph along a random set of axes, each drawn
    with probability `p_axis` (`vistac_learn.data.perturb.random_axes`; a photograph, whose
    regions its colours do not give, along the image-level axes only), with its fingertips,
    finger boxes and the simulator's contacts moved by the tilt."""
    scene = Scene(segment(rgb, finger_rgb, info.table_rgb), finger_rgb)
    out = perturb_axes(random_axes(rng, p_axis, is_flat_render(scene.labels)), rgb, scene, rng)
    hom = out.homography
    if np.allclose(hom, np.eye(3)):
        return out.rgb, info
    tips = {f: moved_fingertip(t, hom) for f, t in info.tips.items()}
    boxes = {}
    for f, b in info.boxes.items():
        if b is None:
            boxes[f] = None
            continue
        x, y, w, h = b
        c = map_points(hom, np.array([[x, y], [x + w, y], [x, y + h], [x + w, y + h]]))
        lo, hi = c.min(axis=0), c.max(axis=0)
        boxes[f] = np.array([lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]])
    # the simulator's contacts move with the image: the point and the finger axis (pixels);
    # the normal is in the sensor frame, which a slight tilt of the camera does not turn
    contacts = {f: (map_points(hom, np.asarray(p, float)[None])[0], n,
                    map_direction(hom, np.asarray(p, float), np.asarray(a, float)))
                for f, (p, n, a) in info.contacts.items()}
    return out.rgb, SampleInfo(boxes, tips, info.table_rgb, contacts)


@dataclass(frozen=True)
class SampleSpec:
    """What each sample of a `SampleSet` is, whichever rows it comes from: the model's input
    (view, size), its target (fingers, `target`) and how a sample is drawn (rotations,
    augmentation or test-time mirroring, seed).

    Attributes:
        view: What the model sees.
        size: Side of the rendered input.
        fingers: Fingers whose labels form the target, in order (2 values per finger).
        target: ``mean``, ``press`` or ``all``.
        seed: Seed of press draws, random angles and augmentation.
        rotations: Samples per configuration and their angles.
        augment: Augmentation (None: none, as at evaluation).
        mirror: Every sample mirrored, its r_y negated (test-time augmentation; only without
            `augment`, which draws its own mirrors).
    """

    view: View
    size: int
    fingers: tuple[str, ...]
    target: str = "mean"
    seed: int = 0
    rotations: RotationCfg = RotationCfg()
    augment: AugmentCfg | None = None
    mirror: bool = False

    def __post_init__(self):
        object.__setattr__(self, "fingers", tuple(self.fingers))
        if self.target not in TARGETS:
            raise UserError(f"target must be one of {', '.join(TARGETS)}, not {self.target!r}")
        if self.mirror and self.augment is not None:
            raise ValueError("mirror (every sample) and augment (drawn mirrors) exclude "
                             "each other")


class SampleSet(torch.utils.data.Dataset):
    """The samples of some configuration rows, one rendered sample per item.

    Args:
        tables: The dataset.
        rows: Configuration rows.
        spec: What each sample is (view, size, fingers, target, rotations, augmentation,
            mirroring, seed); its settings are also attributes of the set.
        tips: Located fingertips (required by views that need them).
        boxes: Finger boxes for views that need boxes the dataset lacks (``bbox_*`` NaN, as
            `vistac ingest` leaves them): the dataset's own where finite, located in the
            image elsewhere (`vistac_learn.data.located_boxes`; located here, cached in the
            dataset's folder, when not given). A finger with no box masks its row out
            (`found`), as a fingertip not found does.
        images: Where a configuration row's image comes from (default: decoded from the
            dataset), e.g. perturbed copies for a stress test.
        threads: Threads rendering a batch's samples in the training process (see
            `__getitems__`).
    """

    def __init__(self, tables: DatasetTables, rows: np.ndarray, spec: SampleSpec,
                 tips: FingertipTable | None = None,
                 images: Callable[[int], np.ndarray] | None = None, threads: int = 2,
                 boxes: BoxTable | None = None):
        view, target, rotations, augment = spec.view, spec.target, spec.rotations, spec.augment
        if view.needs_tips and tips is None:
            raise ValueError(f"view {view.name} needs located fingertips")
        located = missing_boxes(tables, view.needs_boxes)
        if located and boxes is None:
            boxes = box_table(tables)
        self.boxes = boxes if located else None  # the dataset's own boxes wherever it has all
        self.tables, self.spec = tables, spec
        # the spec's settings, read per sample here and by scoring and evaluation
        self.view, self.size, self.fingers = view, spec.size, spec.fingers
        self.target, self.seed, self.rotations, self.augment = target, spec.seed, rotations, augment
        self.mirror = spec.mirror
        self.tips, self.threads = tips, threads
        self.images = images
        self._finger_rgb = {f: tables.finger_rgb(f) for f in FINGERS}
        self.rows = np.asarray(rows, dtype=np.int64)
        n_rot = rotations.count
        self.item_row = np.repeat(self.rows, n_rot)
        self.item_rot = np.tile(np.arange(n_rot), len(self.rows))
        self.item_press = np.full(len(self.item_row), -1, dtype=np.int64)
        if target == "all":
            reps = np.array([len(tables.cones[self.fingers[0]][r]) for r in self.item_row])
            self.item_row = np.repeat(self.item_row, reps)
            self.item_rot = np.repeat(self.item_rot, reps)
            self.item_press = np.concatenate([np.arange(k) for k in reps]).astype(np.int64)
        self._mean = np.concatenate([tables.mean_label(f) for f in self.fingers], axis=1)
        ok = [tips.frame[f"{f}_ok"].to_numpy() if view.needs_tips else
              np.ones(len(tables.configs), bool) for f in self.fingers]
        self._found = np.stack(ok, axis=1)
        if self.boxes is not None:  # a row with a needed finger's box not found: no input
            boxed = np.logical_and.reduce([self.boxes.frame[f"{f}_ok"].to_numpy(bool)
                                           for f in view.needs_boxes])
            self._found &= boxed[:, None]
        self._table_rgb = tables.table_rgb
        self._contacts = contact_truth(tables) if view.needs_contacts else None
        self._draws: tuple[int, np.ndarray] | None = None  # (epoch, press draws), see targets
        # rendered samples that no epoch changes (see `render`): item -> render's result
        self._cache_on = augment is None and rotations.mode != "random"
        self._cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, Aug]] = {}
        self._cache_bytes = 0

    def __len__(self) -> int:
        return len(self.item_row)

    def __getitem__(self, key: Key) -> Item:
        """Sample `key` (an index, or (epoch, index)): its rendered input, augmented target,
        auxiliary targets (NaN where unknown), found-mask and ids, as NumPy arrays."""
        epoch, item = (0, key) if np.isscalar(key) else key
        epoch, item = int(epoch), int(item)
        if not 0 <= item < len(self):
            raise IndexError(f"sample {item} of {len(self)}")
        image, side, aux, aug = self.render(item, epoch)
        target = self.targets(np.array([item]), epoch)[0]
        if aug.mirror:
            target[0::2] *= -1  # r_y of every finger changes sign in a mirrored view
        return {"image": image, "side": side, "aux": aux, "target": target,
                "found": self._found[self.item_row[item]],
                "row": self.item_row[item], "rot": self.item_rot[item]}

    def __getitems__(self, keys: Sequence[Key]) -> list[Item]:
        """A batch's samples, `self[k]` for each key (torch's batched fetch, which a
        `DataLoader` calls). In the training process they are rendered by `threads` threads
        (OpenCV releases the GIL) while the training step waits, so that rendering uses the
        cores torch's own threads leave idle meanwhile; in a loader worker, one by one."""
        if self.threads < 2 or len(keys) < 2 or get_worker_info() is not None:
            return [self[k] for k in keys]
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            return list(pool.map(self.__getitem__, keys))

    # ------------------------------------------------------------------ per-sample parameters
    def aug(self, item: int, epoch: int) -> Aug:
        """The sample's augmentation at an epoch (identity without `augment`, but for the
        rotation and `mirror`)."""
        mode, rot = self.rotations.mode, int(self.item_rot[item])
        if mode == "fixed":
            angle = rot * self.rotations.step_deg
        elif mode == "random":
            angle = float(np.random.default_rng([self.seed, epoch, item, 1]).uniform(0, 360))
        else:
            angle = 0.0
        if self.augment is None:
            return Aug(angle=angle, mirror=self.mirror) if angle or self.mirror else IDENTITY
        return self.augment.draw(np.random.default_rng([self.seed, epoch, item, 2]), angle)

    def targets(self, items: np.ndarray, epoch: int = 0) -> np.ndarray:
        """(len(items), 2F) float32 targets, before augmentation."""
        items = np.asarray(items, dtype=np.int64)
        rows = self.item_row[items]
        if self.target == "mean":
            return self._mean[rows].astype(np.float32)
        press = self.item_press[items]
        if self.target == "press":
            draws = self._press_draws(epoch)[items]
            press = np.array([int(d * len(self.tables.cones[self.fingers[0]][r]))
                              for d, r in zip(draws, rows, strict=True)])
        out = [np.stack([self.tables.cones[f][r][k] for r, k in zip(rows, press, strict=True)])
               for f in self.fingers]
        return np.concatenate(out, axis=1).astype(np.float32)

    def _press_draws(self, epoch: int) -> np.ndarray:
        """One uniform draw per sample from (seed, epoch), which press is its target
        (``press`` target); the last epoch's kept, so that items do not draw them again."""
        if self._draws is None or self._draws[0] != epoch:
            rng = np.random.default_rng([self.seed, epoch])
            self._draws = (epoch, rng.random(len(self.item_row)))
        return self._draws[1]

    def found(self, items: np.ndarray) -> np.ndarray:
        """(len(items), F) whether each finger was located (always True for views without)."""
        return self._found[self.item_row[np.asarray(items, dtype=np.int64)]]

    # ------------------------------------------------------------------ rendering
    def image(self, row: int) -> np.ndarray:
        """The RGB image of a configuration row."""
        if self.images is not None:
            return self.images(row)
        return read_rgb(self.tables.image_path(row))

    def info(self, row: int) -> SampleInfo:
        """Boxes, fingertips and background of a configuration row."""
        boxes = {f: self.tables.box(row, f) if self.boxes is None else self.boxes.box(row, f)
                 for f in self.view.needs_boxes}
        tips = {f: self.tips.get(row, f) for f in FINGERS} if self.view.needs_tips else {}
        contacts = {}
        if self._contacts is not None:
            c = self._contacts
            contacts = {f: (c.point[row, i], c.normal[row, i], c.axis[row, i])
                        for i, f in enumerate(FINGERS) if c.known[row, i]}
        return SampleInfo(boxes, tips, self._table_rgb, contacts)

    def render(self, item: int, epoch: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, Aug]:
        """One sample's model input: pixels (uint8), side features and auxiliary targets
        (float32), and the augmentation they were rendered with; a sample that no epoch
        changes is rendered once and then read from memory (`RENDER_CACHE_BYTES`)."""
        hit = self._cache.get(item) if self._cache_on else None
        if hit is not None:
            return hit
        out = self._render(item, epoch)
        if self._cache_on:
            size = sum(a.nbytes for a in out[:3])
            if self._cache_bytes + size <= RENDER_CACHE_BYTES:
                for a in out[:3]:
                    a.setflags(write=False)  # shared by every epoch: nobody may change it
                self._cache[item] = out
                self._cache_bytes += size
        return out

    def _render(self, item: int, epoch: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, Aug]:
        row = int(self.item_row[item])
        rgb = self.image(row)
        info, aug = self.info(row), self.aug(item, epoch)
        if aug.appearance >= 0:
            rgb, info = perturb_sample(rgb, info, self._finger_rgb,
                                       np.random.default_rng(aug.appearance),
                                       self.augment.appearance_axes)
        return (self.view.render(rgb, info, aug, self.size, self.fingers),
                self.view.side(info, aug, self.fingers), self.view.aux(info, aug, self.fingers),
                aug)

    def batch(self, items: Sequence[int], epoch: int = 0) -> dict[str, torch.Tensor]:
        """The samples `items` at an epoch, collated as a `DataLoader` batch (`collate`)."""
        return collate(self.__getitems__([(epoch, int(i)) for i in items]))


def collate(items: Sequence[Item]) -> dict[str, torch.Tensor]:
    """Samples stacked into the batch a training step takes: ``image`` float32 in [0, 1],
    ``side``, ``aux`` and ``target`` float32, ``found`` bool, ``row`` and ``rot`` int64."""
    out = {k: torch.from_numpy(np.stack([it[k] for it in items])) for k in items[0]}
    out["image"] = out["image"].float().div_(255.0)
    return out
