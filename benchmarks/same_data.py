"""Does a change of the dataset *format* leave the data alone? Generate with this tree and with
another source tree (same options, same seed): images, masks, recordings and `presses.parquet`
must be equal byte for byte, and `configs.parquet` equal value for value, where the columns that
changed form are compared by meaning (format 1 text cells ``"reason:count,..."`` / JSON against
format 2 lists of structs) and renamed columns under their new name.

Writes `benchmarks/results/same_data.md`.

    python benchmarks/same_data.py --before-src SRC [--n 60] [-- --preset lab --recordings]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
from same_bytes import digests, generate

from vistac.dataset.schema import failed_object_counts, redraw_counts

ROOT = Path(__file__).resolve().parent
RENAMED = {"scene_effect_fallbacks": "grasp_effect_fallbacks"}  # format 1 name -> format 2
NESTED = ("redraw_reasons", "failed_objects")


def text_redraws(cell) -> Counter:
    """Format 1 `redraw_reasons` (``"reason:count,..."``), or a format 2 cell."""
    if isinstance(cell, str):
        return Counter({k: int(v) for k, v in (i.split(":") for i in filter(None,
                                                                           cell.split(",")))})
    return redraw_counts(cell)


def text_failed(cell) -> dict[str, Counter]:
    """Format 1 `failed_objects` (JSON text, empty when none), or a format 2 cell."""
    if isinstance(cell, str):
        return {k: Counter(v) for k, v in (json.loads(cell) if cell else {}).items()}
    return failed_object_counts(cell)


def compare_configs(now: pd.DataFrame, before: pd.DataFrame) -> list[str]:
    """Columns whose values differ (after renaming and decoding the changed ones)."""
    before = before.rename(columns=RENAMED)
    differ = sorted(set(now.columns) ^ set(before.columns))
    for col in sorted(set(now.columns) & set(before.columns)):
        a, b = now[col], before[col]
        if col == "redraw_reasons":
            same = [text_redraws(x) for x in a] == [text_redraws(x) for x in b]
        elif col == "failed_objects":
            same = [text_failed(x) for x in a] == [text_failed(x) for x in b]
        elif a.dtype.kind in "fc":
            same = np.array_equal(a.to_numpy(), b.to_numpy(), equal_nan=True)
        else:
            same = a.tolist() == b.tolist()
        if not same:
            differ.append(col)
    return differ


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before-src", type=Path, required=True)
    p.add_argument("--n", type=int, default=60)
    p.add_argument("extra", nargs="*", help="more generate options (after --)")
    args = p.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="same_data_"))
    extra = args.extra or ["--preset", "lab", "--recordings", "--workers", "1"]
    generate(ROOT.parent, work / "now", args.n, extra)
    generate(args.before_src.resolve(), work / "before", args.n, extra)
    a, b = digests(work / "now"), digests(work / "before")
    files = sorted(k for k in set(a) | set(b) if k != "configs.parquet")
    differ = [k for k in files if a.get(k) != b.get(k)]
    now, before = (pd.read_parquet(work / d / "configs.parquet") for d in ("now", "before"))
    columns = compare_configs(now, before)
    redraws = int(now["redraws"].sum())
    lines = ["# Same data before and after the dataset format change", "",
             f"`vistac generate --n {args.n} {' '.join(extra)}` with this tree and with the "
             "tree before the format change (nested Parquet columns, format_version 2; "
             "simulator names changed). Command: `python benchmarks/same_data.py --before-src "
             f"SRC --n {args.n} -- {' '.join(extra)}`.", "",
             f"- files compared byte for byte: {len(files)} (images, recordings, "
             f"presses.parquet); differ: {len(differ)}"
             + (f" ({', '.join(differ[:5])})" if differ else ""),
             f"- configs.parquet: {len(now.columns)} columns, {len(now)} rows compared by "
             f"value; differ: {len(columns)}" + (f" ({', '.join(columns)})" if columns else ""),
             f"- rejected draws carried by the nested columns: {redraws} in `redraw_reasons`, "
             f"{sum(1 for c in now['failed_objects'] if len(c))} configurations with "
             "`failed_objects`", ""]
    (ROOT / "results" / "same_data.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0 if not differ and not columns else 1


if __name__ == "__main__":
    raise SystemExit(main())
