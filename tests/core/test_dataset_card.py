"""The dataset card (vistac.dataset.card): Hugging Face front matter that `datasets` reads."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import yaml
from learn_fixtures import make_dataset

from vistac.dataset.card import card_text, size_category, write_card


def _front_matter(text: str) -> dict:
    assert text.startswith("---\n")
    return yaml.safe_load(text.split("---\n")[1])


def test_size_categories_follow_the_hub():
    assert [size_category(n) for n in (0, 999, 1000, 20_000, 100_000)] == [
        "n<1K", "n<1K", "1K<n<10K", "10K<n<100K", "100K<n<1M"]


def test_card_names_the_tables_and_the_counts():
    manifest = {"generator": "vistac generate", "seed": 4, "config": {"repeats": 6},
                "counts": {"configs": 1500, "presses": 9000, "objects": 32,
                           "split": {"train": 1050, "val": 225, "test": 225}}}
    text = card_text(manifest, has_rejected=False)
    meta = _front_matter(text)
    assert meta["license"] == "apache-2.0" and meta["size_categories"] == ["1K<n<10K"]
    assert [c["config_name"] for c in meta["configs"]] == ["configs", "presses"]
    assert meta["configs"][0]["data_files"] == "configs.parquet" and meta["configs"][0]["default"]
    assert "1500 grasp configurations" in text and "train 1050, val 225, test 225" in text
    ingested = _front_matter(card_text({"generator": "vistac ingest"}, has_rejected=True))
    assert ingested["license"] == "unknown"  # the user's recordings: vistac cannot know
    assert ingested["configs"][-1] == {"config_name": "rejected", "data_files": "rejected.csv"}


def test_datasets_loads_the_tables_through_the_card(tmp_path):
    datasets = pytest.importorskip("datasets")
    root = make_dataset(tmp_path / "d", n=6, repeats=2, size=48)
    write_card(root, json.loads((root / "manifest.json").read_text()))
    cache = str(tmp_path / "hf-cache")
    configs = datasets.load_dataset(str(root), split="train", cache_dir=cache)
    presses = datasets.load_dataset(str(root), "presses", split="train", cache_dir=cache)
    assert sorted(configs["config_id"]) == list(range(6))
    assert len(presses) == 12 and "r_y_index" in presses.column_names
    direct = datasets.load_dataset("parquet", data_files=str(root / "presses.parquet"),
                                   split="train", cache_dir=cache)
    pd.testing.assert_frame_equal(direct.to_pandas(), pd.read_parquet(root / "presses.parquet"))
    # the card's snippet: join the images
    test = configs.filter(lambda r: r["split"] == "test")
    test = test.map(lambda r: {"image": f"{root}/images/{r['image']}"})
    test = test.cast_column("image", datasets.Image())
    assert test[0]["image"].size == (48, 48)
