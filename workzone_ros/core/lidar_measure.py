"""Per-cluster measurements of the LiDAR candidate stage (no decisions).

Bounding boxes and covariances of every cluster at once, the rings (rows of returns) each
cluster spans and their spacing, the widest gap along a ring (the hollow test), and the
contrast of a cluster with the dull returns around it (the retroreflective test).  The
decisions are :func:`workzone_ros.core.lidar_clustering.cluster_cloud`'s.

No rclpy here.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

__all__ = ['cluster_stats', 'rows', 'widest_row_gap', 'contrast', 'ROW_GAP_DEG',
           'CONTRAST_MIN_NEIGHBOURS']

#: Points on one ring share an elevation; a gap larger than this (deg) starts another row.
ROW_GAP_DEG = 0.08
#: The fewest dull returns around a cluster to judge its contrast by.
CONTRAST_MIN_NEIGHBOURS = 5


def widest_row_gap(pts: np.ndarray, row: np.ndarray) -> float:
    """Widest inner gap along the face's horizontal axis between returns of one ring.

    Args:
        pts: (N, 3) level-frame points of one cluster.
        row: (N,) their ring (row) keys: a ring crossing a tape outline has a gap, a ring
            across a filled face has only the azimuth spacing.
    """
    if pts.shape[0] < 3:
        return 0.0
    xy = pts[:, :2] - pts[:, :2].mean(axis=0)
    w, v = np.linalg.eigh(xy.T @ xy)
    u = xy @ v[:, 1]
    o = np.lexsort((u, row))
    same = row[o][1:] == row[o][:-1]
    if not same.any():
        return 0.0
    return float(np.diff(u[o])[same].max())


def cluster_stats(xyz: np.ndarray, inten: np.ndarray, labels: np.ndarray, n: int):
    """Bounding boxes, counts, mean intensity and 3x3 covariances per label (vectorised)."""
    order = np.argsort(labels, kind='stable')
    counts = np.bincount(labels, minlength=n)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    sp = xyz[order]
    lo = np.minimum.reduceat(sp, start, axis=0)
    hi = np.maximum.reduceat(sp, start, axis=0)
    mean = np.add.reduceat(sp, start, axis=0) / counts[:, None]
    mi = np.add.reduceat(inten[order], start) / counts
    d = sp - np.repeat(mean, counts, axis=0)
    outer = d[:, :, None] * d[:, None, :]
    cov = np.add.reduceat(outer, start, axis=0) / counts[:, None, None]
    return lo, hi, mean, mi, counts, cov, order, start


def rows(xyz: np.ndarray, labels: np.ndarray, n: int, rings: Optional[np.ndarray]
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rows of returns (rings) of each cluster: a row key per point, the number of rows per
    cluster, their mean spacing in elevation (rad; NaN on a single row) and the highest
    elevation of each cluster (rad).

    With a ``ring`` field the rings are the rows; otherwise rows are told apart by their
    elevation in the sensor's own frame (within a cluster the points of one ring share it).
    """
    el = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
    o = np.lexsort((el, labels))
    el_s, lab_s = el[o], labels[o]
    new_label = lab_s[1:] != lab_s[:-1]
    if rings is not None:
        key = rings.astype(np.int64)
        pair = np.unique(labels.astype(np.int64) * 65536 + (key % 65536))
        rows = np.bincount(pair // 65536, minlength=n)
    else:
        brk = ~new_label & (np.diff(el_s) > math.radians(ROW_GAP_DEG))
        rows = 1 + np.bincount(lab_s[1:][brk], minlength=n)
        key = np.empty(labels.size, np.int64)
        key[o] = np.concatenate([[0], np.cumsum(brk | new_label)])
    counts = np.bincount(labels, minlength=n)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    el_hi = np.maximum.reduceat(el_s, start)
    span = el_hi - np.minimum.reduceat(el_s, start)
    spacing = np.where(rows >= 2, span / np.maximum(rows - 1, 1), np.nan)
    return key, rows, spacing, el_hi


def contrast(points: np.ndarray, thr_raw: float, lo: np.ndarray, hi: np.ndarray,
              margin: np.ndarray, med_raw: np.ndarray) -> np.ndarray:
    """Median raw intensity of each cluster over the 90th percentile of the dull returns
    (below the threshold) inside its lidar-frame box grown by ``margin``; NaN with fewer than
    ``CONTRAST_MIN_NEIGHBOURS`` of them (nothing around to compare with)."""
    out = np.full(lo.shape[0], np.nan)
    if lo.shape[0] == 0:
        return out
    glo, ghi = (lo - margin[:, None]).min(axis=0), (hi + margin[:, None]).max(axis=0)
    xs = points['x']
    cand = np.flatnonzero((xs >= glo[0]) & (xs <= ghi[0]))
    ys, zs, raw = points['y'][cand], points['z'][cand], points['intensity'][cand]
    keep = (ys >= glo[1]) & (ys <= ghi[1]) & (zs >= glo[2]) & (zs <= ghi[2]) & (raw < thr_raw)
    cand = cand[keep]
    near = np.column_stack([xs[cand], ys[keep], zs[keep]]).astype(np.float64)
    raw = raw[keep].astype(np.float64)
    for j in range(lo.shape[0]):
        inside = np.all((near >= lo[j] - margin[j]) & (near <= hi[j] + margin[j]), axis=1)
        if inside.sum() >= CONTRAST_MIN_NEIGHBOURS:
            out[j] = med_raw[j] / max(float(np.percentile(raw[inside], 90)), 1e-6)
    return out
