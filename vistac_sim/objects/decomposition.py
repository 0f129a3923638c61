"""Convex decomposition of user meshes (CoACD), cached on disk by mesh hash."""

from __future__ import annotations

import hashlib
import io
import os
from pathlib import Path

import numpy as np
import trimesh

from vistac.dataset.files import atomic_write_bytes, remove_stale_temporaries


def convex_decomposition(mesh: trimesh.Trimesh, cache_dir: Path | None,
                         threshold: float = 0.05) -> list[trimesh.Trimesh]:
    """Convex pieces of a mesh: itself if convex, else CoACD, cached on disk by mesh hash."""
    if mesh.convex_hull.volume - mesh.volume <= 1e-3 * mesh.volume:
        return [mesh.convex_hull]
    key = hashlib.sha256(
        mesh.vertices.astype("<f8").tobytes() + mesh.faces.astype("<i8").tobytes()
        + f"coacd-{threshold}".encode()
    ).hexdigest()[:32]
    cache = Path(cache_dir or default_cache_dir()) / f"{key}.npz"
    if cache.exists():
        data = np.load(cache)
        return [trimesh.Trimesh(data[f"v{i}"], data[f"f{i}"]) for i in range(int(data["n"]))]
    import coacd

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(mesh.vertices, mesh.faces), threshold=threshold, seed=0)
    pieces = [trimesh.Trimesh(np.asarray(v), np.asarray(f)).convex_hull for v, f in parts]
    cache.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(cache.parent)  # a killed writer's leftovers
    arrays = {f"v{i}": p.vertices for i, p in enumerate(pieces)}
    arrays.update({f"f{i}": p.faces for i, p in enumerate(pieces)})
    buf = io.BytesIO()
    np.savez(buf, n=len(pieces), **arrays)
    atomic_write_bytes(cache, buf.getvalue())
    return pieces


def default_cache_dir() -> Path:
    """Where convex decompositions are cached ($VISTAC_CACHE or ~/.cache/vistac/coacd)."""
    root = os.environ.get("VISTAC_CACHE") or Path.home() / ".cache" / "vistac"
    return Path(root) / "coacd"
