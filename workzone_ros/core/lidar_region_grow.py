"""Region growing for LiDAR clusters: connected components of "closer than d(r)".

Cahail et al. s1.3 grows regions from seed points, joining a point when it is closer than a
threshold that grows with range, ``d(r) = d0 + k * r``.  The seed's O(N^2) seed-and-grow
loop is replaced by an equivalent graph formulation: the clusters are the connected
components of the "closer than d" graph (single linkage), built on a voxel grid of side
``d0 / sqrt(3)`` -- points sharing a voxel are always closer than ``d0`` -- so dense sign
faces collapse to a few voxels; voxel pairs are decided by bounds on their centroid
distance, and only the ambiguous pairs are checked point against point.  With ``k = 0`` the
partition is exactly DBSCAN's with ``min_samples=1`` and ``eps = d0`` (``bench lidar``
checks it).

No rclpy here.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = ['region_grow']


def region_grow(xyz: np.ndarray, d0: float, k: float = 0.0,
                voxel: float = 0.0) -> np.ndarray:
    """Connected components of "closer than ``d(r) = d0 + k r``" (Cahail et al. s1.3 clustering).

    Args:
        xyz: (N, 3) points.
        d0: distance threshold at range 0 (the fixed radius when ``k == 0``).
        k: growth of the threshold per metre of horizontal range.
        voxel: voxel side; 0 or anything above ``d0 / sqrt(3)`` uses ``d0 / sqrt(3)``, the
            side that guarantees that points sharing a voxel are connected.

    Returns:
        (N,) int64 labels 0..C-1, numbered in order of first appearance.
    """
    n = xyz.shape[0]
    if n == 0:
        return np.zeros(0, np.int64)
    side = d0 / math.sqrt(3.0) * (1.0 - 1e-9)
    if 0 < voxel < side:
        side = voxel
    keys = np.floor((xyz - xyz.min(axis=0)) / side).astype(np.int64)
    span = keys.max(axis=0) + 1
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    uniq, vox = np.unique(flat, return_inverse=True)
    m = uniq.size
    order = np.argsort(vox, kind='stable')
    counts = np.bincount(vox, minlength=m)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    sp = xyz[order]
    cen = np.add.reduceat(sp, start, axis=0) / counts[:, None]
    rad = np.sqrt(np.maximum.reduceat(((sp - cen[np.repeat(np.arange(m), counts)]) ** 2)
                                      .sum(axis=1), start))
    vrange = np.hypot(cen[:, 0], cen[:, 1])
    if m > 1:
        reach = d0 + k * float(vrange.max()) + 2.0 * float(rad.max())
        pairs = cKDTree(cen).query_pairs(reach, output_type='ndarray')
    else:
        pairs = np.zeros((0, 2), np.int64)
    if pairs.size:
        a, b = pairs[:, 0], pairs[:, 1]
        dc = np.linalg.norm(cen[a] - cen[b], axis=1)
        thr = d0 + k * 0.5 * (vrange[a] + vrange[b])
        sure = dc + rad[a] + rad[b] <= thr
        maybe = ~sure & (dc - rad[a] - rad[b] <= thr)
        link = sure
        if maybe.any():
            link = sure.copy()
            link[np.flatnonzero(maybe)] = _any_pair_within(
                sp, start, counts, a[maybe], b[maybe], thr[maybe])
        a, b = a[link], b[link]
        graph = coo_matrix((np.ones(a.size, np.int8), (a, b)), shape=(m, m))
        _, vlab = connected_components(graph, directed=False)
    else:
        vlab = np.arange(m)
    labels = vlab[vox]
    # Renumber by first appearance so labels do not depend on voxel order.
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first)] = np.arange(first.size)
    return rank[np.searchsorted(np.unique(labels), labels)]


def _any_pair_within(sp: np.ndarray, start: np.ndarray, counts: np.ndarray, a: np.ndarray,
                     b: np.ndarray, thr: np.ndarray, chunk: int = 1_000_000) -> np.ndarray:
    """For voxel pairs (a, b): is any point of a within ``thr`` of any point of b (exact)."""
    out = np.zeros(a.size, bool)
    na, nb = counts[a], counts[b]
    sizes = na * nb
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    lo = 0
    while lo < a.size:      # chunks of voxel pairs with at most ~chunk point pairs
        hi = int(np.searchsorted(bounds, bounds[lo] + chunk, side='right'))
        hi = min(max(hi - 1, lo + 1), a.size)
        rep = sizes[lo:hi]
        pid = np.repeat(np.arange(lo, hi), rep)
        local = np.arange(int(rep.sum())) - np.repeat(bounds[lo:hi] - bounds[lo], rep)
        ia = start[a[pid]] + local // nb[pid]
        ib = start[b[pid]] + local % nb[pid]
        d2 = ((sp[ia] - sp[ib]) ** 2).sum(axis=1)
        hit = np.bincount(pid - lo, weights=(d2 <= thr[pid] ** 2), minlength=hi - lo)
        out[lo:hi] = hit > 0
        lo = hi
    return out
