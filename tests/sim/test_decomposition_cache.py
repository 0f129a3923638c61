"""A damaged convex-decomposition cache file is named, removed and made again, never trusted
and never a traceback (every later run with that mesh failed before)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from shapely.geometry import Polygon

from vistac_sim.objects.decomposition import convex_decomposition


def test_a_damaged_cache_file_is_named_and_decomposed_again(tmp_path):
    outline = Polygon([(0, 0), (0.04, 0), (0.04, 0.01), (0.01, 0.01), (0.01, 0.04), (0, 0.04)])
    mesh = trimesh.creation.extrude_polygon(outline, 0.02)  # an L: concave, goes through CoACD
    first = convex_decomposition(mesh, tmp_path)
    (cache,) = tmp_path.glob("*.npz")
    good = cache.read_bytes()
    for damage in (good[: len(good) // 2], b"not a zip", b""):
        cache.write_bytes(damage)
        with pytest.warns(UserWarning, match=f"{cache.name}: damaged convex-decomposition"):
            again = convex_decomposition(mesh, tmp_path)
        assert len(again) == len(first)
        for a, b in zip(again, first, strict=True):
            np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-12)
        assert cache.read_bytes() == good  # written again, whole


def test_a_symlink_loop_in_a_mesh_folder_is_named(tmp_path):
    from vistac.errors import UserError
    from vistac_sim.objects.meshes import find_mesh_files

    trimesh.creation.box((0.03, 0.03, 0.02)).export(tmp_path / "box.stl")
    (tmp_path / "loop.stl").symlink_to("loop.stl")  # ELOOP: was a RuntimeError traceback
    with pytest.raises(UserError, match="loop.stl: a symbolic link that leads to no file"):
        find_mesh_files([str(tmp_path)])
    (tmp_path / "loop.stl").unlink()
    (tmp_path / "back").symlink_to(".")  # a folder loop is not followed
    assert find_mesh_files([str(tmp_path)]) == [tmp_path / "box.stl"]
