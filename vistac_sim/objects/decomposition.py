"""Convex decomposition of user meshes (CoACD), cached on disk by mesh hash, and sections of the
convex pieces (the geometry MuJoCo collides)."""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import warnings
import zipfile
from pathlib import Path

import numpy as np
import shapely
import trimesh
from shapely.ops import unary_union

from vistac.dataset.files import atomic_write_bytes, remove_stale_temporaries

# CoACD's search budget: a quarter of its default cost (20 s instead of 80 s of CPU for a 4 k-face
# scan) for decompositions within the same concavity threshold.
COACD_BUDGET = {"max_convex_hull": 16, "mcts_iterations": 40, "mcts_nodes": 10,
                "resolution": 1000, "preprocess_resolution": 30}


def convex_decomposition(mesh: trimesh.Trimesh, cache_dir: Path | None,
                         threshold: float = 0.05,
                         max_pieces: int | None = None) -> list[trimesh.Trimesh]:
    """Convex pieces of a mesh: itself if convex, else CoACD, cached on disk by the hash of the
    mesh scaled to the unit cube. `max_pieces` overrides the budget's `max_convex_hull`.

    An open mesh (not watertight) goes through CoACD's manifold pre-processing, which needs no
    closed surface.
    """
    closed = mesh.is_watertight
    if closed and mesh.convex_hull.volume - mesh.volume <= 1e-3 * mesh.volume:
        return [mesh.convex_hull]
    mode = "auto" if closed else "on"
    budget = COACD_BUDGET | ({} if max_pieces is None else {"max_convex_hull": max_pieces})
    # Decompose (and key the cache by) the mesh scaled into the unit cube, so that one mesh at
    # different footprints is decomposed once.
    lo, size = mesh.bounds[0], float(mesh.extents.max())
    unit = np.round((mesh.vertices - lo) / size, 9)
    key = hashlib.sha256(
        unit.astype("<f8").tobytes() + mesh.faces.astype("<i8").tobytes()
        + f"coacd-{threshold}-{mode}-{sorted(budget.items())}".encode()
    ).hexdigest()[:32]
    cache = Path(cache_dir or default_cache_dir()) / f"{key}.npz"
    if cache.exists():
        cached = read_cached_pieces(cache)
        if cached is not None:
            return [trimesh.Trimesh(v * size + lo, f) for v, f in cached]
    import coacd

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(unit, mesh.faces), threshold=threshold, seed=0,
                            preprocess_mode=mode, **budget)
    unit_pieces = [trimesh.Trimesh(np.asarray(v), np.asarray(f)).convex_hull for v, f in parts]
    unit_pieces = [p for p in unit_pieces if p.volume > 0]
    pieces = [trimesh.Trimesh(p.vertices * size + lo, p.faces) for p in unit_pieces]
    cache.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(cache.parent)  # a killed writer's leftovers
    arrays = {f"v{i}": p.vertices for i, p in enumerate(unit_pieces)}
    arrays.update({f"f{i}": p.faces for i, p in enumerate(unit_pieces)})
    buf = io.BytesIO()
    np.savez(buf, n=len(unit_pieces), **arrays)
    atomic_write_bytes(cache, buf.getvalue())
    return pieces


def read_cached_pieces(cache: Path) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """The (unit-cube vertices, faces) of a cached decomposition, or None for a cache file that
    cannot be read (truncated, overwritten, not a regular file): it is named in a warning and
    removed, and the decomposition is made again."""
    try:
        if not cache.is_file():
            raise ValueError("not a regular file")
        with np.load(cache, allow_pickle=False) as data:
            out = [(np.asarray(data[f"v{i}"], float), np.asarray(data[f"f{i}"], np.int64))
                   for i in range(int(data["n"]))]
        if not out or any(not np.isfinite(v).all() or v.ndim != 2 or v.shape[1] != 3
                          or f.ndim != 2 or f.shape[1] != 3 or f.size == 0
                          or f.min() < 0 or f.max() >= len(v) for v, f in out):
            raise ValueError("pieces out of shape")
        return out
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        warnings.warn(f"{cache}: damaged convex-decomposition cache ({exc}); removed, "
                      "decomposing again", stacklevel=2)
        with contextlib.suppress(OSError):
            cache.unlink()
        return None


def pieces_section(pieces: list[trimesh.Trimesh], z: float):
    """Top-view section of the union of convex pieces at height z (a shapely geometry, possibly
    empty or a MultiPolygon). Each piece's section is the convex hull of where its edges cross
    the plane."""
    polys = []
    for p in pieces:
        v = p.vertices
        e = p.edges_unique
        z0, z1 = v[e[:, 0], 2] - z, v[e[:, 1], 2] - z
        cross = z0 * z1 < 0
        t = (z0[cross] / (z0[cross] - z1[cross]))[:, None]
        pts = v[e[cross, 0], :2] * (1 - t) + v[e[cross, 1], :2] * t
        pts = np.concatenate([pts, v[np.abs(v[:, 2] - z) <= 1e-12, :2]])
        if len(pts) >= 3:
            hull = shapely.MultiPoint(pts).convex_hull
            if hull.area > 0:
                polys.append(hull)
    return unary_union(polys) if polys else shapely.Polygon()


def default_cache_dir() -> Path:
    """Where convex decompositions are cached ($VISTAC_CACHE or ~/.cache/vistac/coacd)."""
    root = os.environ.get("VISTAC_CACHE") or Path.home() / ".cache" / "vistac"
    return Path(root) / "coacd"


FIDELITY_SAMPLES = 2000
"""Points sampled on each side (collision pieces, labelled mesh) to measure their distance."""


def collision_fidelity(mesh: trimesh.Trimesh, pieces: list[trimesh.Trimesh],
                       seed: int = 0) -> dict[str, float]:
    """How far the collision pieces lie from the labelled mesh (the same frame and units).

    Returns:
        ``hausdorff``: the larger of (a) the farthest point of the pieces' outer surface (points
        on or inside another piece left out: seams between pieces) from the mesh and (b) the
        farthest point of the mesh from the pieces' surface; each from `FIDELITY_SAMPLES`
        surface points (and mesh vertices), exact point-to-triangle distances.
        ``volume_ratio``: the pieces' summed volume over the mesh's (NaN for an open mesh).
    """
    rng = np.random.default_rng(seed)
    planes = [_planes(p) for p in pieces]
    # (b) mesh -> pieces: distance to the nearest piece face
    pts = np.concatenate([_sample(mesh, rng), mesh.vertices[::max(1, len(mesh.vertices) // 2000)]])
    to_pieces = _max_distance(pts, np.concatenate([p.triangles for p in pieces]))
    # (a) pieces -> mesh: outer-surface samples of each piece
    size = float(mesh.extents.max())
    outer = []
    for i, p in enumerate(pieces):
        s = _sample(p, rng, max(64, FIDELITY_SAMPLES // len(pieces)))
        keep = np.ones(len(s), bool)
        for j, (n, d) in enumerate(planes):
            if j != i:
                keep &= (s @ n.T - d).max(axis=1) > 1e-4 * size
        outer.append(s[keep])
    outer = np.concatenate(outer) if outer else np.zeros((0, 3))
    to_mesh = _max_distance(outer, mesh.triangles)
    ratio = (sum(p.volume for p in pieces) / mesh.volume
             if mesh.is_watertight and mesh.volume > 0 else float("nan"))
    return {"hausdorff": max(to_pieces, float(to_mesh)), "volume_ratio": float(ratio)}


def _planes(piece: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Outward face normals and offsets of a convex piece (inside: n . x - d < 0 for all)."""
    n = piece.face_normals
    return n, (n * piece.triangles[:, 0]).sum(1)


def _sample(mesh: trimesh.Trimesh, rng: np.random.Generator,
            count: int = FIDELITY_SAMPLES) -> np.ndarray:
    """`count` points on the surface, area-weighted, from `rng`."""
    area = mesh.area_faces
    face = rng.choice(len(area), count, p=area / area.sum())
    u, v = rng.random((2, count))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = mesh.triangles[face]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


RESOLUTION = 1e-4
"""Distances below this fraction of the size are not refined (the bound stands)."""
BRUTE_FORCE = 250_000
"""Up to this many point-face pairs, every point is measured against every face."""


def _max_distance(points: np.ndarray, tri: np.ndarray) -> float:
    """Exact largest distance of the points to the triangles `tri` (F, 3, 3).

    Few points and faces are measured all against all. Otherwise each point's distance is at
    most that to the nearest of the 16 faces with the nearest centres (k-d tree, exact
    point-triangle distances, in one batch); where the true closest face may be another, the
    exact distance over the faces whose box lies within that bound is computed, in order of
    falling bound, until no bound left can beat the largest exact distance (to `RESOLUTION`
    of the size).
    """
    from scipy.spatial import cKDTree

    from vistac_sim.physics.normals import closest_point_on_triangles

    if len(points) == 0:
        return 0.0
    if len(points) * len(tri) <= BRUTE_FORCE:  # every point against every face, in chunks
        step = max(1, BRUTE_FORCE // 8 // len(tri))
        best = 0.0
        for i in range(0, len(points), step):
            p = np.repeat(points[i:i + step], len(tri), axis=0)
            q = closest_point_on_triangles(p, np.tile(tri, (len(p) // len(tri), 1, 1)))
            d = np.sqrt(((q - p) ** 2).sum(1)).reshape(-1, len(tri)).min(axis=1)
            best = max(best, float(d.max()))
        return best
    k = min(16, len(tri))
    _, near = cKDTree(tri.mean(axis=1)).query(points, k=k)
    near = near.reshape(len(points), k)
    rep = np.repeat(points, k, axis=0)
    q = closest_point_on_triangles(rep, tri[near.ravel()])
    bound = np.sqrt(((q - rep) ** 2).sum(1)).reshape(-1, k).min(axis=1)
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    best, slack = 0.0, RESOLUTION * float((hi.max(axis=0) - lo.min(axis=0)).max())
    for k in np.argsort(-bound):
        b, p = float(bound[k]), points[k]
        if b <= best + slack:
            break
        idx = np.flatnonzero(((lo - b <= p) & (p <= hi + b)).all(1))
        q = closest_point_on_triangles(p, tri[idx])
        best = max(best, min(b, float(np.sqrt(((q - p) ** 2).sum(1)).min())))
    return best
