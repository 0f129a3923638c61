"""The dataset card: a `README.md` in every dataset folder, generated from its manifest.

The card follows the Hugging Face convention: YAML front matter (licence, task categories, size
category, tags, and ``configs`` naming the tables as ``data_files``) above a short description,
so that the folder can be published as it is and ``datasets.load_dataset(folder)`` (the
``configs`` table) or ``datasets.load_dataset(folder, "presses")`` reads its tables. The text
depends only on the manifest's content (no wall time, no versions), so the same seed gives the
same card. `vistac generate` and `vistac ingest` write it beside the manifest; `vistac inspect`
writes it for datasets made before there were cards.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from vistac.dataset.files import atomic_write_bytes
from vistac.dataset.schema import CARD, CONFIGS, IMAGES, MASKS, PRESSES, REJECTED, SPLITS

SIZE_CATEGORIES = ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"),
                   (1_000_000, "100K<n<1M"))
"""Upper bounds of the hub's size categories (configurations), in order."""


def size_category(n: int) -> str:
    """The hub's size category of a dataset of `n` configurations."""
    return next((name for bound, name in SIZE_CATEGORIES if n < bound), "1M<n<10M")


def _simulated(manifest: dict) -> bool:
    return manifest.get("generator") == "vistac generate"


def front_matter(manifest: dict, has_rejected: bool) -> dict[str, Any]:
    """The card's YAML front matter (a dict, in the order it is written)."""
    n = int((manifest.get("counts") or {}).get("configs") or 0)
    objects = (manifest.get("config") or {}).get("objects") or {}
    own_data = not _simulated(manifest) or bool(objects.get("paths"))
    configs = [{"config_name": "configs", "data_files": CONFIGS, "default": True},
               {"config_name": "presses", "data_files": PRESSES}]
    if has_rejected:
        configs.append({"config_name": "rejected", "data_files": REJECTED})
    return {
        # procedural objects are the project's own (Apache-2.0); meshes and recordings are the
        # user's, whose licence vistac cannot know
        "license": "unknown" if own_data else "apache-2.0",
        "pretty_name": "vistac visuo-tactile dataset",
        "task_categories": ["robotics"],
        "size_categories": [size_category(n)],
        "tags": ["visuo-tactile", "tactile", "force", "grasping", "vistac",
                 "simulation" if _simulated(manifest) else "real-recordings"],
        "configs": configs,
    }


def _counts_lines(manifest: dict) -> list[str]:
    counts = manifest.get("counts") or {}
    split = counts.get("split") or {}
    lines = [f"- {counts.get('configs', '?')} grasp configurations (one top-view image each), "
             f"{counts.get('presses', '?')} presses, {counts.get('objects', '?')} objects",
             "- splits: " + (", ".join(f"{s} {split[s]}" for s in SPLITS if s in split) or "-")]
    families = counts.get("families")
    if families:
        lines.append("- object families: " + ", ".join(f"{k} {v}"
                                                      for k, v in sorted(families.items())))
    return lines


def _making_lines(manifest: dict) -> list[str]:
    cfg = manifest.get("config") or {}
    if _simulated(manifest):
        effects = [k for k, v in (cfg.get("effects") or {}).items() if v]
        render = manifest.get("render") or {}
        lines = [f"- made by `vistac generate` (MuJoCo), seed {manifest.get('seed')}, "
                 f"{cfg.get('repeats', '?')} presses per configuration",
                 f"- images {render.get('image_size', '?')} x {render.get('image_size', '?')} px, "
                 f"{render.get('view_extent_m', '?')} m across, index finger drawn green, "
                 "thumb red",
                 "- effects: " + (", ".join(effects) if effects else "none (noise-free)")]
        redraws = (manifest.get("redraws") or {}).get("by_reason") or {}
        if redraws:
            lines.append("- rejected grasp draws: " + ", ".join(f"{k} {v}"
                                                                for k, v in redraws.items()))
        return lines
    rejected = (manifest.get("rejected") or {}).get("by_reason") or {}
    return [f"- made by `{manifest.get('generator', 'vistac ingest')}` from RH8D/FTS-3 "
            "recordings and their images",
            "- rejected grasps: " + (", ".join(f"{k} {v}" for k, v in rejected.items())
                                     or "none") + f" (every one in `{REJECTED}`)"]


def card_text(manifest: dict, has_rejected: bool = False, has_masks: bool = False) -> str:
    """The whole card: front matter, description, files and how to load them."""
    head = yaml.safe_dump(front_matter(manifest, has_rejected), sort_keys=False,
                          default_flow_style=False, width=100)
    files = [f"- `{CONFIGS}`: one row per configuration (object, split, image file name, pose, "
             "finger geometry)",
             f"- `{PRESSES}`: one row per press: each fingertip's force (N, in its sensor frame) "
             "and the unit labels `r_y_<finger>`, `r_z_<finger>`",
             f"- `{IMAGES}/`: one PNG per configuration, named in the `image` column",
             "- `manifest.json`: every setting the dataset was made with"]
    if has_masks:
        files.append(f"- `{MASKS}/`: one label PNG per image (0 table, 1 object, 2 index, "
                     "3 thumb)")
    if has_rejected:
        files.append(f"- `{REJECTED}`: every rejected grasp with its recording lines and reason")
    body = [
        "# vistac visuo-tactile dataset", "",
        "Top-view images of a two-finger hand (index finger and thumb) pressing an object, with "
        "the force each fingertip felt, as a unit direction (r_y, r_z) in the fingertip's "
        "sensor frame: z out of the pad towards the object, y across the finger in the table "
        "plane (the thumb's y mirrored against the index finger's).", "",
        "## Contents", "", *_counts_lines(manifest), *_making_lines(manifest), "",
        "## Files", "", *files, "",
        "## Loading", "",
        "```python",
        "import datasets, pandas as pd",
        f"configs = datasets.load_dataset(folder, split='train')   # {CONFIGS}, every split",
        "presses = datasets.load_dataset(folder, 'presses', split='train')",
        f"# or: datasets.load_dataset('parquet', data_files=f'{{folder}}/{PRESSES}')",
        "test = configs.filter(lambda r: r['split'] == 'test')",
        "# join the images: the image column names a file under images/",
        f"test = test.map(lambda r: {{'image': f\"{{folder}}/{IMAGES}/{{r['image']}}\"}})",
        "test = test.cast_column('image', datasets.Image())",
        "# join the labels: presses by config_id (pandas)",
        "joined = pd.merge(test.to_pandas(), presses.to_pandas(), on='config_id')",
        "```", "",
        "Hugging Face's `train` split here is the whole table; the dataset's own split is the "
        "`split` column (whole configurations are assigned, never single presses).", "",
        "Made with vistac; `vistac inspect FOLDER` draws the labels on the images and plots "
        "their distributions.", "",
    ]
    return f"---\n{head}---\n\n" + "\n".join(body)


def write_card(root: str | Path, manifest: dict) -> Path:
    """Write (atomically, replacing any) the dataset card of folder `root`; returns its path."""
    root = Path(root)
    path = root / CARD
    text = card_text(manifest, has_rejected=(root / REJECTED).is_file(),
                     has_masks=(root / MASKS).is_dir())
    atomic_write_bytes(path, text.encode())
    return path
