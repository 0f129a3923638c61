"""The environment a command runs in (issue 31): a ``MUJOCO_GL`` backend that cannot start here
and a C locale without Python's UTF-8 mode used to end in tracebacks (MuJoCo's ``FatalError``,
PyOpenGL's ``AttributeError``, pyarrow's ``UnicodeEncodeError``) or to call a good dataset
"unreadable". Each row runs the `vistac` command in a fresh process with that environment and
asserts exit status 2, one line naming the variable and what to set, nothing written; then the
same command in a good environment works.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from bad_input_env import GEN_OK

from vistac.dataset.files import check_out_dir
from vistac.errors import UserError

VISTAC = str(Path(sys.executable).parent / "vistac")

CASES = {
    "mujoco-gl-vulkan": ({"MUJOCO_GL": "vulkan"}, "out", "MUJOCO_GL=vulkan: MuJoCo cannot "
                         "render with this backend here (invalid value"),
    "mujoco-gl-glx-without-display": ({"MUJOCO_GL": "glx", "DISPLAY": ""}, "out",
                                      "MUJOCO_GL=glx: MuJoCo cannot render"),
    "mujoco-gl-osmesa-without-library": ({"MUJOCO_GL": "osmesa"}, "out",
                                         "MUJOCO_GL=osmesa: MuJoCo cannot render"),
    "c-locale-non-ascii-out": ({"LC_ALL": "C", "PYTHONUTF8": "0"}, "dataset-\u00f6",
                               "not ASCII, and this process reads names as ascii (locale C, "
                               "PYTHONUTF8 off); run with LC_ALL=C.UTF-8"),
}
SLOW = {"mujoco-gl-glx-without-display", "mujoco-gl-osmesa-without-library"}  # 6 s each: as
# the vulkan row (one line, nothing written), failing in another library


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW else c
                                  for c in CASES])
def test_an_environment_that_cannot_work_is_one_line(case, tmp_path):
    env_vars, name, needle = CASES[case]
    out = tmp_path / name
    argv = [VISTAC, *GEN_OK.format(out=out).split()]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    res = subprocess.run(argv, env=env | env_vars, capture_output=True, timeout=300)
    err = res.stderr.decode("utf-8", "backslashreplace").strip()
    assert res.returncode == 2 and "Traceback" not in err, err[-3000:]
    assert err.count("\n") == 0 and needle in err, err
    assert not out.exists() and not list(tmp_path.iterdir())  # nothing written
    if "LC_ALL" in env_vars:  # the advice works (a good generate: the suite's others)
        res = subprocess.run(argv, env=env | {"LC_ALL": "C.UTF-8"}, capture_output=True,
                             timeout=300)
        assert res.returncode == 0, res.stderr[-3000:]


def test_a_name_that_is_not_text_is_refused_from_python():
    """The API's folders go through `check_out_dir`: a name whose bytes are not UTF-8 (they
    arrive as lone surrogates) is refused in one line naming the option."""
    with pytest.raises(UserError, match="--out .*dataset-\ufffd: a name that is not valid UTF-8"):
        check_out_dir("/tmp/dataset-\udcf6")  # Latin-1 "ö"


def test_ingest_refuses_a_file_name_that_is_not_utf8(env, tmp_path, capsys):
    """A recording and its image named in Latin-1 (``café``) used to end in pyarrow's
    UnicodeEncodeError traceback; now one line names the file, nothing is written, and the
    files renamed, the same command works."""
    from vistac.cli import main

    rec, img = tmp_path / "rec", tmp_path / "img"
    shutil.copytree(env["paths"]["rec"], rec)
    shutil.copytree(env["paths"]["img"], img)
    latin1 = b"caf\xe9".decode("utf-8", "surrogateescape")
    (rec / "000001.csv").rename(rec / f"{latin1}.csv")
    (img / "000001.png").rename(img / f"{latin1}.png")
    out = tmp_path / "out"
    argv = ["ingest", "--recordings", str(rec), "--images", str(img), "--out", str(out)]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert "caf\ufffd.png: a name that is not valid UTF-8 text; rename it" in err, err
    assert not out.exists()
    (rec / f"{latin1}.csv").rename(rec / "cafe.csv")
    (img / f"{latin1}.png").rename(img / "cafe.png")
    assert main(argv) == 0


def test_a_texture_opencv_cannot_read_is_one_line(tmp_path):
    """A 32-bit float TIFF among --textures: OpenCV's warning used to print beside the error."""
    import cv2
    import numpy as np

    textures = tmp_path / "textures"
    textures.mkdir()
    cv2.imwrite(str(textures / "float.tiff"), np.random.default_rng(0).random((16, 16, 3),
                                                                               np.float32))
    out = tmp_path / "out"
    argv = [VISTAC, *GEN_OK.format(out=out).split(), "--preset", "photo", "--textures",
            str(textures)]
    res = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    err = res.stderr.strip()
    assert res.returncode == 2 and err.count("\n") == 0 and "Traceback" not in err, err
    assert f"--textures {textures}: no readable image" in err, err
    assert not out.exists()
