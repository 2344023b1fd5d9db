"""The baseline colour detectors: RGB thresholds chosen by a Boolean LP,
grouped by MSER (``method='rgb_lp'``).

The fixed HSV ranges baseline (``method='hsv'``) shares the blob stage (:mod:`.blobs`).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Sequence

import cv2
import numpy as np

from workzone_ros.core.color_model import ModelError
from workzone_ros.core.detect.candidates import Candidate

__all__ = ['rgb_histograms', 'candidate_rgb_thresholds', 'RgbLpModel', 'fit_rgb_lp', 'MserMixin']


_RGB_Q = 8            # RGB quantisation step for the LP's pixel bins


def rgb_histograms(bgr: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positive / negative pixel counts per quantised RGB bin (32^3 bins)."""
    q = (bgr // _RGB_Q).astype(np.int64)
    n = 256 // _RGB_Q
    idx = (q[..., 2] * n + q[..., 1]) * n + q[..., 0]       # R, G, B order
    m = mask.astype(bool)
    return (np.bincount(idx[m], minlength=n ** 3).astype(np.float64),
            np.bincount(idx[~m], minlength=n ** 3).astype(np.float64))


def _bin_centres() -> np.ndarray:
    n = 256 // _RGB_Q
    r, g, b = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing='ij')
    return (np.column_stack([r.ravel(), g.ravel(), b.ravel()]) * _RGB_Q + _RGB_Q / 2.0)


def candidate_rgb_thresholds(pos_rgb: np.ndarray, levels: Sequence[float] = (
        0.02, 0.1, 0.25, 0.5)) -> np.ndarray:
    """Candidate thresholds (alpha, beta, lambda, t) of Balali and Golparvar-Fard eq. 1.

    Directions: every (alpha, beta, lambda) in {-1, -0.5, 0, 0.5, 1}^3 up to scale; levels t:
    quantiles of the positive pixels' projections (a threshold keeps at least that share
    of them).
    """
    dirs = set()
    for a, b, c in itertools.product((-1.0, -0.5, 0.0, 0.5, 1.0), repeat=3):
        v = np.array([a, b, c])
        if not v.any():
            continue
        dirs.add(tuple(np.round(v / np.abs(v).max(), 3)))
    out = []
    for d in sorted(dirs):
        proj = pos_rgb @ np.array(d)
        for q in levels:
            out.append((*d, float(np.quantile(proj, q))))
    return np.array(out, np.float64)


@dataclass(frozen=True)
class RgbLpModel:
    """The selected thresholds rho* of Balali and Golparvar-Fard (rows alpha, beta, lambda, t
    on R, G, B)."""

    thresholds: np.ndarray
    metadata: dict = field(default_factory=dict)

    def mask(self, bgr: np.ndarray) -> np.ndarray:
        """uint8 count of thresholds each pixel passes (0 = none)."""
        count = np.zeros(bgr.shape[:2], np.uint8)
        f = bgr.astype(np.float32)
        for a, b, c, t in self.thresholds:
            # cv2.transform: BGR -> alpha R + beta G + lambda B
            proj = cv2.transform(f, np.array([[c, b, a]], np.float32))
            count += (proj >= t).astype(np.uint8)
        return count

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for an ``.npz`` next to the colour model."""
        return {'rgb_lp_thresholds': self.thresholds.astype(np.float64)}


def fit_rgb_lp(pos: np.ndarray, neg: np.ndarray, w: float = 1.0, max_thresholds: int = 6,
               max_candidates: int = 80, time_limit: float = 60.0,
               max_bins: int = 3000) -> RgbLpModel:
    """Choose rho* = argmin FP(rho) + w FN(rho) over subsets of thresholds (Balali and
    Golparvar-Fard, eq. 2).

    Boolean linear program over quantised RGB bins with pixel counts as weights: x_k selects
    threshold k, y_i = 1 when positive bin i passes a selected threshold (y_i <= sum_k A_ik
    x_k), z_j = 1 when negative bin j does (deg_j z_j >= sum_k A_jk x_k); minimise
    sum_j n_j z_j + w sum_i p_i (1 - y_i), with at most ``max_thresholds`` thresholds.
    Solved with ``scipy.optimize.milp`` (HiGHS).

    Args:
        pos, neg: counts from :func:`rgb_histograms`.
        w: the weight of a false negative relative to a false positive, in units of the
            class-size ratio (1 = balanced).
        max_thresholds: cardinality bound (each threshold costs time per frame).
        max_candidates: candidates kept after a single-threshold pre-screen.
        max_bins: only the heaviest positive / negative colour bins enter the program (the
            rest hold a small share of the pixels; the reported rates count every bin).
        time_limit: solver time limit in seconds.

    Returns:
        The :class:`RgbLpModel`.
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import csr_matrix, hstack, identity, vstack

    centres = _bin_centres()
    ip, ineg = np.nonzero(pos)[0], np.nonzero(neg)[0]
    ip = ip[np.argsort(pos[ip])[::-1][:max_bins]]
    ineg_all = ineg
    if len(ip) == 0 or len(ineg) == 0:
        raise ModelError('the RGB threshold LP needs both sign and background pixels')
    # w is relative to the class sizes: FP + w (N_neg / N_pos) FN, so w = 1 weighs the
    # classes equally (raw pixel counts make "no threshold at all" optimal: signs are <0.1 %)
    w = w * float(neg.sum()) / float(pos.sum())
    pw, nw = pos[ip], neg[ineg]
    rep = np.repeat(centres[ip], np.minimum(pw, 50).astype(int), axis=0)
    cands = candidate_rgb_thresholds(rep)
    # Pre-screen: the single-threshold objective; keep the best candidates.
    a_pos = (centres[ip] @ cands[:, :3].T) >= cands[:, 3]
    a_neg = (centres[ineg] @ cands[:, :3].T) >= cands[:, 3]
    single = nw @ a_neg + w * (pw @ ~a_pos)
    keep = np.argsort(single)[:max_candidates]
    cands, a_pos, a_neg = cands[keep], a_pos[:, keep], a_neg[:, keep]
    # Only negative bins that some candidate passes matter; the heaviest of them.
    live = np.nonzero(a_neg.any(axis=1))[0]
    live = live[np.argsort(nw[live])[::-1][:max_bins]]
    a_neg, nw = a_neg[live], nw[live]
    k, npos, nneg = len(cands), len(ip), len(nw)
    # variables: x (k), y (npos), z (nneg)
    c = np.concatenate([np.zeros(k), -w * pw, nw]) / (pw.sum() * w + nw.sum())
    ap, an = csr_matrix(a_pos.astype(np.float64)), csr_matrix(a_neg.astype(np.float64))
    deg = np.asarray(an.sum(axis=1)).ravel()
    from scipy.sparse import diags
    rows = [
        hstack([-ap, identity(npos), csr_matrix((npos, nneg))]),          # y - A x <= 0
        hstack([an, csr_matrix((nneg, npos)), -diags(deg)]),              # A x - deg z <= 0
        hstack([csr_matrix(np.ones((1, k))), csr_matrix((1, npos + nneg))]),  # sum x <= m
    ]
    A = vstack(rows).tocsr()
    ub = np.concatenate([np.zeros(npos + nneg), [max_thresholds]])
    res = milp(c, constraints=LinearConstraint(A, -np.inf, ub),
               integrality=np.ones(k + npos + nneg), bounds=Bounds(0, 1),
               options={'time_limit': time_limit, 'disp': False})
    if res.x is None:
        raise ModelError(f'RGB threshold LP failed: {res.message}')
    sel = np.nonzero(res.x[:k] > 0.5)[0]
    chosen = cands[sel]
    allc = centres[ineg_all]
    pass_all = np.zeros(len(ineg_all), bool)
    for a, b, c_, t in chosen:
        pass_all |= allc @ np.array([a, b, c_]) >= t
    pos_all = np.nonzero(pos)[0]
    pass_pos = np.zeros(len(pos_all), bool)
    for a, b, c_, t in chosen:
        pass_pos |= centres[pos_all] @ np.array([a, b, c_]) >= t
    meta = {'w_effective': w, 'candidates': int(k), 'selected': int(len(sel)),
            'fn_rate': float(pos[pos_all][~pass_pos].sum() / pos.sum()),
            'fp_rate': float(neg[ineg_all][pass_all].sum() / neg.sum()),
            'status': str(res.message), 'mip_gap': float(getattr(res, 'mip_gap', 0.0) or 0.0)}
    return RgbLpModel(chosen, meta)


class MserMixin:
    """The detector's MSER grouping of the RGB-LP mask."""

    def _mser_blobs(self, count: np.ndarray, bgr: np.ndarray, off: tuple[int, int],
                    s: int) -> list[Candidate]:
        cfg = self.config
        img = (np.minimum(count, 5) * 50).astype(np.uint8)
        # min_diversity=0: OpenCV 5.0.0 rejects every stable grey-level region otherwise
        # (opencv/opencv#29652, fixed by #29653); 0 restores the 4.x behaviour.
        mser = cv2.MSER_create(cfg.mser_delta, max(4, int(cfg.min_area_px / (s * s))),
                               max(5, int(img.size * 0.25)), 0.25, 0.0)
        # MSER finds dark-on-bright regions; the passing pixels are bright
        _, bboxes = mser.detectRegions(255 - img)
        out = []
        for x, y, w, h in (bboxes if len(bboxes) else []):
            fx, fy, fw, fh = (x + off[0]) * s, (y + off[1]) * s, w * s, h * s
            if min(fw, fh) / 2.0 < cfg.min_radius_px or max(fw, fh) / 2.0 > cfg.max_radius_px:
                continue
            fill = float(np.count_nonzero(count[y:y + h, x:x + w])) / (w * h)
            out.append(Candidate(fx, fy, fw, fh, 'orange', fill, 'unknown', fill * fw * fh))
        return out
