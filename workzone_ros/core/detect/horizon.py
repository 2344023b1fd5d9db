"""The horizon row of a frame from its lane lines' vanishing point.
"""
from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

__all__ = ['estimate_horizon']


def estimate_horizon(bgr: np.ndarray, width: int = 320, top: float = 0.3, bottom: float = 0.95,
                     min_angle: float = 15.0, max_angle: float = 75.0, min_len: float = 0.07,
                     min_pairs: int = 3, max_spread: float = 0.04) -> Optional[float]:
    """The horizon row of one frame from the vanishing point of the road's lane lines.

    Line segments (Canny + probabilistic Hough, on the frame scaled to ``width``) between
    rows ``top`` and ``bottom`` (fractions of the height) that slope by ``min_angle`` ..
    ``max_angle`` degrees are split into left-leaning (rising to the right) and
    right-leaning ones; every left / right pair is intersected, and the length-weighted
    median row of the intersections is the horizon (a level road's lane lines meet there).

    Returns:
        The horizon row in pixels of ``bgr``, or None when the estimate is unreliable: fewer
        than ``min_pairs`` pairs, or the weighted median absolute deviation of the
        intersection rows above ``max_spread`` x the height, or a vanishing point below the
        top of the segments that define it.
    """
    H, W = bgr.shape[:2]
    if H < 16 or W < 16:
        return None
    f = min(1.0, width / float(W))
    small = cv2.resize(bgr, (max(16, int(W * f)), max(16, int(H * f))),
                       interpolation=cv2.INTER_AREA) if f < 1.0 else bgr
    h, w = small.shape[:2]
    y0, y1 = int(top * h), int(bottom * h)
    gray = cv2.cvtColor(small[y0:y1], cv2.COLOR_BGR2GRAY)
    edges = cv2.Canny(gray, 60, 160)
    segs = cv2.HoughLinesP(edges, 1, np.pi / 180, 18, minLineLength=max(6, int(min_len * w)),
                           maxLineGap=4)
    if segs is None or len(segs) < 2:
        return None
    seg = np.asarray(segs).reshape(-1, 4).astype(np.float64)
    seg[:, [1, 3]] += y0
    dx, dy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    ang = np.degrees(np.arctan2(np.abs(dy), np.abs(dx)))
    keep = (ang >= min_angle) & (ang <= max_angle)
    seg, dx, dy = seg[keep], dx[keep], dy[keep]
    if len(seg) < 2:
        return None
    slope = dy / np.where(dx == 0, 1e-9, dx)
    length = np.hypot(dx, dy)
    left, right = slope < 0, slope > 0           # y down: a left lane line rises to the right
    if not left.any() or not right.any():
        return None
    # lines y = y_a + m (x - x_a); intersect every left with every right
    la, ra = seg[left], seg[right]
    ml, mr = slope[left][:, None], slope[right][None, :]
    xl, yl = la[:, 0][:, None], la[:, 1][:, None]
    xr, yr = ra[:, 0][None, :], ra[:, 1][None, :]
    x = (yr - yl + ml * xl - mr * xr) / (ml - mr)
    y = yl + ml * (x - xl)
    wgt = length[left][:, None] * length[right][None, :]
    # the vanishing point lies above both segments and not far outside the frame
    top_l = np.minimum(la[:, 1], la[:, 3])[:, None]
    top_r = np.minimum(ra[:, 1], ra[:, 3])[None, :]
    ok = ((y <= np.minimum(top_l, top_r) + 2) & (y >= 0.05 * h) & (x >= -0.25 * w)
          & (x <= 1.25 * w))
    if np.count_nonzero(ok) < min_pairs:
        return None
    ys, ws = y[ok], wgt[ok]
    order = np.argsort(ys)
    ys, ws = ys[order], ws[order]
    cw = np.cumsum(ws)
    med = float(ys[np.searchsorted(cw, 0.5 * cw[-1])])
    dev = np.abs(ys - med)
    o2 = np.argsort(dev)
    mad = float(dev[o2][np.searchsorted(np.cumsum(ws[o2]), 0.5 * cw[-1])])
    if mad > max_spread * h:
        return None
    return med / f
