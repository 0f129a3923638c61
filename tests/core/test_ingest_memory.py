"""Ingesting a long recording (issue 31): a recording is parsed straight to numbers, not first
into a table of text (a 100 MB recording of the simulator's took 963 MiB of memory and 20 s to
ingest; now 320 MiB and 5 s, the same bytes written). The fast reading gives exactly the
numbers of the careful one, which still names a bad line and cell (tests/sim/test_ingest.py).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vistac.dataset.ingest.config import IngestCfg
from vistac.dataset.ingest.readers import _forces, read_recording
from vistac.dataset.recordings import HEADER


def _recording(path: Path, rows: int, seed: int = 0) -> Path:
    """A recording of `rows` samples: presses (both pads at about 2 N) between rests."""
    rng = np.random.default_rng(seed)
    values = np.zeros((rows, len(HEADER)), np.int64)
    values[:, 0] = np.arange(rows) * 20
    values[:, 1] = np.arange(rows)
    pressing = (np.arange(rows) % 800) >= 200
    for c in (14, 15, 16, 17, 18, 19):
        values[:, c] = rng.integers(-30, 30, rows) + pressing * (-2000 if c in (16, 19) else 150)
    text = "\n".join([",".join(HEADER), *(",".join(map(str, r)) for r in values)]) + "\n"
    path.write_text(text)
    return path


def test_the_fast_reading_gives_the_careful_readings_numbers(tmp_path, monkeypatch):
    import vistac.dataset.ingest.readers as readers

    path = _recording(tmp_path / "000001.csv", 500)
    fast = read_recording(path, IngestCfg())
    assert _forces(path, IngestCfg()) is not None
    monkeypatch.setattr(readers, "_forces", lambda *a: None)  # the careful reading alone
    careful = read_recording(path, IngestCfg())
    assert np.array_equal(fast, careful)
    lines = path.read_text().splitlines()
    for bad in (lines[3] + ",7", lines[3].rsplit(",", 1)[0] + ",x", ""):
        changed = tmp_path / "bad.csv"
        changed.write_text("\n".join([*lines[:3], bad, *lines[4:]]) + "\n")
        assert _forces(changed, IngestCfg()) is None  # the careful reading names it


@pytest.mark.slow  # writes and reads a 100 MB recording (about 15 s)
def test_a_100_mb_recording_is_read_in_bounded_memory(tmp_path):
    """Peak memory of a fresh process reading a 100 MB recording: 357 MiB (the imports ~110),
    was 1130 MiB when each cell was first held as text."""
    path = _recording(tmp_path / "000000.csv", 1_600_000)
    assert path.stat().st_size > 95e6
    # VmHWM, the peak of this program (ru_maxrss would carry this test's own over the exec)
    code = ("import sys\nfrom pathlib import Path\n"
            "from vistac.dataset.ingest.config import IngestCfg\n"
            "from vistac.dataset.ingest.readers import read_recording\n"
            "forces = read_recording(Path(sys.argv[1]), IngestCfg())\n"
            "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]\n"
            "print(len(forces), int(hwm.split()[1]) // 1024)\n")
    res = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                         text=True, timeout=600)
    rows, peak_mib = map(int, res.stdout.split())
    assert rows == 1_600_000
    assert peak_mib < 500, (peak_mib, res.stderr[-2000:])
