"""The tracked target's appearance and the gates that use it.

The target model (:class:`TargetModel`: the shape mask, the kernel histogram, the relation of
the coloured anchor to the whole box) built from a detection, and the tests of whether a
target looks like a sign on its own: more saturated and colourful than its surroundings
(:func:`saturation_contrast`, :func:`chroma_contrast`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.track.config import TrackerConfig
from workzone_ros.core.track.meanshift import (
    SearchWindow,
    _histogram,
    _kernel,
    _luts,
    _stride,
    bhattacharyya,
)

__all__ = [
    'saturation_contrast', 'chroma_contrast', 'shape_mask', 'TargetModel', 'build_target',
]


_MASK_GRID = 32          # resolution of the shape mask over normalized coordinates [-1, 1]^2


def saturation_contrast(win: SearchWindow, zx: float, zy: float, ax: float,
                        ay: float, reference: float = 90.0) -> float:
    """Sign-likeness of the box centred at z, half-size a: the upper decile of its
    saturation minus the ``reference`` percentile of that of the rest of the window, in
    [-1, 1].

    Work-zone sign faces are fluorescent orange: more saturated than what surrounds them,
    whatever the light (upper decile, so a legend or a white part does not matter).  Patches
    of a tinted sky, road or vegetation (dusk) are as saturated as their surroundings; the
    inside of a large orange vehicle is as saturated as the rest of the vehicle.  The
    tracker compares with the surroundings' median (``TrackerConfig.saturation_reference``):
    their upper decile is set by the few most saturated things around a sign (its stand's
    orange flags, a neighbouring sign, sunlit or shaded vegetation, which reaches the
    255 that a sunlit face is clipped at), so it fell to 0-0.1 for most sunlit signs
    (sunny tuning paper_c 2100: 3 of 31 detector misses covered).

    Returns:
        The contrast, or 0 when the box or the rest of the window holds fewer than four
        samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return 0.0
    sat = win.hsv[..., 1]
    inside = np.zeros(sat.shape, bool)
    inside[ky0:ky1, kx0:kx1] = True
    out = sat[~inside]
    if out.size < 4:
        return 0.0
    s_in = np.percentile(sat[ky0:ky1, kx0:kx1], 90)
    return float(s_in - np.percentile(out, reference)) / 255.0


def chroma_contrast(win: SearchWindow, zx: float, zy: float, ax: float, ay: float,
                    reference: float = 90.0) -> float:
    """Sign-likeness of the box centred at z, half-size a: the upper decile of its chroma
    over the ``reference`` percentile of that of the rest of the window (a ratio; the
    tracker uses the median, ``TrackerConfig.chroma_reference``).

    Chroma is ``S * V / 255`` (HSV; the spread ``max - min`` of the RGB channels): how
    colourful a pixel is.  HSV saturation alone is ``(max - min) / max``, which is high on
    dark pixels whatever their colour (shaded vegetation, dark trees in sun reach the
    saturation of a fluorescent face), while their chroma stays low.  A ratio (not a
    difference) does not depend on the light level: rain and dusk lower the chroma of
    everything.  With :func:`saturation_contrast` against the surroundings' median, it
    keeps dim targets in bright, moderately saturated surroundings (patches of a tinted
    dusk sky, dark-orange clutter) from running on their own.

    Returns:
        The ratio, or 0 when the box or the rest of the window holds fewer than four samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return 0.0
    hsv = win.hsv
    chroma = hsv[..., 1].astype(np.float32) * hsv[..., 2].astype(np.float32) / 255.0
    inside = np.zeros(chroma.shape, bool)
    inside[ky0:ky1, kx0:kx1] = True
    out = chroma[~inside]
    if out.size < 4:
        return 0.0
    c_in = float(np.percentile(chroma[ky0:ky1, kx0:kx1], 90))
    return c_in / max(float(np.percentile(out, reference)), 1.0)


def shape_mask(hsv: np.ndarray, min_saturation: int = 70, min_value: int = 50,
               hue_tolerance: int = 12, min_fraction: float = 0.08) -> Optional[np.ndarray]:
    """Shape mask of a detection (Lee et al., Fig. 2): convex hull of its dominant-hue pixels.

    The dominant hue is the mode of the chromatic pixels near the box centre; the mask is the
    filled convex hull of the pixels within ``hue_tolerance`` of it (so a black legend and the
    inside of a border belong to the shape).

    Args:
        hsv: (h, w, 3) uint8 HSV patch of the detection box.
        min_saturation: saturation below which a pixel has no usable hue.
        min_value: value below which a pixel has no usable hue.
        hue_tolerance: half-width of the accepted hue range (OpenCV hue units, 0..179).
        min_fraction: fewer dominant-hue pixels than this fraction of the box: no mask.

    Returns:
        uint8 mask (h, w) with 1 inside the shape, or None for an achromatic/featureless box.
    """
    h, w = hsv.shape[:2]
    if h < 2 or w < 2:
        return None
    hue = hsv[..., 0].astype(np.int16)
    chroma = (hsv[..., 1] >= min_saturation) & (hsv[..., 2] >= min_value)
    yy, xx = np.ogrid[:h, :w]
    inner = (((xx - (w - 1) / 2) / (w / 2)) ** 2 + ((yy - (h - 1) / 2) / (h / 2)) ** 2) < 1.0
    sel = chroma & inner
    if sel.sum() < max(3, min_fraction * h * w):
        return None
    mode = int(np.argmax(np.bincount(hue[sel] // 6, minlength=30))) * 6 + 3
    diff = np.abs(hue - mode)
    diff = np.minimum(diff, 180 - diff)
    on = chroma & (diff <= hue_tolerance)
    if on.sum() < max(3, min_fraction * h * w):
        return None
    pts = cv2.findNonZero(on.astype(np.uint8))
    hull = cv2.convexHull(pts)
    mask = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(mask, hull, 1)
    return mask


@dataclass
class TargetModel:
    """What a track follows: the anchor box, its shape mask and its histogram (eq. 1).

    Attributes:
        q: target histogram t_b (nh * ns, normalized).
        qw: the histogram the mean-shift weights use: ``q`` with the bins common in the
            surroundings scaled down when ``background_weighting`` is on, else ``q``.
        mask: (32, 32) float32 shape mask over normalized anchor coordinates.
        relation: the output box relative to the anchor: ``(dx, dy, rw, rh)`` with
            ``box = (ax0 + dx * aw, ay0 + dy * ah, rw * aw, rh * ah)``.
        anchor: anchor box ``(x, y, w, h)`` in the frame it was built from.
        background_similarity: Bhattacharyya coefficient of the model and its surroundings.
        colored: a shape mask was found (False: featureless or achromatic box).
        hue_hist: hue histogram for the CamShift peer (float32, 180 bins, max 255).
        dark_fraction: share of the shape that is much darker than its colour (legend,
            border): signs have one, drums, cones and orange vehicles mostly do not.
        white_fraction: share of the shape that is white (a drum's or cone's bands).
        white_below: share of that white below the lowest row where the colour dominates
            (a regulatory sign's white bottom: near 1; a drum's or cone's bands: low).
        saturation_contrast: :func:`saturation_contrast` of the anchor in its frame
            (sign-likeness: sign faces are more saturated than their surroundings).
        chroma_contrast: :func:`chroma_contrast` of the anchor in its frame (sign faces are
            more colourful than their surroundings).
    """

    q: np.ndarray
    qw: np.ndarray
    mask: np.ndarray
    relation: tuple[float, float, float, float]
    anchor: tuple[float, float, float, float]
    background_similarity: float
    colored: bool
    hue_hist: np.ndarray
    dark_fraction: float = 0.0
    white_fraction: float = 0.0
    white_below: float = 0.0
    saturation_contrast: float = 0.0
    chroma_contrast: float = 0.0

    def box_from_anchor(self, anchor: Sequence[float]) -> tuple[float, float, float, float]:
        """The output box for an anchor ``(x, y, w, h)``."""
        dx, dy, rw, rh = self.relation
        return (anchor[0] + dx * anchor[2], anchor[1] + dy * anchor[3], rw * anchor[2],
                rh * anchor[3])


def build_target(frame: np.ndarray, box: Sequence[float], cfg: TrackerConfig,
                 luts: Optional[np.ndarray] = None) -> Optional[TargetModel]:
    """Target model of a detection box (Lee et al., eq. 1) with its anchor and shape mask.

    Args:
        frame: BGR uint8 image.
        box: detection ``(x, y, w, h)`` in pixels.
        cfg: tracker configuration.
        luts: bin look-up tables (computed from ``cfg`` when None).

    Returns:
        The model, or None when the box is (almost) outside the image.
    """
    luts = _luts(cfg.hue_bins, cfg.sat_bins) if luts is None else luts
    H, W = frame.shape[:2]
    x, y, w, h = (float(v) for v in box)
    xi0, yi0 = max(0, int(math.floor(x))), max(0, int(math.floor(y)))
    xi1, yi1 = min(W, int(math.ceil(x + w))), min(H, int(math.ceil(y + h)))
    if xi1 - xi0 < 2 or yi1 - yi0 < 2:
        return None
    s = _stride(w / 2, h / 2, 4 * cfg.max_samples)
    patch = cv2.cvtColor(np.ascontiguousarray(frame[yi0:yi1:s, xi0:xi1:s]), cv2.COLOR_BGR2HSV)
    m = shape_mask(patch)
    colored = m is not None
    dark = white = white_below = 0.0
    if colored:
        dark, white, white_below = _content(patch, m)
    anchor = (x, y, w, h)
    if colored and cfg.anchor_on_color:
        ys_, xs_ = np.nonzero(m)
        ax0, ax1 = xi0 + s * xs_.min(), xi0 + s * (xs_.max() + 1)
        ay0, ay1 = yi0 + s * ys_.min(), yi0 + s * (ys_.max() + 1)
        anchor = (float(ax0), float(ay0), float(ax1 - ax0), float(ay1 - ay0))
        sub = m[ys_.min():ys_.max() + 1, xs_.min():xs_.max() + 1]
    elif colored:
        ox0, oy0 = int(round((x - xi0) / s)), int(round((y - yi0) / s))
        sub = m[max(0, oy0):, max(0, ox0):]
    else:
        sub = np.ones((2, 2), np.uint8)
    mask = cv2.resize(sub.astype(np.float32), (_MASK_GRID, _MASK_GRID),
                      interpolation=cv2.INTER_AREA)
    mask = (mask >= 0.5).astype(np.float32)
    if mask.sum() < 4:
        mask[:] = 1.0
    aw, ah = max(anchor[2], 1.0), max(anchor[3], 1.0)
    relation = ((x - anchor[0]) / aw, (y - anchor[1]) / ah, w / aw, h / ah)
    ax, ay = aw / 2, ah / 2
    zx, zy = anchor[0] + ax, anchor[1] + ay
    stride = _stride(ax, ay, cfg.max_samples)
    win = SearchWindow(frame, zx - 2 * ax, zy - 2 * ay, zx + 2 * ax + 1, zy + 2 * ay + 1,
                       stride, luts)
    nb = cfg.hue_bins * cfg.sat_bins
    kern = _kernel(win, mask, zx, zy, ax, ay)
    q = None if kern is None else _histogram(kern[0], kern[1], nb)
    if q is None:
        return None
    # Surroundings: the window outside the anchor box (Lee et al. has no such check).
    inside = np.zeros(win.bins.shape, bool)
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    inside[ky0:ky1, kx0:kx1] = True
    ring = win.bins[~inside]
    sat_contrast = saturation_contrast(win, zx, zy, ax, ay, cfg.saturation_reference)
    chroma = chroma_contrast(win, zx, zy, ax, ay, cfg.chroma_reference)
    bg_sim = 1.0
    qw = q
    if ring.size >= 8:
        bg = np.bincount(ring, minlength=nb).astype(np.float64)
        bg /= bg.sum()
        bg_sim = bhattacharyya(q, bg)
        if cfg.background_weighting:
            # Corrected background-weighted histogram: v_u = min(o* / o_u, 1).
            nz = bg[bg > 0]
            v = np.ones(nb)
            v[bg > 0] = np.minimum(nz.min() / nz, 1.0)
            qw = q * v
            qw = qw / qw.sum() if qw.sum() > 0 else q
    # CamShift peer model: hue histogram of the chromatic anchor samples.
    hsv_in = win.hsv[ky0:ky1, kx0:kx1]
    valid = ((hsv_in[..., 1] >= 60) & (hsv_in[..., 2] >= 32)).astype(np.uint8)
    hue_hist = cv2.calcHist([np.ascontiguousarray(hsv_in)], [0], valid, [180], [0, 180])
    cv2.normalize(hue_hist, hue_hist, 0, 255, cv2.NORM_MINMAX)
    return TargetModel(q=q, qw=qw, mask=mask, relation=relation, anchor=anchor,
                       background_similarity=bg_sim, colored=colored, hue_hist=hue_hist,
                       dark_fraction=dark, white_fraction=white, white_below=white_below,
                       saturation_contrast=sat_contrast, chroma_contrast=chroma)


def _content(hsv: np.ndarray, mask: np.ndarray) -> tuple[float, float, float]:
    """Dark and white shares of the shape, relative to the brightness of its colour, and the
    share of its white below the lowest row where the colour dominates (``white_below``:
    about 1 for a regulatory sign's white bottom, low for a drum's or cone's bands, which
    have colour below them)."""
    inside = mask > 0
    n = int(inside.sum())
    if n == 0:
        return 0.0, 0.0, 0.0
    s, v = hsv[..., 1].astype(np.int16), hsv[..., 2].astype(np.int16)
    colour = (s >= 100) & inside
    ref = float(np.median(v[colour])) if colour.any() else float(np.median(v[inside]))
    dark = float(np.count_nonzero((v < 0.5 * ref) & inside)) / n
    white_px = (s < 60) & (v >= 0.75 * ref) & inside
    n_white = int(np.count_nonzero(white_px))
    below = 0.0
    if n_white:
        rows_c = colour.sum(axis=1)
        rows_w = white_px.sum(axis=1)
        dom = np.nonzero(rows_c > rows_w)[0]
        last = int(dom.max()) if dom.size else -1
        below = float(rows_w[last + 1:].sum()) / n_white
    return dark, n_white / n, below
