"""Read the number on a work-zone speed limit sign (R2-1 with a WORK ZONE plaque) from a crop.

The classifier labels a track ``work_zone_speed_limit``; this module reads the limit itself
from the classifier's crop (the sign grown by a margin, perhaps shifted by the detector's
localisation or cut by the image border).  No ROS import (DESIGN.md, principle 1).

1. The crop is scaled to :data:`WORK_H` rows.
2. The sign is located: the WORK ZONE plaque (a wide blob of the crop's most saturated
   orange) gives the scale ``ph`` (its height) and the top of the white panel under it; the
   panel is the white blob there, closed over its legend, taken as a rectangle.  Without a
   plaque the panel is the largest white blob of a panel's shape.
3. The number is segmented: ink is measured between the panel's white and its darkest legend,
   the border line is cleared, the band below LIMIT is cut at its emptiest row, and the
   number's digits are its tallest dark blobs (a blob too wide for one digit is split).
4. Each digit is classified by linear discriminant analysis on pixels and gradient
   histograms, trained at first use on numbers we draw with OpenCV's Hershey fonts, warped,
   blurred (focus and motion), noised and JPEG-compressed as a far sign is
   (:func:`digit_model`); its confidence is its posterior, lowered as its distance to the
   digit's class grows (a cut, merged or smeared glyph is far from every digit).
5. The read is refused, with the reason, when the evidence is weak: digits cut by the crop
   or too near the panel's edge, of the wrong size, shape or pairing, a number off the
   panel's centre, not a multiple of 5 in 5..85, a confidence under ``min_confidence``, or
   another valid speed's whole-number templates fitting the number clearly better
   (:func:`number_templates`).

A wrong limit on the planner's input is worse than none: every doubt returns None.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.kernels import components_with_stats

__all__ = [
    'SpeedReading', 'read_speed_limit', 'warm_up', 'classify_glyphs', 'digit_model',
    'DigitModel', 'features', 'number_templates', 'VALID_SPEEDS', 'MIN_CONFIDENCE', 'WORK_H',
    'GLYPH_W', 'GLYPH_H', 'NUMBER_H', 'NUMBER_W', 'FONTS',
]

#: Speed limits a sign can carry (mph): multiples of 5 in 5..85.
VALID_SPEEDS: tuple[int, ...] = tuple(range(5, 90, 5))
#: A read below this confidence is returned as None ('low confidence').
MIN_CONFIDENCE = 0.8
#: Working height (px) the crop is scaled to before anything is measured.
WORK_H = 128
#: Size (px) of a normalised digit glyph.
GLYPH_W, GLYPH_H = 16, 24
#: Template fonts: sans-serif Hershey faces like the highway Series D/E numerals.
FONTS: tuple[int, ...] = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX,
                          cv2.FONT_HERSHEY_TRIPLEX, cv2.FONT_HERSHEY_COMPLEX)
#: Stroke weights of the training digits (thickness / glyph height), a range.
_WEIGHTS = (0.09, 0.22)
#: Heights (px) the training digits are drawn at before scaling up (far to near signs).
_SMALL_H = (5.0, 40.0)
#: Digit height in the working image (px): the crop is ~1.2 x the sign, the number ~0.23 of
#: the sign, the crop WORK_H high.
_WORK_DIGIT_H = 24
#: Shrinkage of the classifier's pooled covariance towards a multiple of the identity.
_SHRINK = 0.2
#: A digit's confidence falls from its posterior at _D2_TYPICAL to 0 at _D2_FAR squared
#: Mahalanobis distances to its class (in units of the training digits' median).
_D2_TYPICAL, _D2_FAR = 2.0, 5.0
#: Veto: a read is refused when another valid speed's whole-number templates correlate
#: better with the number than the read's own by more than this.
_HOLISTIC_MARGIN = -0.05

# Sign layout (R2-1 + plaque, in plaque heights ph below the plaque's bottom edge): SPEED
# spans 0.24-0.64, LIMIT 0.72-1.12, the number 1.7-2.6 (0.9 ph high, 0.13-0.86 of the width);
# the panel ends at 3.0.
#: Plaque height / width (0.525 m / 1.2 m).
_PLAQUE_ASPECT = 0.525 / 1.2


@dataclass(frozen=True)
class SpeedReading:
    """The number read from a speed limit sign.

    Attributes:
        value: mph, a multiple of 5 in 5..85, or None when it cannot be read.
        confidence: 0..1 (of the read; for None, of the best rejected read).
        reason: why the value is None ('' when read).
    """

    value: Optional[int]
    confidence: float
    reason: str = ''


def _unread(reason: str, confidence: float = 0.0) -> SpeedReading:
    return SpeedReading(None, float(round(confidence, 3)), reason)


# ------------------------------------------------------------------ input and colour masks
def _as_bgr(crop: np.ndarray) -> np.ndarray:
    """``crop`` as a uint8 BGR image (grey and BGRA accepted).

    Raises:
        ValueError: not a 2-D or 3-D uint8 image with 1, 3 or 4 channels.
    """
    a = np.asarray(crop)
    if a.dtype != np.uint8 or a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in
                                                        (1, 3, 4)):
        raise ValueError(f'crop must be a uint8 grey/BGR/BGRA image, got {a.dtype} {a.shape}')
    if a.ndim == 2 or a.shape[2] == 1:
        return cv2.cvtColor(a.reshape(a.shape[:2]), cv2.COLOR_GRAY2BGR)
    if a.shape[2] == 4:
        return cv2.cvtColor(a, cv2.COLOR_BGRA2BGR)
    return a


def _working_image(bgr: np.ndarray) -> np.ndarray:
    """The crop scaled to :data:`WORK_H` rows (cubic up, area down)."""
    h, w = bgr.shape[:2]
    s = WORK_H / h
    size = (max(1, int(round(w * s))), WORK_H)
    return cv2.resize(bgr, size, interpolation=cv2.INTER_CUBIC if s > 1 else cv2.INTER_AREA)


def _masks(bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(grey, white mask, orange mask) of a BGR image.

    White: low chroma (max - min channel under 0.3 of the max, plus a little) and brighter
    than the image's Otsu level.  Orange: hue 0-25 (OpenCV), red well above blue, not dark,
    and at least 0.55 of the crop's most saturated such colour (faded sheeting is paler;
    a pinkish-white panel under a red sky is paler still).
    """
    f = bgr.astype(np.int16)
    mx = f.max(axis=2)
    chroma = mx - f.min(axis=2)
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    otsu, _ = cv2.threshold(mx.astype(np.uint8), 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    white = (chroma * 10 <= mx * 3 + 80) & (mx >= max(otsu, 50))
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
    hue, sat, val = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    warm = ((hue <= 25) | (hue >= 175)) & (val >= 50) & (f[..., 2] > f[..., 0] + 30)
    # fluorescent sheeting is the most saturated thing around it: half of its saturation
    top = float(np.percentile(sat[warm], 98)) if warm.sum() >= 16 else 255.0
    orange = warm & (sat >= max(70.0, 0.55 * top))
    return grey, white.astype(np.uint8), orange.astype(np.uint8)


# ------------------------------------------------------------------ locating the sign
@dataclass(frozen=True)
class _Sign:
    """The sign in the working image.

    Attributes:
        pb: row of the plaque's bottom edge (the top of the white panel).
        ph: the plaque's height (px), the unit of the layout: the panel is 3 ph high, the
            number 1.7-2.6 ph below the plaque.
        region: uint8 mask of the white panel (a rectangle).
        cut_side: the panel reaches the crop's left or right edge.
        px0, px1: the panel's columns.
    """

    pb: float
    ph: float
    region: np.ndarray
    cut_side: bool
    px0: int
    px1: int


Blob = tuple[int, int, int, int, int]


def _blobs(mask: np.ndarray) -> tuple[np.ndarray, list[Blob]]:
    """(labels, [(x, y, w, h, area), ...] with the label i + 1) of a mask's 8-connected blobs."""
    n, labels, stats = components_with_stats(mask)
    return labels, [tuple(st) for st in stats[1:n].tolist()]


def _plaques(orange: np.ndarray) -> list[Blob]:
    """Candidates for the WORK ZONE plaque, largest first: orange blobs wider than tall,
    not slivers, in the upper part of the crop."""
    H, W = orange.shape
    # wide kernel: the legend and border line cut the plaque's orange into pieces
    closed = cv2.morphologyEx(orange, cv2.MORPH_CLOSE, np.ones((5, 9), np.uint8))
    _, blobs = _blobs(closed)
    ok = [b for b in blobs if b[2] >= 1.4 * b[3] and b[2] >= 0.25 * W and b[3] >= 4 and
          b[4] >= 0.5 * b[2] * b[3] and b[1] + b[3] < 0.75 * H]
    return sorted(ok, key=lambda b: -b[4])[:3]


def _odd(x: float) -> int:
    return max(3, int(round(x)) | 1)


def _make_sign(white: np.ndarray, pb: float, ph: float,
               rect: tuple[float, float, float, float]) -> Optional[_Sign]:
    """The sign whose panel lies in ``rect`` (x0, y0, x1, y1): the panel is the largest
    white blob there, closed over its legend (a kernel of 0.6 ph); None when it is less
    than half of the rectangle.  The panel region is a rectangle: the blob's rows (to at
    most 3.3 ph), and its columns beside the legend; ``ph`` is refined by the panel's size."""
    x0, y0, x1, y1 = (int(round(v)) for v in rect)
    H, W = white.shape
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(W, x1), min(H, y1)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None
    win = np.zeros_like(white)
    win[y0:y1, x0:x1] = white[y0:y1, x0:x1]
    n = _odd(0.6 * ph)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (n, n))
    # zero padding: a closing must not glue the panel to the image border
    padded = cv2.copyMakeBorder(win, n, n, n, n, cv2.BORDER_CONSTANT, value=0)
    labels, blobs = _blobs(cv2.morphologyEx(padded, cv2.MORPH_CLOSE, k)[n:-n, n:-n])
    if not blobs:
        return None
    i = max(range(len(blobs)), key=lambda j: blobs[j][4])
    if blobs[i][4] < 0.5 * (x1 - x0) * (y1 - y0):
        return None
    blob = labels == i + 1
    rows = np.nonzero(blob.any(axis=1))[0]
    # The panel is a rectangle: its sides where the blob's are beside the legend (0.2-1.3 ph
    # below the plaque), not beside the number, where a blurred rim may not look white.
    legend = rows[(rows >= pb + 0.2 * ph) & (rows <= pb + 1.3 * ph)]
    if legend.size < 2:
        return None
    left = int(np.median(blob[legend].argmax(axis=1)))
    right = int(np.median(W - blob[legend, ::-1].argmax(axis=1)))
    if right - left < 0.5 * (x1 - x0):
        return None
    cut_side = left <= 1 or right >= W - 1
    # the scale once more from the panel: 2.29 ph wide (if whole), 3 ph high (if its bottom
    # is in the crop); the median of what is known
    est = [ph]
    if not cut_side:
        est.append((right - left) * _PLAQUE_ASPECT)
    if rows[-1] < H - 1 and pb >= 1:
        est.append((rows[-1] + 1 - pb) / 3.0)
    ph = float(np.median(est))
    region = np.zeros_like(white)
    region[rows[0]:min(rows[-1] + 1, int(pb + 3.3 * ph)), left:right] = 1
    return _Sign(pb, ph, region, cut_side, left, right)


def _from_plaque(white: np.ndarray, plaque: Blob) -> Optional[_Sign]:
    """The sign below a plaque: the panel is the white blob under it, as wide as the plaque
    and about 3 plaque heights high."""
    H, W = white.shape
    x, y, w, h, _ = plaque
    # The plaque is 0.25 of the sign's height and as wide as the sign (1.2 m x 0.525 m).
    # Its measured height is too large by the blur, its width too small on a sign seen from
    # the side: the mean of both; only the width where the crop cuts its top, only the
    # height where the crop cuts a side, the larger where it cuts both (the panel refines it).
    cut_top, cut = y <= 1, x <= 1 or x + w >= W - 1
    if cut_top and cut:
        ph = max(h, w * _PLAQUE_ASPECT)
    else:
        ph = w * _PLAQUE_ASPECT if cut_top else h if cut else 0.5 * (h + w * _PLAQUE_ASPECT)
    pb = y + h
    m = 0.05 * w
    return _make_sign(white, pb, ph, (x - m, pb, x + w + m, pb + 3.6 * ph))


def _from_panel(white: np.ndarray) -> Optional[_Sign]:
    """The sign from its white panel alone (no plaque in the crop): the largest white blob
    of a panel's shape; the scale from its width, or its height if the crop cuts a side."""
    H, W = white.shape
    labels, blobs = _blobs(cv2.morphologyEx(white, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)))
    ok = [k for k, (x, y, w, h, a) in enumerate(blobs) if h >= 0.3 * H and w >= 0.15 * W
          and 0.3 <= w / h <= 1.6 and a >= 0.35 * w * h]
    if not ok:
        return None
    i = max(ok, key=lambda k: blobs[k][4])
    x, y, w, h, _ = blobs[i]
    cut = x <= 1 or x + w >= W - 1
    cut_top, cut_bottom = y <= 1, y + h >= H - 1
    # the panel is 3 ph high and 2.29 ph wide (less on a sign seen from the side)
    if not (cut_top or cut_bottom) and (cut or 0.9 <= h / 3.0 / (w * _PLAQUE_ASPECT) <= 1.5):
        ph = h / 3.0
    elif not cut:
        ph = w * _PLAQUE_ASPECT
    else:
        return None
    pb = y + h - 3.0 * ph if cut_top else y
    return _make_sign(white, pb, ph, (x, pb, x + w, pb + 3.0 * ph))


def _locate(bgr: np.ndarray) -> Optional[_Sign]:
    """The sign in the working image: from the first plaque candidate with a white panel
    under it, else from the white panel alone."""
    _, white, orange = _masks(bgr)
    for plaque in _plaques(orange):
        sign = _from_plaque(white, plaque)
        if sign is not None:
            return sign
    return _from_panel(white)


# ------------------------------------------------------------------ digit segmentation
@dataclass(frozen=True)
class _Digits:
    """Segmented digits: boxes (x, y, w, h) in the working image, left to right, and the
    ink image (0 white .. 1 ink, 0 outside the panel)."""

    boxes: tuple[tuple[int, int, int, int], ...]
    ink: np.ndarray


def _ink(grey: np.ndarray, region: np.ndarray) -> Optional[np.ndarray]:
    """Ink in [0, 1] (1 = as dark as the legend) inside ``region`` (0 outside), or None when
    the region has no contrast.  The panel's white is its 75th percentile, the ink its 3rd."""
    vals = grey[region > 0].astype(np.float32)
    if vals.size < 16:
        return None
    white, black = np.percentile(vals, 75), np.percentile(vals, 3)
    if white - black < 25:
        return None
    ink = np.clip((white - grey.astype(np.float32)) / (white - black), 0.0, 1.0)
    ink[region == 0] = 0.0
    return ink


def _inner(sign: _Sign) -> np.ndarray:
    """The panel region less a thin rim; a side the crop cuts keeps its edge (erosion does
    not eat in from the image border)."""
    k = _odd(0.12 * sign.ph)
    return cv2.erode(sign.region, np.ones((k, k), np.uint8))


def _drop_border_line(ink: np.ndarray, region: np.ndarray, ph: float) -> None:
    """Clear, in place, the panel's black border line: the columns within 0.25 ph of the
    region's sides that are ink along half their length (the number covers 0.3 of the
    panel's height), the rows within 0.3 ph of its bottom that are ink along 0.85 of theirs
    (a row through the bottom of a blurred number is ink along 0.7 of it)."""
    rows = np.nonzero(region.any(axis=1))[0]
    cols = np.nonzero(region.any(axis=0))[0]
    if rows.size < 2 or cols.size < 2:
        return
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    dark = ink[r0:r1, c0:c1] >= 0.5
    m, mb = max(1, int(round(0.25 * ph))), max(1, int(round(0.3 * ph)))
    col_frac, row_frac = dark.mean(axis=0), dark.mean(axis=1)
    for c in np.r_[0:m, max(0, dark.shape[1] - m):dark.shape[1]]:
        if col_frac[c] > 0.5:
            ink[r0:r1, c0 + c] = 0.0
    for r in range(max(0, dark.shape[0] - mb), dark.shape[0]):
        if row_frac[r] > 0.85:
            ink[r0 + r, c0:c1] = 0.0


def _band_rows(ink: np.ndarray, sign: _Sign) -> tuple[int, int]:
    """Rows of the number: from the emptiest row between LIMIT and the number (1.0-1.7 ph
    below the plaque) to the bottom of the panel."""
    H = ink.shape[0]
    lo = int(np.clip(sign.pb + 1.0 * sign.ph, 0, H - 1))
    hi = int(np.clip(sign.pb + 1.7 * sign.ph, lo + 1, H))
    top = lo + int(np.argmin(ink[lo:hi].sum(axis=1)))
    rows = np.nonzero(sign.region.any(axis=1))[0]
    return top, max(top + 1, int(rows[-1]) + 1 if rows.size else H)


def _split_wide(mask: np.ndarray, box) -> list[tuple[int, int, int, int]]:
    """Split a blob too wide for one digit at its thinnest column (middle 30-70 %)."""
    x, y, w, h = box
    cols = mask[y:y + h, x:x + w].sum(axis=0).astype(np.float32)
    lo, hi = int(0.3 * w), int(0.7 * w) + 1
    if hi - lo < 2:
        return [box]
    c = lo + int(np.argmin(cols[lo:hi]))
    return [(x, y, c, h), (x + c, y, w - c, h)]


def _segment(ink: np.ndarray, min_h: float) -> tuple[list[tuple[int, int, int, int]], str]:
    """Digit boxes (x, y, w, h) in an ink image, left to right, or ([], reason).

    The digits are the dark blobs at least ``min_h`` and 0.7 of the tallest high, on the
    tallest's rows; slivers (the border line) are dropped.  One blob too wide for a digit is
    split in two.
    """
    mask = (ink >= 0.5).astype(np.uint8)
    _, blobs = _blobs(mask)
    comps = [b[:4] for b in blobs if b[3] >= min_h and b[2] >= 0.2 * b[3]]
    if not comps:
        return [], 'no digits'
    ref = max(comps, key=lambda c: c[3])
    tallest = ref[3]
    digits = sorted(c for c in comps if c[3] >= 0.7 * tallest and
                    min(c[1] + c[3], ref[1] + ref[3]) - max(c[1], ref[1]) >= 0.6 * tallest)
    if len(digits) == 1 and digits[0][2] > 0.95 * digits[0][3]:
        digits = _split_wide(mask, digits[0])
    if len(digits) > 2:
        return [], 'ambiguous digits'
    return digits, ''


def _too_close(boxes, sign: _Sign) -> bool:
    """True when a digit box comes nearer than 0.06 ph to the panel's sides or bottom (the
    number keeps 0.15 ph of white from the border line): a digit the crop or an occluder
    cut may be part of another."""
    rows = np.nonzero(sign.region.any(axis=1))[0]
    gap = max(1.0, 0.06 * sign.ph)
    for x, y, w, h in boxes:
        if x - sign.px0 < gap or sign.px1 - (x + w) < gap or rows[-1] + 1 - (y + h) < gap:
            return True
    return False


def _touch_outside(band: np.ndarray, boxes, region: np.ndarray) -> bool:
    """True when the ink of a digit box reaches the outside of the panel region at its left
    or right (a digit the region cuts; at the bottom a small sign's number comes near the
    border line)."""
    outside = cv2.dilate((region == 0).astype(np.uint8), np.ones((1, 3), np.uint8))
    for x, y, w, h in boxes:
        if np.any((band[y:y + h, x:x + w] >= 0.5) & (outside[y:y + h, x:x + w] > 0)):
            return True
    return False


def _implausible(boxes, ph: float) -> str:
    """Why the digit boxes are not the number of a sign ``ph`` plaque heights tall ('' if
    they are): the number is 0.9 ph high, its digits alike and side by side."""
    hs = [b[3] for b in boxes]
    if not all(0.6 * ph <= h <= 1.4 * ph for h in hs):
        return 'digits of the wrong size'
    if not all(0.3 <= b[2] / b[3] <= 1.3 for b in boxes):
        return 'digits of the wrong shape'
    if len(boxes) == 2:
        (x0, y0, w0, h0), (x1, y1, w1, h1) = boxes
        if abs(h0 - h1) > 0.2 * max(h0, h1) or abs(y0 - y1) > 0.2 * max(h0, h1) or \
                x1 - (x0 + w0) > 0.5 * max(h0, h1):
            return 'digits not a pair'
    return ''


def _digits(grey: np.ndarray, sign: _Sign) -> tuple[Optional[_Digits], str]:
    """Segment the number of ``sign``; (None, reason) when there is none to read."""
    inner = _inner(sign)
    ink = _ink(grey, inner)
    if ink is None:
        return None, 'no contrast'
    _drop_border_line(ink, inner, sign.ph)
    top, bottom = _band_rows(ink, sign)
    band = np.zeros_like(ink)
    band[top:bottom] = ink[top:bottom]
    boxes, reason = _segment(band, 0.5 * sign.ph)
    if not boxes:
        return None, reason
    H, W = grey.shape
    r0 = min(b[1] for b in boxes)
    r1 = max(b[1] + b[3] for b in boxes)
    # ink on the crop's outer two columns beside the number, or a digit nearer than 0.15 ph
    # to the crop's left, right or bottom edge (a whole sign keeps 0.23 ph of white beside
    # its number and 0.4 ph below it): part of the number may be outside
    edge_ink = (band[r0:r1, :2] >= 0.5).any() or (band[r0:r1, W - 2:] >= 0.5).any()
    m = max(2.0, 0.15 * sign.ph)
    if edge_ink or any(b[0] < m or b[0] + b[2] > W - m or b[1] + b[3] > H - m
                       for b in boxes):
        return None, 'digits cut by the crop border'
    if any(b[1] <= top for b in boxes):
        return None, 'digits off the expected rows'
    if _touch_outside(band, boxes, sign.region) or _too_close(boxes, sign):
        return None, 'digits touch the panel edge'
    reason = _implausible(boxes, sign.ph)
    if reason:
        return None, reason
    return _Digits(tuple(boxes), band), ''


def _centred(digits: _Digits, sign: _Sign) -> bool:
    """True when the number is centred on the panel (a digit lost to a cut is not)."""
    x0 = digits.boxes[0][0]
    x1 = digits.boxes[-1][0] + digits.boxes[-1][2]
    return abs(0.5 * (x0 + x1) - 0.5 * (sign.px0 + sign.px1)) <= 0.12 * (sign.px1 - sign.px0)


# ------------------------------------------------------------------ glyphs and features
def _fit(patch: np.ndarray, height: int, width: int) -> np.ndarray:
    """``patch`` scaled to fit ``height`` x ``width`` (aspect kept) and centred in a float32
    canvas of that size."""
    h, w = patch.shape
    s = min(height / h, width / w)
    gw, gh = max(1, int(round(w * s))), max(1, int(round(h * s)))
    canvas = np.zeros((height, width), np.float32)
    ox, oy = (width - gw) // 2, (height - gh) // 2
    canvas[oy:oy + gh, ox:ox + gw] = cv2.resize(patch, (gw, gh), interpolation=cv2.INTER_AREA)
    return canvas


def _glyph(ink: np.ndarray, box) -> np.ndarray:
    """The ink inside ``box`` fitted to a :data:`GLYPH_H` x :data:`GLYPH_W` image."""
    x, y, w, h = box
    return _fit(ink[y:y + h, x:x + w], GLYPH_H, GLYPH_W)


def _unit(v: np.ndarray) -> np.ndarray:
    v = v - v.mean()
    return v / max(float(np.linalg.norm(v)), 1e-6)


#: Each glyph pixel's 4 x 4 cell, times the 8 gradient directions (bin offsets of the HOG).
_CELL = ((np.arange(GLYPH_H)[:, None] // 4) * (GLYPH_W // 4) +
         np.arange(GLYPH_W)[None, :] // 4) * 8


def features(glyph: np.ndarray) -> np.ndarray:
    """Feature vector of a glyph: its pixels and a histogram of oriented gradients (8
    directions in 4 x 4 cells), each part zero-mean and unit-norm."""
    gx = cv2.Sobel(glyph, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(glyph, cv2.CV_32F, 0, 1, ksize=3)
    mag, ang = cv2.cartToPolar(gx, gy)
    b = np.minimum((ang * (8 / (2 * np.pi))).astype(np.int32), 7)
    cells = np.bincount((_CELL + b).ravel(), mag.ravel(), _CELL.max() + 8)
    return np.concatenate([_unit(glyph.ravel()), _unit(cells)]).astype(np.float32)


# ------------------------------------------------------------------ training glyphs
def _motion_kernel(length: int, angle: float) -> np.ndarray:
    """A normalised line kernel (``length`` odd) at ``angle`` radians, point-symmetric."""
    k = np.zeros((length, length), np.float32)
    c = (length - 1) / 2
    dx, dy = c * np.cos(angle), c * np.sin(angle)
    cv2.line(k, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)),
             int(round(c + dy))), 1.0, 1)
    k = k + k[::-1, ::-1]
    return k / k.sum()


def _text_image(text: str, font: int, weight: float) -> np.ndarray:
    """``text`` black on white, digits 64 px high, stroke ``weight`` of that, 24 px margin."""
    (_, th), _ = cv2.getTextSize(text, font, 1.0, 1)
    scale = 64.0 / th
    thick = max(1, int(round(weight * 64)))
    (tw, th), base = cv2.getTextSize(text, font, scale, thick)
    pad = 24
    img = np.full((th + base + 2 * pad, tw + 2 * pad), 255, np.uint8)
    cv2.putText(img, text, (pad, pad + th), font, scale, 0, thick, cv2.LINE_AA)
    return img


def _draw_number(text: str, font: int, weight: float, height: float,
                 rng: np.random.Generator) -> np.ndarray:
    """``text`` black on white with digits ``height`` px high, as a camera sees a far sign:
    drawn 64 px high, warped (rotation, shear, aspect), shrunk, then blurred (focus, motion
    blur of 3 or 5 px), noised and sometimes JPEG-compressed at that size."""
    img = _text_image(text, font, weight)
    h, w = img.shape
    a = np.deg2rad(rng.uniform(-4, 4))
    shear, aspect = rng.uniform(-0.15, 0.15), rng.uniform(0.8, 1.15)
    m = np.array([[np.cos(a) * aspect, -np.sin(a) + shear], [np.sin(a) * aspect, np.cos(a)]])
    c = np.array([w / 2, h / 2])
    f = height / 64.0
    M = f * np.hstack([m, (c - m @ c)[:, None]])
    small = cv2.warpAffine(img, M, (max(4, int(w * f)), max(4, int(h * f))),
                           flags=cv2.INTER_AREA, borderValue=255)
    sigma = rng.uniform(0.0, 1.0)
    if sigma > 0.3:
        small = cv2.GaussianBlur(small, (0, 0), sigma)
    if rng.random() < 0.35:
        angle = rng.uniform(-0.3, 0.3) + (np.pi / 2 if rng.random() < 0.5 else 0.0)
        small = cv2.filter2D(small, -1, _motion_kernel(int(rng.choice([3, 5])), angle))
    noisy = small + rng.normal(0.0, rng.uniform(0.0, 10.0), small.shape)
    small = np.clip(noisy, 0, 255).astype(np.uint8)
    if rng.random() < 0.3:
        _, buf = cv2.imencode('.jpg', small, [cv2.IMWRITE_JPEG_QUALITY,
                                              int(rng.integers(25, 90))])
        small = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return small


def _training_glyphs(grey: np.ndarray, height: float, text: str,
                     rng: np.random.Generator) -> list[np.ndarray]:
    """The glyphs of a drawn number (digits ``height`` px high) scaled to a working digit
    height, segmented and normalised exactly as a crop's number is ([] if the segmentation
    does not find one glyph per digit)."""
    up = _WORK_DIGIT_H * rng.uniform(0.8, 1.25) / height
    big = cv2.resize(grey, None, fx=up, fy=up,
                     interpolation=cv2.INTER_CUBIC if up > 1 else cv2.INTER_AREA)
    ink = _ink(big, np.ones(big.shape, np.uint8))
    if ink is None:
        return []
    boxes, _ = _segment(ink, 0.5 * height * up)
    return [_glyph(ink, b) for b in boxes] if len(boxes) == len(text) else []


@dataclass(frozen=True)
class DigitModel:
    """Linear discriminant digit classifier over 0-9 (Gaussian classes, one shared,
    shrunk covariance).

    Attributes:
        W, b: discriminants ``features @ W + b`` (softmax: the posteriors).
        precision: the inverse of the shared covariance.
        typical_d2: median squared Mahalanobis distance of the training digits to their
            class mean (the unit of :meth:`scores`' distances).
        fonts, samples: what it was trained on.
    """

    W: np.ndarray
    b: np.ndarray
    precision: np.ndarray
    typical_d2: float
    fonts: tuple[int, ...]
    samples: int

    def scores(self, glyphs: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(posteriors (n, 10), squared Mahalanobis distance to each class mean in units
        of ``typical_d2`` (n, 10)) of ``glyphs``."""
        X = np.stack([features(g) for g in glyphs]).astype(np.float64)
        # einsum, not BLAS: a multi-threaded BLAS spins for whole milliseconds on a busy
        # machine for products this small
        z = np.einsum('ij,jk->ik', X, self.W) + self.b
        d2 = (np.einsum('ij,jk->ik', X, self.precision) * X).sum(axis=1)[:, None] - 2 * z
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True), d2 / self.typical_d2


@lru_cache(maxsize=4)
def digit_model(fonts: tuple[int, ...] = FONTS, numbers: int = 1200, seed: int = 0
                ) -> DigitModel:
    """Train the digit classifier on rendered numbers (deterministic, about a second;
    cached).

    ``numbers`` random two-digit strings (every digit in both places; one in ten a single
    digit) are drawn in the Hershey ``fonts`` at random stroke weights (:data:`_WEIGHTS`)
    and digit heights (:data:`_SMALL_H`, log-uniform), warped, blurred, noised and
    compressed (:func:`_draw_number`), then segmented as a crop's number is, so merged and
    split digits are learnt too.  Linear discriminant analysis with a shrunk pooled
    covariance.
    """
    rng = np.random.default_rng([seed, 0xd161])
    X, y = [], []
    for i in range(numbers):
        text = ''.join(str(d) for d in rng.integers(0, 10, 1 if rng.random() < 0.1 else 2))
        height = float(np.exp(rng.uniform(*np.log(_SMALL_H))))
        grey = _draw_number(text, fonts[i % len(fonts)], rng.uniform(*_WEIGHTS), height, rng)
        for ch, g in zip(text, _training_glyphs(grey, height, text, rng)):
            X.append(features(g))
            y.append(int(ch))
    X, y = np.asarray(X, np.float64), np.asarray(y)
    means = np.stack([X[y == d].mean(axis=0) for d in range(10)])
    R = X - means[y]
    cov = R.T @ R / max(1, len(X) - 10)
    cov = (1 - _SHRINK) * cov + _SHRINK * np.trace(cov) / cov.shape[0] * np.eye(cov.shape[0])
    P = np.linalg.inv(cov)
    W = P @ means.T
    b = -0.5 * np.sum(means.T * W, axis=0)
    d2 = ((R @ P) * R).sum(axis=1)
    return DigitModel(W, b, P, float(np.median(d2)), tuple(fonts), len(X))


def classify_glyphs(glyphs: Sequence[np.ndarray], fonts: tuple[int, ...] = FONTS
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(posterior per digit class, distance to each class) of each glyph: two
    (len(glyphs), 10) arrays (see :meth:`DigitModel.scores`)."""
    return digit_model(tuple(fonts)).scores(glyphs)


def _digit_confidence(post: np.ndarray, d2: np.ndarray) -> tuple[int, float]:
    """(best digit, confidence): its posterior probability, times a factor that falls from
    1 to 0 as its distance to the digit's class grows from :data:`_D2_TYPICAL` to
    :data:`_D2_FAR` typical distances (a glyph unlike every digit: a cut, merged or
    smeared one)."""
    d = int(np.argmax(post))
    near = np.clip((_D2_FAR - d2[d]) / (_D2_FAR - _D2_TYPICAL), 0.0, 1.0)
    return d, float(post[d] * near)


# ------------------------------------------------------------------ whole-number check
#: Size (px) of a normalised number (all its digits): height, width.
NUMBER_H, NUMBER_W = 20, 40


def _number_patch(ink: np.ndarray, boxes) -> np.ndarray:
    """The ink of the number (the union of its digit boxes) scaled to NUMBER_H rows and
    centred in a NUMBER_H x NUMBER_W canvas, as a zero-mean unit vector."""
    x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
    x1 = max(b[0] + b[2] for b in boxes)
    y1 = max(b[1] + b[3] for b in boxes)
    return _unit(_fit(ink[y0:y1, x0:x1], NUMBER_H, NUMBER_W).ravel())


@lru_cache(maxsize=4)
def number_templates(fonts: tuple[int, ...] = FONTS) -> tuple[np.ndarray, np.ndarray]:
    """Whole-number templates of every valid speed: (vectors (N, NUMBER_H * NUMBER_W),
    values (N,)), each speed in every font and three stroke weights, drawn with digits 6,
    9, 14 and 30 px high (focus-blurred too) and segmented as a crop's number is
    (deterministic; cached)."""
    vecs, values = [], []
    for value in VALID_SPEEDS:
        text = str(value)
        for font in fonts:
            for weight in (0.11, 0.16, 0.21):
                for height in (6.0, 9.0, 14.0, 30.0):
                    grey = _draw_clean(text, font, weight, height, blur=height < 10)
                    up = _WORK_DIGIT_H / height
                    big = cv2.resize(grey, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
                    ink = _ink(big, np.ones(big.shape, np.uint8))
                    if ink is None:
                        continue
                    boxes, _ = _segment(ink, 0.5 * _WORK_DIGIT_H)
                    if len(boxes) == len(text):
                        vecs.append(_number_patch(ink, boxes))
                        values.append(value)
    return np.asarray(vecs, np.float32), np.asarray(values, np.int64)


def _draw_clean(text: str, font: int, weight: float, height: float, blur: bool) -> np.ndarray:
    """``text`` black on white, digits ``height`` px high (drawn 64 px, shrunk; a Gaussian
    blur of 0.7 px at that size if ``blur``)."""
    f = height / 64.0
    small = cv2.resize(_text_image(text, font, weight), None, fx=f, fy=f,
                       interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(small, (0, 0), 0.7) if blur else small


def _holistic_margin(digits: '_Digits', value: int) -> float:
    """How much better ``value``'s templates fit the whole number than the best other valid
    speed's (normalised correlation; negative when another speed fits better)."""
    T, values = number_templates(FONTS)
    scores = np.einsum('ij,j->i', T, _number_patch(digits.ink, digits.boxes))
    own = scores[values == value]
    other = scores[values != value]
    if own.size == 0 or other.size == 0:
        return -1.0
    return float(own.max() - other.max())


# ------------------------------------------------------------------ the reader
def warm_up() -> None:
    """Train the digit model, draw the number templates and run the reader once (about a
    second): call it when a node starts, so the first sign is read in milliseconds."""
    digit_model(FONTS)
    number_templates(FONTS)
    blank = np.full((WORK_H, WORK_H // 2, 3), 200, np.uint8)
    read_speed_limit(blank)


def read_speed_limit(crop_bgr: np.ndarray, min_height_px: int = 24,
                     min_confidence: float = MIN_CONFIDENCE) -> SpeedReading:
    """Read the limit on a work-zone speed limit sign crop.

    Args:
        crop_bgr: the classifier's crop of a ``work_zone_speed_limit`` sign (uint8 BGR; grey
            and BGRA accepted), with a margin, possibly shifted or cut by the image border.
        min_height_px: crops less tall than this are not read ('too small').
        min_confidence: reads below this confidence are returned as None.

    Returns:
        A :class:`SpeedReading`: ``value`` a multiple of 5 in 5..85, or None with a reason
        ('too small', 'no white panel', 'no digits', 'ambiguous digits', 'digits cut by the
        crop border', 'not a speed' (not a multiple of 5 in range), 'low confidence', ...).

    Raises:
        ValueError: ``crop_bgr`` is not a uint8 image.
    """
    bgr = _as_bgr(crop_bgr)
    if bgr.shape[0] < max(1, min_height_px) or bgr.shape[1] < 4:
        return _unread('too small')
    work = _working_image(bgr)
    sign = _locate(work)
    if sign is None:
        return _unread('no white panel')
    if not 0.35 * WORK_H <= 4.0 * sign.ph <= 1.6 * WORK_H:
        return _unread('sign of the wrong size for the crop')
    digits, reason = _digits(cv2.cvtColor(work, cv2.COLOR_BGR2GRAY), sign)
    if digits is None:
        return _unread(reason)
    glyphs = [_glyph(digits.ink, b) for b in digits.boxes]
    post, d2 = classify_glyphs(glyphs)
    reads = [_digit_confidence(p, d) for p, d in zip(post, d2)]
    value = int(''.join(str(d) for d, _ in reads))
    conf = float(np.prod([c for _, c in reads]))
    if value not in VALID_SPEEDS or (len(reads) == 2 and reads[0][0] == 0):
        return _unread('not a speed', conf)
    whole = not sign.cut_side and sign.px1 - sign.px0 >= 0.85 * sign.ph / _PLAQUE_ASPECT
    if (len(reads) == 1 and not whole) or (not sign.cut_side and not _centred(digits, sign)):
        return _unread('number off the panel centre', conf)
    if conf < min_confidence:
        return _unread('low confidence', conf)
    if _holistic_margin(digits, value) < _HOLISTIC_MARGIN:
        return _unread('another speed fits the whole number better', conf)
    return SpeedReading(value, round(conf, 3), '')
