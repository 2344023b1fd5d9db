"""Colour stage of the general sign recogniser: working image, colour masks, blobs.

Cahail, Vera, Daddeo, Shelton, Menz, Long, "Traffic Sign Detection" (UT Austin), section
3.4.2: a colour blob filter marks the pixels inside one of two HSV ranges (the red of STOP,
YIELD and DO NOT ENTER, the yellow of warning signs) in two binary images; an erosion removes
the small noisy regions, a dilation joins what remains into a few larger blobs; a blob is kept
when its width / height ratio is near 1 and its bounding box area is less than its area
times a constant.

Two additions, both measured on development renders (docs/general_signs.md): the frame is
grey-world white balanced first (dusk light moves red sheeting into orange's hues otherwise),
and each kept blob's colour is verified by the median hue of all its saturated pixels, so an
orange work-zone sign whose darker edge falls in the red range is not a red blob.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.general.config import GeneralConfig

__all__ = ['Working', 'Blob', 'working_image', 'red_mask', 'yellow_mask', 'white_mask',
           'green_mask', 'clean', 'blobs', 'median_hue', 'merge_stacked', 'iou']


@dataclass(frozen=True)
class Working:
    """The frame as the colour stage sees it.

    Attributes:
        bgr: white-balanced working image (shrunk to ``work_width``).
        hsv: its HSV (OpenCV ranges).
        scale: full-image px per working px.
        gains: the B, G, R white balance gains (apply them to full-image crops).
    """

    bgr: np.ndarray
    hsv: np.ndarray
    scale: float
    gains: np.ndarray


@dataclass(frozen=True)
class Blob:
    """A blob in working-image px: box (x, y, w, h), filled area (holes included) and the
    outer contours it is made of (image coordinates); ``bridges`` are rectangles (x, y, w, h)
    filled between stacked pieces."""

    box: tuple[int, int, int, int]
    area: float
    contours: tuple = ()
    bridges: tuple = ()

    @cached_property
    def mask(self) -> np.ndarray:
        """The filled outline as a uint8 0/1 mask of the box (drawn on first use)."""
        x, y, w, h = self.box
        m = np.zeros((h, w), np.uint8)
        cv2.drawContours(m, [c - np.array([x, y]) for c in self.contours], -1, 1, -1)
        for bx, by, bw, bh in self.bridges:
            m[by - y:by - y + bh, bx - x:bx - x + bw] = 1
        return m

    @property
    def fill(self) -> float:
        """Blob area / box area."""
        return self.area / float(max(1, self.box[2] * self.box[3]))


def balance(bgr: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """``bgr`` times per-channel ``gains`` (uint8, saturating)."""
    return cv2.transform(bgr, np.diag(gains.astype(np.float32)))


def working_image(bgr: np.ndarray, cfg: GeneralConfig) -> Working:
    """Shrink ``bgr`` to ``cfg.work_width`` (area), white-balance it by the grey world (the
    mean of each channel made equal, gains clipped to ``cfg.max_gain``), convert to HSV."""
    h, w = bgr.shape[:2]
    scale = max(1.0, w / float(cfg.work_width))
    small = bgr if scale == 1.0 else cv2.resize(
        bgr, (int(round(w / scale)), max(1, int(round(h / scale)))),
        interpolation=cv2.INTER_AREA)
    mean = np.asarray(cv2.mean(small)[:3], np.float64)
    gains = np.clip(mean.mean() / np.maximum(mean, 1.0), 1.0 / cfg.max_gain, cfg.max_gain)
    wb = balance(small, gains)
    return Working(wb, cv2.cvtColor(wb, cv2.COLOR_BGR2HSV), scale, gains)


def red_mask(hsv: np.ndarray, cfg: GeneralConfig, min_saturation: int) -> np.ndarray:
    """Pixels in either red hue range (uint8 0/255)."""
    lo = cv2.inRange(hsv, (0, min_saturation, cfg.min_value), (cfg.red_hue_lo, 255, 255))
    hi = cv2.inRange(hsv, (cfg.red_hue_hi, min_saturation, cfg.min_value), (180, 255, 255))
    return cv2.bitwise_or(lo, hi)


def yellow_mask(hsv: np.ndarray, cfg: GeneralConfig, min_saturation: int) -> np.ndarray:
    """Pixels in the yellow hue range (uint8 0/255)."""
    return cv2.inRange(hsv, (cfg.yellow_hue[0], min_saturation, cfg.min_value),
                       (cfg.yellow_hue[1], 255, 255))


def white_mask(hsv: np.ndarray, cfg: GeneralConfig, value: Optional[np.ndarray] = None
               ) -> np.ndarray:
    """Bright unsaturated pixels: value at least ``white_value`` of the frame's 99th
    percentile (and 70), saturation at most ``white_max_saturation``.  ``value``: the value
    channel of ``hsv`` as its own array, when it is at hand (the histogram is faster on it)."""
    v = hsv[..., 2] if value is None else value
    hist = cv2.calcHist([v], [0], None, [256], [0, 256]).ravel()
    p99 = int(np.searchsorted(np.cumsum(hist), 0.99 * v.size))
    v_min = max(70, int(cfg.white_value * p99))
    return cv2.inRange(hsv, (0, 0, v_min), (180, cfg.white_max_saturation, 255))


def green_mask(hsv: np.ndarray, cfg: GeneralConfig, strict: bool = False) -> np.ndarray:
    """Pixels of green sheeting (uint8 0/255); ``strict``: only the saturated, blue-green
    sheeting, not foliage."""
    if strict:
        return cv2.inRange(hsv, (cfg.green_strict_hue, cfg.strict_saturation,
                                 cfg.green_min_value), (cfg.green_hue[1], 255, 255))
    return cv2.inRange(hsv, (cfg.green_hue[0], cfg.green_min_saturation, cfg.green_min_value),
                       (cfg.green_hue[1], 255, 255))


def clean(mask: np.ndarray, cfg: GeneralConfig) -> np.ndarray:
    """Erosion, then dilation (Cahail et al., Figs. 3.5-3.6)."""
    if not cv2.countNonZero(mask):
        return mask
    k = np.ones((cfg.erode_px, cfg.erode_px), np.uint8)
    return cv2.dilate(cv2.erode(mask, k), k, iterations=cfg.dilate_iter)


def blobs(mask: np.ndarray, min_side: float, max_area: float = np.inf) -> list[Blob]:
    """The connected components of ``mask`` as blobs, their holes filled (a legend does not
    count against a sign's area), those whose box's shorter side is at least ``min_side`` and
    whose area is at most ``max_area`` (working px).  A component inside another's hole (a
    sign's white panel inside its black border inside white sky) is a blob of its own."""
    if not cv2.countNonZero(mask):
        return []
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c, hr in zip(contours, hier[0]):
        if hr[3] >= 0:              # a hole's boundary
            continue
        x, y, w, h = cv2.boundingRect(c)
        if min(w, h) < min_side or w * h > max_area:
            continue
        # the polygon's area plus half its outline: the pixel count of the filled contour
        area = cv2.contourArea(c) + 0.5 * cv2.arcLength(c, True) + 1.0
        out.append(Blob((x, y, w, h), float(min(area, w * h)), (c,)))
    return out


def _stacked_pairs(boxes: np.ndarray) -> np.ndarray:
    """(i, j) index pairs of boxes (N, 4) that are pieces of one panel cut by a legend line
    across it (MILE above a mile marker's number, STOP across a far stop sign): one above
    the other (not nested), overlapping in x by 70 % of the wider, the gap at most half the
    smaller one's height plus 2 px."""
    x, y, w, h = (boxes[:, k][:, None] for k in range(4))
    xt, yt, wt, ht = (boxes[:, k][None, :] for k in range(4))
    ox = np.minimum(x + w, xt + wt) - np.maximum(x, xt)
    gap = np.maximum(y, yt) - np.minimum(y + h, yt + ht)
    return np.argwhere(np.triu(stacked_test(ox, gap, w, wt, h, ht), 1))


def stacked_test(ox, gap, w1, w2, h1, h2):
    """Two boxes of widths ``w1``, ``w2`` and heights ``h1``, ``h2`` whose x ranges overlap
    by ``ox`` and which are ``gap`` apart in y are pieces of one panel (:func:`_stacked_pairs`);
    with x and y swapped, pieces side by side."""
    return (ox >= 0.7 * np.maximum(w1, w2)) & (gap >= -2) & \
        (gap <= 0.5 * np.minimum(h1, h2) + 2)


def merge_stacked(blobs: list[Blob]) -> list[Blob]:
    """Join stacked pieces of one sign (:func:`_stacked_pairs`, transitively) into one blob,
    the gap between them filled."""
    if len(blobs) < 2:
        return blobs
    parent = list(range(len(blobs)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i, j in _stacked_pairs(np.array([b.box for b in blobs], np.int64)):
        parent[root(int(i))] = root(int(j))
    groups: dict[int, list[Blob]] = {}
    for i, b in enumerate(blobs):
        groups.setdefault(root(i), []).append(b)
    return [g[0] if len(g) == 1 else _join(g) for g in groups.values()]


def _join(parts: list[Blob]) -> Blob:
    """One blob of ``parts``: their contours, and the gap between each piece and the next
    one down filled over the columns they share."""
    x = min(b.box[0] for b in parts)
    y = min(b.box[1] for b in parts)
    w = max(b.box[0] + b.box[2] for b in parts) - x
    h = max(b.box[1] + b.box[3] for b in parts) - y
    bridges = []
    parts = sorted(parts, key=lambda b: b.box[1])
    for a, b in zip(parts, parts[1:]):
        c0 = max(a.box[0], b.box[0])
        c1 = min(a.box[0] + a.box[2], b.box[0] + b.box[2])
        r0, r1 = a.box[1] + a.box[3] - 1, b.box[1] + 1
        if c1 > c0 and r1 > r0:
            bridges.append((c0, r0, c1 - c0, r1 - r0))
    contours = tuple(c for b in parts for c in b.contours)
    blob = Blob((x, y, w, h), 0.0, contours, tuple(bridges))
    return Blob((x, y, w, h), float(np.count_nonzero(blob.mask)), contours, tuple(bridges))


def iou(a, b) -> float:
    """IoU of two (x, y, w, h) boxes."""
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / float(union) if union > 0 else 0.0


def median_hue(hsv: np.ndarray, blob: Blob, min_saturation: int, min_value: int) -> float:
    """Median hue of the blob's pixels with at least ``min_saturation`` and ``min_value``
    (hue wrapped to -90..90, so red sits around 0), or nan when there are none."""
    x, y, w, h = blob.box
    patch = hsv[y:y + h, x:x + w]
    sel = (blob.mask > 0) & (patch[..., 1] >= min_saturation) & (patch[..., 2] >= min_value)
    if not sel.any():
        return float('nan')
    hue = patch[..., 0][sel].astype(np.int16)
    return float(np.median(np.where(hue >= 90, hue - 180, hue)))
