"""Kernel-weighted hue-saturation histograms and mean-shift localisation.

The target is a hue-saturation histogram weighted by a kernel (the Epanechnikov profile times
the detection's shape mask: Lee et al., eq. 1); a candidate is moved by mean-shift until the
shift is small, and candidates are compared by their Bhattacharyya coefficient.  Everything
runs on a :class:`SearchWindow` sub-sampled on a regular grid, so a track costs the same
whatever the sign's size.  :func:`camshift_localise` is the OpenCV CamShift peer.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Optional

import cv2
import numpy as np

from workzone_ros.core.track.config import TrackerConfig, TrackingError

if TYPE_CHECKING:        # (the target model is built from a search window)
    from workzone_ros.core.track.appearance import TargetModel

__all__ = ['bhattacharyya', 'SearchWindow', 'meanshift_localise', 'camshift_localise', 'score_box']


def _luts(nh: int, ns: int) -> np.ndarray:
    """(1, 256, 3) uint8 look-up table: hue -> hue bin, saturation -> saturation bin."""
    if nh > 256 or ns > 256:
        raise TrackingError('at most 256 hue and saturation bins')
    v = np.arange(256)
    lut = np.zeros((1, 256, 3), np.uint8)
    lut[0, :, 0] = np.minimum(v, 179) * nh // 180        # OpenCV 8-bit hue is 0..179
    lut[0, :, 1] = v * ns // 256
    return lut


def bhattacharyya(p: np.ndarray, q: np.ndarray) -> float:
    """Bhattacharyya coefficient of two normalized histograms (Lee et al., B(t, c))."""
    return float(np.sqrt(p * q).sum())


class SearchWindow:
    """A sub-sampled HSV view of a frame region and its hue-saturation bin index.

    Attributes:
        x0, y0: full-resolution pixel of grid sample (0, 0).
        stride: grid spacing in pixels.
        xs, ys: full-resolution coordinates of the grid columns / rows (float64).
        hsv: (ny, nx, 3) uint8 HSV samples.
        bins: (ny, nx) intp hue-saturation bin of each sample.
    """

    __slots__ = ('x0', 'y0', 'stride', 'xs', 'ys', 'hsv', 'bins', 'nx', 'ny')

    def __init__(self, frame: np.ndarray, x0: int, y0: int, x1: int, y1: int, stride: int,
                 luts: np.ndarray) -> None:
        h, w = frame.shape[:2]
        x0, y0 = max(0, int(x0)), max(0, int(y0))
        x1, y1 = min(w, int(x1)), min(h, int(y1))
        self.x0, self.y0, self.stride = x0, y0, int(stride)
        if x1 <= x0 or y1 <= y0:
            self.hsv = np.zeros((0, 0, 3), np.uint8)
        else:
            sub = np.ascontiguousarray(frame[y0:y1:self.stride, x0:x1:self.stride])
            self.hsv = cv2.cvtColor(sub, cv2.COLOR_BGR2HSV)
        self.ny, self.nx = self.hsv.shape[:2]
        # Pixel centres in continuous image coordinates (pixel j covers [j, j + 1)).
        self.xs = x0 + 0.5 + self.stride * np.arange(self.nx, dtype=np.float64)
        self.ys = y0 + 0.5 + self.stride * np.arange(self.ny, dtype=np.float64)
        if self.hsv.size:
            hb, sb, _ = cv2.split(cv2.LUT(self.hsv, luts))
            ns = int(luts[0, 255, 1]) + 1
            self.bins = cv2.addWeighted(hb, ns, sb, 1, 0, dtype=cv2.CV_16U)
        else:
            self.bins = np.zeros((0, 0), np.uint16)

    def span(self, zx: float, zy: float, ax: float, ay: float) -> tuple[int, int, int, int]:
        """Grid index ranges ``(kx0, kx1, ky0, ky1)`` of the box centred at z, half-size a."""
        s = self.stride
        kx0 = max(0, math.ceil((zx - ax - self.x0 - 0.5) / s))
        kx1 = min(self.nx, math.floor((zx + ax - self.x0 - 0.5) / s) + 1)
        ky0 = max(0, math.ceil((zy - ay - self.y0 - 0.5) / s))
        ky1 = min(self.ny, math.floor((zy + ay - self.y0 - 0.5) / s) + 1)
        return kx0, kx1, ky0, ky1


def _stride(ax: float, ay: float, max_samples: int) -> int:
    """Grid spacing so that a box of half-size (ax, ay) holds at most ``max_samples``."""
    return max(1, math.ceil(math.sqrt(4.0 * ax * ay / max_samples)))


def _kernel(win: SearchWindow, mask: np.ndarray, zx: float, zy: float, ax: float,
            ay: float):
    """Kernel of eq. 1 at centre z: Epanechnikov profile times the shape mask.

    Returns:
        ``(bins, k, xs, ys)`` of the samples inside the box, or None when it holds fewer than
        four samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return None
    xs, ys = win.xs[kx0:kx1], win.ys[ky0:ky1]
    px = (xs - zx) / ax
    py = (ys - zy) / ay
    g = mask.shape[0]
    ix = np.minimum(((px + 1.0) * (g / 2)).astype(np.intp), g - 1)   # px is in [-1, 1]
    iy = np.minimum(((py + 1.0) * (g / 2)).astype(np.intp), g - 1)
    k = (1.0 - py * py)[:, None] - (px * px)[None, :]       # Epanechnikov profile 1 - |p|^2
    np.maximum(k, 0.0, out=k)
    k *= mask.take(iy, axis=0).take(ix, axis=1)
    return win.bins[ky0:ky1, kx0:kx1], k, xs, ys


def _surround(win: SearchWindow, mask: np.ndarray, zx: float, zy: float, ax: float,
              ay: float, size: float, nb: int) -> Optional[np.ndarray]:
    """Normalized histogram of the samples outside the candidate's shape, inside ``size``
    times its box (uniform weights)."""
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax * size, ay * size)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return None
    px = (win.xs[kx0:kx1] - zx) / ax
    py = (win.ys[ky0:ky1] - zy) / ay
    g = mask.shape[0]
    inx = np.abs(px) < 1.0
    iny = np.abs(py) < 1.0
    ix = np.minimum(np.maximum(((px + 1.0) * (g / 2)).astype(np.intp), 0), g - 1)
    iy = np.minimum(np.maximum(((py + 1.0) * (g / 2)).astype(np.intp), 0), g - 1)
    shape = mask.take(iy, axis=0).take(ix, axis=1) > 0
    shape &= iny[:, None]
    shape &= inx[None, :]
    ring = win.bins[ky0:ky1, kx0:kx1][~shape]
    if ring.size < 4:
        return None
    h = np.bincount(ring, minlength=nb).astype(np.float64)
    return h / ring.size


def _histogram(bins: np.ndarray, k: np.ndarray, nb: int) -> Optional[np.ndarray]:
    p = np.bincount(bins.ravel(), k.ravel(), nb)
    total = p.sum()
    if total <= 0:
        return None
    return p / total


def meanshift_localise(win: SearchWindow, target: TargetModel, zx: float, zy: float,
                       ax: float, ay: float, cfg: TrackerConfig
                       ) -> tuple[float, float, float, float, float]:
    """Lee et al.'s multi-scale mean-shift: five kernel sizes, eq. 3, best Bhattacharyya.

    Args:
        win: search window of the current frame.
        target: the track's model.
        zx, zy: start centre (previous or predicted anchor centre).
        ax, ay: previous anchor half-size.
        cfg: tracker configuration (scales, iterations, threshold).

    Returns:
        ``(cx, cy, half_w, half_h, rho, ring)`` of the best candidate: rho = 0 when none
        converged; ring is the Bhattacharyya coefficient of the target and the candidate's
        surroundings (None when ``surround_weight`` is 0: the seed's rule does not look).
    """
    nb = target.q.size
    q, qw, mask = target.q, target.qw, target.mask
    eps2 = cfg.shift_threshold_px ** 2
    best = (zx, zy, ax, ay, 0.0, None)
    best_score = -math.inf
    start = (zx, zy)
    for scale in cfg.scales:
        bx, by = ax * scale, ay * scale
        cx, cy = start
        rho = 0.0
        converged = False
        for _ in range(cfg.max_iterations):
            kern = _kernel(win, mask, cx, cy, bx, by)
            if kern is None:
                break
            bins, k, xs, ys = kern
            p = _histogram(bins, k, nb)
            if p is None:
                break
            rho = bhattacharyya(p, q)
            ratio = np.sqrt(qw / np.maximum(p, 1e-12))
            wts = ratio.take(bins)
            wts *= k > 0                                    # eq. 3: w_i * mask on the support
            total = wts.sum()
            if total <= 0:
                break
            nx = float(wts.sum(axis=0) @ xs) / total
            ny = float(wts.sum(axis=1) @ ys) / total
            moved2 = (nx - cx) ** 2 + (ny - cy) ** 2
            cx, cy = nx, ny
            if moved2 < eps2:
                converged = True      # rho of the last evaluation stands (moved < threshold)
                break
        if not converged:
            kern = _kernel(win, mask, cx, cy, bx, by)
            if kern is not None:
                p = _histogram(kern[0], kern[1], nb)
                rho = bhattacharyya(p, q) if p is not None else 0.0
            else:
                rho = 0.0
        score = rho
        ring_sim = None
        if cfg.surround_weight > 0 and rho > 0:
            ring = _surround(win, mask, cx, cy, bx, by, cfg.surround_size, nb)
            if ring is not None:
                ring_sim = bhattacharyya(ring, q)
                score -= cfg.surround_weight * ring_sim
        if score > best_score:
            best, best_score = (cx, cy, bx, by, rho, ring_sim), score
        if scale == cfg.scales[0]:
            start = (cx, cy)          # the other sizes start where the first one converged
    return best


def camshift_localise(win: SearchWindow, target: TargetModel, zx: float, zy: float,
                      ax: float, ay: float, cfg: TrackerConfig
                      ) -> tuple[float, float, float, float, float]:
    """OpenCV CamShift on the hue back-projection of the same search window (the peer).

    The similarity reported is the same kernel Bhattacharyya coefficient as mean-shift's, at
    the CamShift box, so both methods share the track-life rules.

    Returns:
        ``(cx, cy, half_w, half_h, rho, None)`` (ring: see :func:`meanshift_localise`).
    """
    if win.nx < 2 or win.ny < 2:
        return zx, zy, ax, ay, 0.0, None
    s = win.stride
    hsv = win.hsv
    bp = cv2.calcBackProject([hsv], [0], target.hue_hist, [0, 180], 1)
    bp[(hsv[..., 1] < 60) | (hsv[..., 2] < 32)] = 0
    gx0 = int(round((zx - ax - win.x0) / s))
    gy0 = int(round((zy - ay - win.y0) / s))
    gw = max(1, int(round(2 * ax / s)))
    gh = max(1, int(round(2 * ay / s)))
    gx0 = min(max(gx0, 0), win.nx - 1)
    gy0 = min(max(gy0, 0), win.ny - 1)
    gw, gh = min(gw, win.nx - gx0), min(gh, win.ny - gy0)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, cfg.max_iterations,
            max(cfg.shift_threshold_px / s, 0.1))
    _, (x, y, w, h) = cv2.CamShift(bp, (gx0, gy0, gw, gh), crit)
    if w <= 0 or h <= 0:
        return zx, zy, ax, ay, 0.0, None
    cx = win.x0 + s * (x + w / 2.0)
    cy = win.y0 + s * (y + h / 2.0)
    bx, by = s * w / 2.0, s * h / 2.0
    kern = _kernel(win, target.mask, cx, cy, bx, by)
    rho = 0.0
    if kern is not None:
        p = _histogram(kern[0], kern[1], target.q.size)
        rho = bhattacharyya(p, target.q) if p is not None else 0.0
    return cx, cy, bx, by, rho, None


def score_box(win: SearchWindow, target: TargetModel, cx: float, cy: float, bx: float,
              by: float, cfg: TrackerConfig) -> tuple[float, float]:
    """Target agreement of the box centred at (cx, cy), half-size (bx, by), as mean-shift
    scores its candidates: ``(rho, ring)``, the Bhattacharyya coefficients of the target
    with the kernel histogram (eq. 1 with the target's shape mask) and with the
    surroundings up to ``surround_size`` times the box (0 when either is empty)."""
    nb = target.q.size
    rho = ring_sim = 0.0
    kern = _kernel(win, target.mask, cx, cy, bx, by)
    if kern is not None:
        p = _histogram(kern[0], kern[1], nb)
        rho = bhattacharyya(p, target.q) if p is not None else 0.0
    ring = _surround(win, target.mask, cx, cy, bx, by, cfg.surround_size, nb)
    if ring is not None:
        ring_sim = bhattacharyya(ring, target.q)
    return rho, ring_sim
