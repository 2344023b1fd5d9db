"""Sign crops and the feature vectors of the sign classifier (no ROS import).

Seo et al., section III.B (and Lee et al., III.C): a region localised as a potential work-zone
sign is cropped with a margin, its intensity normalised, and it is resampled into a
log-polar image of rho x theta = 32 x 32 bins: dense samples near the centre, where sign
images differ little, sparse ones at the border, where perspective and box jitter distort
them most.  The flattened 1024-vector is what PCA and the SVM see.  The seed's baseline
representation is the crop scaled to 100 x 100 raw intensities (Table III, last rows).

The log-polar image is sampled densely about its centre, so a detector box that is shifted
by 10-20 % of its size (our renders' jitter, and real detectors') moves the sign off the
densest samples.  The ``logpolar-centred`` variant takes the transform about the crop's
foreground (the centroid and spread of the pixels whose colour differs from the crop's
border, :func:`foreground_frame`) after a slight anti-aliasing blur; ``logpolar`` is the
seed's transform about the crop centre, unchanged.

The intensity-only log-polar image loses colour (a drum and an orange diamond look alike in
grey) and can confuse left/right mirror signs after PCA keeps 10 components, so two small
families of *extra* features are available (appended after the PCA, see
``workzone_ros.core.classifier``):

* :func:`color_features`: mean CIE a*, b* chroma on a 3 x 3 grid (18 values) -- which colour
  sits where (orange top / white bottom of R22-1, yellow vs orange diamond, red octagon);
* :func:`mirror_features`: the left half of the antisymmetric part ``g - fliplr(g)`` of the
  normalised grey crop pooled on a 4 x 4 grid (16 values): a sign and its mirror image give
  exactly opposite vectors, a symmetric sign gives zeros.

Crops are BGR ``uint8`` images of any size; every feature first resizes them to a fixed
square (:data:`BASE_SIDE`), so a border crop that is not square is stretched to one.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Optional, Sequence

import cv2
import numpy as np

__all__ = [
    'BASE_SIDE', 'BASES', 'FEATURE_KINDS', 'crop_sign', 'normalised_grey', 'foreground_frame',
    'log_polar_features', 'raw_intensity_features', 'color_features', 'mirror_features',
    'base_features', 'extra_features', 'features',
]

#: Side (px) every crop is resized to before the log-polar transform (2 x rho).
BASE_SIDE = 64
#: Base representations: the seed's log-polar image about the crop centre, ours about the
#: crop's foreground (:func:`foreground_frame`), and the seed's raw-intensity baseline.
BASES = ('logpolar', 'logpolar-centred', 'raw')
#: Feature kinds the trainer accepts: a base, then optional ``+color`` / ``+mirror`` extras.
FEATURE_KINDS = tuple(b + e for b in BASES for e in ('', '+color', '+mirror', '+color+mirror'))
#: Anti-aliasing blur (px) of the centred log-polar variant.
CENTRED_BLUR = 1.0
#: Side (px) of the copy the foreground frame and the colour statistics are measured on.
WORK_SIDE = 32
#: Colour distances up to this percentile of the border frame's count as surroundings.
RING_QUANTILE = 75
_EPS = 1e-6
#: OpenCV's 8-bit Lab stores L * 255 / 100, a* + 128, b* + 128: offsets and squared scales.
_LAB_OFFSET = np.array([0.0, 128.0, 128.0], np.float32)
_LAB_SQ_SCALE = np.array([(100.0 / 255.0) ** 2, 1.0, 1.0], np.float32)


def crop_sign(frame_bgr: np.ndarray, box: tuple[float, float, float, float],
              margin: float = 0.1, square: bool = False
              ) -> tuple[Optional[np.ndarray], float]:
    """The image region of a detection box, grown by a margin and clipped to the image.

    Args:
        frame_bgr: the camera frame (H x W x 3, or H x W).
        box: ``(x, y, w, h)`` in pixels.
        margin: growth on each side, as a fraction of the box size.
        square: first make the box a square of side ``max(w, h)`` around the same centre,
            as the classifier's training crops are (a wide END ROAD WORK panel is then seen
            with some surroundings above and below, never stretched);
            ``SignClassifier.classify_boxes`` does this.

    Returns:
        ``(crop, visible)``: the crop (a view into the frame; ``None`` when no pixel of the
        grown box is inside the image or the box is empty) and the fraction of the grown
        box's area that is inside the image.  A box at the border is cropped to its visible
        part.
    """
    x, y, w, h = (float(v) for v in box)
    if not all(math.isfinite(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
        return None, 0.0
    cx, cy = x + w / 2, y + h / 2
    if square:
        w = h = max(w, h)
    w, h = w * (1 + 2 * margin), h * (1 + 2 * margin)
    x0, y0, x1, y1 = cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2
    H, W = frame_bgr.shape[:2]
    vx = max(0.0, min(x1, W) - max(x0, 0.0))
    vy = max(0.0, min(y1, H) - max(y0, 0.0))
    visible = float(vx * vy / (w * h))
    ix0, iy0 = max(0, int(round(x0))), max(0, int(round(y0)))
    ix1, iy1 = min(W, int(round(x1))), min(H, int(round(y1)))
    if ix1 <= ix0 or iy1 <= iy0:
        return None, visible
    return frame_bgr[iy0:iy1, ix0:ix1], visible


def _square(crop: np.ndarray, side: int) -> np.ndarray:
    """``crop`` resized to ``side`` x ``side`` (area filter when shrinking)."""
    h, w = crop.shape[:2]
    if (h, w) == (side, side):
        return crop
    interp = cv2.INTER_AREA if h >= side and w >= side else cv2.INTER_LINEAR
    return cv2.resize(crop, (side, side), interpolation=interp)


def normalised_grey(crop: np.ndarray, side: int = BASE_SIDE) -> np.ndarray:
    """The crop as a ``side`` x ``side`` float32 grey image of zero mean and unit deviation.

    The intensity normalisation of Seo et al. III.B: exposure, contrast and sheeting
    brightness differ from sign to sign, the layout of dark and bright does not.
    """
    if crop.ndim == 3:
        crop = cv2.cvtColor(np.ascontiguousarray(crop), cv2.COLOR_BGR2GRAY)
    g = _square(crop, side).astype(np.float32)
    return (g - g.mean()) / (g.std() + _EPS)


class _Batch:
    """The crops of one batch as stacked small images, shared by every feature.

    Each crop is resized once to :data:`BASE_SIDE` (BGR); the stack is then processed as
    one tall image where OpenCV allows it (grey, the 2x area reduction to
    :data:`WORK_SIDE`, 8-bit Lab, the log-polar remap), so a batch of 20 crops costs a few
    calls instead of a few hundred.
    """

    def __init__(self, crops: Sequence[np.ndarray], side: int = BASE_SIDE):
        self.n, self.side = len(crops), side
        bgr = np.empty((self.n * side, side, 3), np.uint8)
        for k, crop in enumerate(crops):
            crop = np.ascontiguousarray(crop)
            if crop.ndim == 2:
                crop = cv2.cvtColor(crop, cv2.COLOR_GRAY2BGR)
            bgr[k * side:(k + 1) * side] = _square(crop, side)
        self.bgr = bgr                                           # (n * side, side, 3)
        self._grey: Optional[np.ndarray] = None
        self._lab: Optional[np.ndarray] = None

    def grey(self) -> np.ndarray:
        """Normalised grey crops, (n, side, side) float32, zero mean and unit deviation."""
        if self._grey is None:
            g8 = cv2.cvtColor(self.bgr, cv2.COLOR_BGR2GRAY)
            side = self.side
            stats = np.array([cv2.meanStdDev(g8[k * side:(k + 1) * side])
                              for k in range(self.n)], np.float32).reshape(self.n, 2)
            g = g8.reshape(self.n, side, side).astype(np.float32)
            g -= stats[:, 0, None, None]
            g *= (1.0 / (stats[:, 1] + _EPS))[:, None, None]
            self._grey = g
        return self._grey

    def lab(self) -> np.ndarray:
        """8-bit CIE Lab at :data:`WORK_SIDE` as float32, (n, w, w, 3); see :data:`_LAB`."""
        if self._lab is None:
            w = WORK_SIDE
            small = cv2.resize(self.bgr, (w, self.n * w), interpolation=cv2.INTER_AREA)
            # OpenCV's 8-bit Lab (a table lookup): L * 255 / 100, a* + 128, b* + 128
            lab = cv2.cvtColor(small, cv2.COLOR_BGR2Lab).astype(np.float32)
            self._lab = lab.reshape(self.n, w, w, 3)
        return self._lab


def _ring(work: int, b: int) -> np.ndarray:
    mask = np.zeros((work, work), bool)
    mask[:b] = mask[-b:] = True
    mask[:, :b] = mask[:, -b:] = True
    return mask


def _order_stat(x: np.ndarray, q: float) -> np.ndarray:
    """The order statistic nearest to quantile ``q`` along axis 1 (cheaper than percentile)."""
    k = int(round(q * (x.shape[1] - 1)))
    return np.partition(x, k, axis=1)[:, k]


def _frames(lab: np.ndarray, side: int, spread: float = 1.6) -> np.ndarray:
    """Foreground centre and radius of each crop (see :func:`foreground_frame`): (n, 3)."""
    n, work = lab.shape[:2]
    ring = _ring(work, max(1, work // 16)).ravel()
    X = lab.reshape(n, work * work, 3)
    med = _order_stat(X[:, ring], 0.5)                           # (n, 3)
    # |x - med|^2 in CIE units (L rescaled), expanded: numpy is slow on a trailing axis of 3
    wm = _LAB_SQ_SCALE * med
    d2 = (X * X) @ _LAB_SQ_SCALE - 2.0 * (X @ wm[:, :, None])[..., 0] \
        + (wm * med).sum(axis=1)[:, None]
    dist = np.sqrt(np.maximum(d2, 0.0))
    thr = _order_stat(dist[:, ring], RING_QUANTILE / 100.0)
    w = np.maximum(dist - thr[:, None], 0.0)
    w *= w
    w = w.reshape(n, work, work)
    u = np.arange(work, dtype=np.float32)
    row, col = w.sum(axis=2), w.sum(axis=1)                    # (n, work): over x, over y
    m00 = row.sum(axis=1)
    ok = m00 >= 1e-3
    m00 = np.where(ok, m00, 1.0)
    cx, cy = col @ u / m00, row @ u / m00
    r2 = np.maximum((col @ (u * u) + row @ (u * u)) / m00 - cx * cx - cy * cy, 0.0)
    scale = side / work
    out = np.empty((n, 3))
    # a work-px pixel centre u is at (u + 0.5) * scale - 0.5 in the side-px crop
    out[:, 0] = np.where(ok, (cx + 0.5) * scale - 0.5, (side - 1) / 2.0)
    out[:, 1] = np.where(ok, (cy + 0.5) * scale - 0.5, (side - 1) / 2.0)
    out[:, 2] = np.where(ok, np.clip(spread * np.sqrt(r2) * scale, 0.3 * side, 0.7 * side),
                         side / 2.0)
    return out


def foreground_frame(crop: np.ndarray, side: int = BASE_SIDE, spread: float = 1.6
                     ) -> tuple[float, float, float]:
    """Centre and radius of the object in a crop, in the ``side`` x ``side`` resized crop.

    On a 32 px copy (:data:`WORK_SIDE`), pixels are weighted by how far their CIE Lab colour
    is from the median colour of the crop's border frame (1/16 of the side: the
    surroundings), beyond the 75th percentile of that distance over the frame, squared.  The
    centre is the weighted centroid, the radius ``spread`` times the weighted RMS distance
    from it, clipped to 0.3-0.7 ``side``.  A detector box that is shifted or too large by
    10-20 % then still puts the sign at the log-polar centre and scale.  A crop without a
    distinct object gives the crop centre and half its side.
    """
    cx, cy, r = _frames(_Batch([crop]).lab(), side, spread)[0]
    return float(cx), float(cy), float(r)


def _log_polar(grey: np.ndarray, rho: int, theta: int) -> np.ndarray:
    """``cv2.warpPolar`` (log radius) of a square grey image about its centre: theta x rho."""
    side = grey.shape[0]
    c = (side - 1) / 2.0
    return cv2.warpPolar(grey, (rho, theta), (c, c), side / 2.0,
                         cv2.INTER_LINEAR | cv2.WARP_POLAR_LOG)


@lru_cache(maxsize=8)
def _log_polar_grid(rho: int, theta: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """cos, sin of warpPolar's angles and its log radius exponents i / rho."""
    a = 2 * np.pi * np.arange(theta, dtype=np.float64) / theta
    return (np.cos(a).astype(np.float32), np.sin(a).astype(np.float32),
            (np.arange(rho, dtype=np.float32) / rho))


def _centred_log_polar(batch: _Batch, rho: int, theta: int) -> np.ndarray:
    """Log-polar images about each crop's foreground frame: (n, theta, rho) float32.

    The sampling grid is warpPolar's (``WARP_POLAR_LOG``: radius ``R ** (i / rho) - 1``),
    centred on :func:`foreground_frame`; it is sampled with one ``cv2.remap`` over the
    stacked, slightly blurred crops, coordinates clipped to each crop (its border repeats).
    """
    side, n = batch.side, batch.n
    frames = _frames(batch.lab(), side).astype(np.float32)
    # blur every crop in one call: stacked with 4 repeated border rows between them
    pad = 4
    padded = np.empty((n, side + 2 * pad, side), np.float32)
    padded[:, pad:-pad] = batch.grey()
    padded[:, :pad] = padded[:, pad:pad + 1]
    padded[:, -pad:] = padded[:, -pad - 1:-pad]
    blurred = cv2.GaussianBlur(padded.reshape(-1, side), (0, 0), CENTRED_BLUR)
    tall = np.ascontiguousarray(blurred.reshape(n, -1, side)[:, pad:-pad]).reshape(-1, side)
    cos, sin, expo = _log_polar_grid(rho, theta)
    r = frames[:, 2:3] ** expo[None, :] - 1.0                               # (n, rho)
    map_x = frames[:, 0, None, None] + cos[None, :, None] * r[:, None, :]     # (n, th, rho)
    map_y = frames[:, 1, None, None] + sin[None, :, None] * r[:, None, :]
    np.clip(map_x, 0, side - 1, out=map_x)
    np.clip(map_y, 0, side - 1, out=map_y)
    map_y += (np.arange(n, dtype=np.float32) * side)[:, None, None]
    out = cv2.remap(tall, map_x.reshape(n * theta, rho), map_y.reshape(n * theta, rho),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(n, theta, rho)


def log_polar_features(crops: Sequence[np.ndarray], rho: int = 32, theta: int = 32, *,
                       centred: bool = False) -> np.ndarray:
    """Log-polar intensity vectors (Seo et al. III.B): one row of ``rho * theta`` per crop.

    Each crop is resized to ``2 * rho`` square, grey-normalised (:func:`normalised_grey`)
    and resampled on ``theta`` angles x ``rho`` log-spaced radii out to the inscribed
    circle (the seed).  With ``centred`` the transform is taken about the crop's foreground
    instead (:func:`foreground_frame`), after a Gaussian blur of :data:`CENTRED_BLUR` px that
    keeps the sparse outer rings from aliasing.

    Returns:
        float32 array ``(len(crops), rho * theta)``.
    """
    if centred:
        return _chunked(lambda b: _centred_log_polar(b, rho, theta).reshape(b.n, -1), crops,
                        rho * theta, 2 * rho)
    out = np.empty((len(crops), rho * theta), np.float32)
    for i, crop in enumerate(crops):
        out[i] = _log_polar(normalised_grey(crop, 2 * rho), rho, theta).ravel()
    return out


def raw_intensity_features(crops: Sequence[np.ndarray], size: int = 100) -> np.ndarray:
    """The seed's baseline: each crop scaled to ``size`` x ``size`` grey, normalised, flattened.

    Returns:
        float32 array ``(len(crops), size * size)``.
    """
    out = np.empty((len(crops), size * size), np.float32)
    for i, crop in enumerate(crops):
        out[i] = normalised_grey(crop, size).ravel()
    return out


def _colors(batch: _Batch, grid: int = 3) -> np.ndarray:
    n, w = batch.n, WORK_SIDE
    ab = np.ascontiguousarray(batch.lab()[..., 1:]).reshape(n * w, w, 2)
    cells = cv2.resize(ab, (grid, n * grid), interpolation=cv2.INTER_AREA) - _LAB_OFFSET[1:]
    return cells.reshape(n, 2 * grid * grid)


def _mirrors(batch: _Batch, grid: int = 4) -> np.ndarray:
    n, side, half = batch.n, 8 * grid, 4 * grid
    g = cv2.resize(batch.grey().reshape(n * batch.side, batch.side), (side, n * side),
                   interpolation=cv2.INTER_AREA).reshape(n, side, side)
    anti = (g - g[:, :, ::-1])[:, :, :half]
    return anti.reshape(n, grid, side // grid, grid, half // grid).mean(axis=(2, 4)).reshape(
        n, grid * grid)


def color_features(crops: Sequence[np.ndarray], grid: int = 3) -> np.ndarray:
    """Mean CIE a*, b* chroma of each cell of a ``grid`` x ``grid`` partition of the crop.

    Returns:
        float32 array ``(len(crops), 2 * grid * grid)`` (a*, b* in about -100..100), per
        cell (row-major) a* then b*.
    """
    return _chunked(lambda b: _colors(b, grid), crops, 2 * grid * grid)


def mirror_features(crops: Sequence[np.ndarray], grid: int = 4) -> np.ndarray:
    """Left-right asymmetry: the left half of ``g - fliplr(g)`` pooled on ``grid`` x ``grid``.

    ``g`` is the normalised grey crop at ``8 * grid`` px; a sign and its mirror image
    (W1-4L / W1-4R, W4-2L / W4-2R, W20-5L / W20-5R) give exactly opposite vectors.

    Returns:
        float32 array ``(len(crops), grid * grid)``.
    """
    return _chunked(lambda b: _mirrors(b, grid), crops, grid * grid)


def _parts(kind: str) -> tuple[str, tuple[str, ...]]:
    if kind not in FEATURE_KINDS:
        raise ValueError(f'unknown feature kind {kind!r}; known: {", ".join(FEATURE_KINDS)}')
    base, *extras = kind.split('+')
    return base, tuple(extras)


def base_features(kind: str, crops: Sequence[np.ndarray], rho: int = 32, theta: int = 32,
                  raw_size: int = 100) -> np.ndarray:
    """The representation PCA reduces: log-polar or raw intensity, by ``kind``."""
    base, _ = _parts(kind)
    if base == 'logpolar':
        return log_polar_features(crops, rho, theta)
    if base == 'logpolar-centred':
        return log_polar_features(crops, rho, theta, centred=True)
    return raw_intensity_features(crops, raw_size)


def extra_features(kind: str, crops: Sequence[np.ndarray]) -> Optional[np.ndarray]:
    """The extra features of ``kind`` appended after PCA (``None`` when it has none)."""
    _, extras = _parts(kind)
    blocks = [color_features(crops) if e == 'color' else mirror_features(crops)
              for e in extras]
    return np.hstack(blocks) if blocks else None


def features(kind: str, crops: Sequence[np.ndarray], rho: int = 32, theta: int = 32,
             raw_size: int = 100) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``(base_features, extra_features)`` of ``kind`` in one pass over the crops.

    The same values as the two functions, with the crops resized once and their grey and
    Lab images shared (what the classifier runs per frame).
    """
    base, extras = _parts(kind)
    if base != 'logpolar-centred' or not len(crops):
        return base_features(kind, crops, rho, theta, raw_size), extra_features(kind, crops)

    def one(batch: _Batch) -> np.ndarray:
        blocks = [_centred_log_polar(batch, rho, theta).reshape(batch.n, -1)]
        blocks += [_colors(batch) if e == 'color' else _mirrors(batch) for e in extras]
        return np.hstack(blocks)
    width = {'color': 18, 'mirror': 16}
    both = _chunked(one, crops, rho * theta + sum(width[e] for e in extras), 2 * rho)
    return both[:, :rho * theta], (both[:, rho * theta:] if extras else None)


def _chunked(fn, crops: Sequence[np.ndarray], width: int, side: int = BASE_SIDE,
             chunk: int = 256) -> np.ndarray:
    """``fn(_Batch)`` over chunks of ``crops`` (OpenCV limits an image to 32767 rows)."""
    out = np.empty((len(crops), width), np.float32)
    for start in range(0, len(crops), chunk):
        part = crops[start:start + chunk]
        out[start:start + len(part)] = fn(_Batch(part, side))
    return out
