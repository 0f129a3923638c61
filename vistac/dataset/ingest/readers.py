"""Reading `vistac ingest`'s inputs: recording CSVs, the study's label spreadsheets, image and
recording folders, object lists. Every error names the file and the line (or row)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset import FINGERS
from vistac.dataset.files import check_file, locale_problem
from vistac.dataset.ingest.config import UNITS, IngestCfg
from vistac.dataset.schema import LABEL_COLUMNS
from vistac.errors import UserError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
MAX_LISTED_ERRORS = 20


def data_line(row: int) -> int:
    """1-based file line of 0-based data row `row` (the header is line 1)."""
    return row + 2


def read_recording(path: Path, cfg: IngestCfg) -> np.ndarray:
    """(T, 2, 3) force series in N of one recording CSV.

    A whole recording is parsed straight to numbers (`_forces`); only one that does not parse
    so is read again as text, cell by cell, to name its first bad line and cell.

    Raises:
        UserError: unreadable file, no header, too few fields, unparsable rows or non-numeric
            cells; the message names the file and line.
    """
    check_file(path)
    forces = _forces(path, cfg)
    if forces is not None:
        return forces * UNITS[cfg.unit]
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: unreadable ({exc})") from exc
    text = text.rstrip()
    if not text:
        raise UserError(f"{path}: line 1: empty file (expected a header line)")
    header = text.split("\n", 1)[0].rstrip("\r")
    need = cfg.columns.needed
    n_head = len(header.split(","))
    if n_head < need:
        raise UserError(f"{path}: line 1: missing columns: the header has {n_head} fields, the "
                        f"column map needs {need} (force columns {cfg.columns})")
    try:
        df = pd.read_csv(io.StringIO(text), header=0, dtype=str, keep_default_na=False,
                         skip_blank_lines=False)
    except pd.errors.ParserError as exc:
        raise UserError(f"{path}: unreadable row: {_parser_message(exc)}") from exc
    if len(df) == 0:
        raise UserError(f"{path}: line 2: no data rows after the header")
    lines = text.split("\n")[1:]
    fields = np.fromiter((line.count(",") + 1 for line in lines), int, len(lines))
    short = np.flatnonzero(fields < need)
    if len(short):
        r = int(short[0])
        what = "empty line" if not lines[r].strip() else f"only {fields[r]} fields"
        raise UserError(f"{path}: line {data_line(r)}: {what}, the column map needs {need} "
                        f"(missing field; {len(short)} short row(s) in all)")
    cols = [c for f in FINGERS for c in cfg.columns.of(f)]
    raw = df.iloc[:, cols]
    values = raw.apply(pd.to_numeric, errors="coerce").to_numpy(float)
    bad = ~np.isfinite(values)
    if bad.any():
        order = np.argsort(cols)  # report the leftmost bad cell of the first bad row
        r = int(np.flatnonzero(bad.any(axis=1))[0])
        c = int(order[np.flatnonzero(bad[r, order])[0]])
        raise UserError(f"{path}: line {data_line(r)}: non-numeric cell {raw.iat[r, c]!r} in "
                        f"column {cols[c]} ({bad.sum()} bad cell(s) in all)")
    return values.reshape(-1, 2, 3) * UNITS[cfg.unit]


def _forces(path: Path, cfg: IngestCfg) -> np.ndarray | None:
    """(T, 2, 3) forces (in the file's unit) of a recording whose rows all have the header's
    fields and whose force cells are all finite numbers, read by Arrow's CSV reader as numbers
    only: read as a table of text, each cell took ~60 bytes, so checking a 100 MB recording
    took 1 GB. None for anything else (the careful reading then names the line and cell). The
    numbers are those `pd.to_numeric` gives the same cells (correctly rounded)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    cols = [c for f in FINGERS for c in cfg.columns.of(f)]
    try:
        with path.open(encoding="utf-8") as fh:
            n_fields = len(fh.readline().rstrip("\r\n").split(","))
        if n_fields < cfg.columns.needed:
            return None
        names = [f"c{i}" for i in range(n_fields)]  # unique, whatever the header says
        wanted = [names[c] for c in dict.fromkeys(cols)]
        table = pacsv.read_csv(
            path, read_options=pacsv.ReadOptions(column_names=names, skip_rows=1,
                                                 use_threads=False),
            parse_options=pacsv.ParseOptions(ignore_empty_lines=False),  # a row of other length:
            convert_options=pacsv.ConvertOptions(  # an error, as a cell that is not a number
                include_columns=wanted, column_types=dict.fromkeys(wanted, pa.float64())))
    except (OSError, UnicodeDecodeError, pa.ArrowException):
        return None
    if table.num_rows == 0:
        return None
    values = np.empty((table.num_rows, len(cols)))
    for i, c in enumerate(cols):
        values[:, i] = table[names[c]].to_numpy()  # nulls (empty cells) become NaN
    if not np.isfinite(values).all():
        return None
    return values.reshape(-1, 2, 3)


def _parser_message(exc: Exception) -> str:
    """pandas' tokenizer message ("Expected 20 fields in line 7, saw 21") without its prefix."""
    text = str(exc).strip()
    return text.split(". C error: ")[-1] if "C error" in text else text


def read_label_sheet(path: Path, sheet: str | None = None) -> pd.DataFrame:
    """The study's label spreadsheet: columns image, row, r_y_index, r_z_index, r_y_thumb,
    r_z_thumb (`row` is the sheet's 1-based row). A first row whose label cells are not all
    numbers is a header.

    Raises:
        UserError: unreadable file, unknown sheet, rows with missing or non-numeric cells.
    """
    import openpyxl

    try:
        wb = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # openpyxl raises many types for a bad file
        raise UserError(f"{path}: not a readable xlsx file ({exc})") from exc
    try:
        if sheet is not None and sheet not in wb.sheetnames:
            raise UserError(f"{path}: no sheet {sheet!r} (sheets: {', '.join(wb.sheetnames)})")
        ws = wb[sheet] if sheet is not None else wb.worksheets[0]
        rows, errors, first = [], [], True
        for r, cells in enumerate(ws.iter_rows(values_only=True), start=1):
            cells = list(cells) + [None] * max(0, 5 - len(cells))
            if all(c is None or str(c).strip() == "" for c in cells):
                continue
            nums = [_number(c) for c in cells[1:5]]
            if first and any(v is None for v in nums):
                first = False  # a header row
                continue
            first = False
            name = "" if cells[0] is None else str(cells[0]).strip()
            if not name:
                errors.append(f"{path}: sheet {ws.title!r}, row {r}: no image name")
            elif any(v is None for v in nums):
                k = next(i for i, v in enumerate(nums) if v is None)
                errors.append(f"{path}: sheet {ws.title!r}, row {r}: non-numeric cell "
                              f"{cells[k + 1]!r} in column {'BCDE'[k]}")
            else:
                rows.append((name, r, *nums))
    finally:
        wb.close()
    raise_all(errors)
    if not rows:
        raise UserError(f"{path}: no label rows")
    return pd.DataFrame(rows, columns=["image", "row", *LABEL_COLUMNS])


def _number(cell) -> float | None:
    if isinstance(cell, bool):
        return None
    if isinstance(cell, int | float):
        return float(cell) if np.isfinite(cell) else None
    try:
        v = float(str(cell).strip().replace(",", "."))
    except (TypeError, ValueError):
        return None
    return v if np.isfinite(v) else None


def raise_all(errors: list[str]) -> None:
    """One `UserError` listing every problem found (at most `MAX_LISTED_ERRORS` of them)."""
    if errors:
        more = len(errors) - MAX_LISTED_ERRORS
        listed = errors[:MAX_LISTED_ERRORS] + ([f"... and {more} more"] if more > 0 else [])
        raise UserError("\n  ".join([f"{len(errors)} problem(s):", *listed]))


def files_by_stem(folder: Path, suffixes: tuple[str, ...], what: str) -> dict[str, Path]:
    """Files of `folder` with one of `suffixes`, by stem (two files of one stem: error)."""
    if not folder.is_dir():
        raise UserError(f"{folder}: no such {what} folder")
    out: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in suffixes:
            problem = locale_problem(str(p))
            if problem is not None:  # its name cannot be written into a table
                raise UserError(problem)
            if p.stem in out:
                raise UserError(f"{folder}: two {what} files for {p.stem!r}: {out[p.stem].name}, "
                                f"{p.name}")
            out[p.stem] = p
    if not out:
        raise UserError(f"{folder}: no {what} files ({', '.join(suffixes)})")
    return out


MAX_NAMED_ID = 2**53
"""A name that is a number below this keeps it as its id (beyond it, ids lose precision in the
float columns of tools that read the tables)."""


def named_id(name: str) -> int | None:
    """The configuration id a file name gives (``000123`` -> 123), or None when it is not a
    number (ASCII digits only: ``int`` would also read ``"١٢"`` or ``"1_0"``)."""
    if name.isascii() and name.isdigit() and int(name) < MAX_NAMED_ID:
        return int(name)
    return None


def config_ids(names: list[str]) -> dict[str, int]:
    """Configuration id of each name: the number it is; names that are not numbers follow the
    largest such number (or 0) in name order. A number name's id never depends on the other
    files (an odd name added or removed renumbers nothing else).

    Raises:
        UserError: two names that give the same number (``7`` and ``007``).
    """
    ids: dict[str, int] = {}
    seen: dict[int, str] = {}
    for n in sorted(names):
        i = named_id(n)
        if i is None:
            continue
        if i in seen:
            raise UserError(f"names {seen[i]!r} and {n!r} give the same configuration id {i}")
        ids[n], seen[i] = i, n
    start = max(seen, default=-1) + 1
    odd = sorted(n for n in names if n not in ids)
    ids.update((n, start + k) for k, n in enumerate(odd))
    return {n: ids[n] for n in names}


def match_names(recordings: dict[str, Path], images: dict[str, Path], rec_dir: Path,
                img_dir: Path) -> list[str]:
    """The names with both a recording and an image (every unmatched file is an error)."""
    no_image = sorted(set(recordings) - set(images))
    no_rec = sorted(set(images) - set(recordings))
    errors = [f"{recordings[n]}: recording without an image in {img_dir}" for n in no_image]
    errors += [f"{images[n]}: image without a recording in {rec_dir}" for n in no_rec]
    raise_all(errors)
    return sorted(recordings)


def read_objects_csv(path: Path, ids: dict[str, int]) -> dict[int, str]:
    """config_id -> object_id from a CSV with columns object_id and config_id or name.

    Raises:
        UserError: unreadable file, missing columns, unknown or missing configurations.
    """
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: unreadable ({exc})") from exc
    key = "config_id" if "config_id" in df else "name" if "name" in df else None
    if key is None or "object_id" not in df:
        raise UserError(f"{path}: line 1: needs columns object_id and config_id (or name)")
    by_id = {str(i): i for i in ids.values()} if key == "config_id" else ids
    out, errors = {}, []
    for r, (k, obj) in enumerate(zip(df[key], df["object_id"], strict=True)):
        k = k.strip()
        if key == "config_id" and k.isdigit():
            k = str(int(k))
        if k not in by_id:
            errors.append(f"{path}: line {data_line(r)}: unknown {key} {k!r}")
        elif not obj.strip():
            errors.append(f"{path}: line {data_line(r)}: empty object_id")
        else:
            out[by_id[k]] = obj.strip()
    missing = sorted(set(ids.values()) - set(out))
    if missing:
        errors.append(f"{path}: no object_id for configuration(s) {missing[:10]}")
    raise_all(errors)
    return out
