"""White regulatory rectangles, green guide signs and mile markers, by colour and shape.

Cahail et al. recognise red and yellow signs only; the catalogue's other general signs
(Balali and Golparvar-Fard's classes, DESIGN.md "Sign catalogue") are found here by the
same colour blob idea with stricter shape and legend tests:

* ``speed_limit`` (R2-1): a white region of sign proportions (taller than wide) that fills
  its box, holds a dark legend in its upper and lower parts and is framed by a dark ring
  (the black border line, or a darker background) on every side.  White alone is
  everywhere (sky, lane lines, trailers): the legend and the border are what make a sign.
* ``guide`` (D1-1 ...): a wide green rectangle with a white legend.
* ``mile_marker`` (D10-1): a small tall green rectangle with a white legend; its number is
  read with the digit classifier of :mod:`workzone_ros.core.digits` when the digits are
  large enough, and left None otherwise (never guessed).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core import digits
from workzone_ros.core.general import colour
from workzone_ros.core.general.config import GeneralConfig
from workzone_ros.core.kernels import components_with_stats

__all__ = ['Panel', 'white_panels', 'green_panels', 'read_mile']


@dataclass(frozen=True)
class Panel:
    """A panel in working px: box, class key and score."""

    box: tuple[int, int, int, int]
    class_key: str
    score: float


def _dark_sides(v: np.ndarray, box, ref: float, cfg: GeneralConfig) -> int:
    """How many of the four sides of ``box`` have, within 10 % of its size outside it, a line
    parallel to the side that is mostly darker than ``ref`` (the border line, or a darker
    background)."""
    x, y, w, h = box
    H, W = v.shape
    t = max(2, int(round(0.1 * min(w, h))))
    lines = ([v[y - k, x:x + w] for k in range(1, t + 1) if y - k >= 0],
             [v[y + h - 1 + k, x:x + w] for k in range(1, t + 1) if y + h - 1 + k < H],
             [v[y:y + h, x - k] for k in range(1, t + 1) if x - k >= 0],
             [v[y:y + h, x + w - 1 + k] for k in range(1, t + 1) if x + w - 1 + k < W])
    return sum(1 for side in lines
               if any(np.count_nonzero(ln < 0.7 * ref) >= cfg.border_dark * ln.size
                      for ln in side))


def _white_panel(hsv: np.ndarray, b: colour.Blob, cfg: GeneralConfig) -> Optional[Panel]:
    """A white blob is an R2-1 panel when, in its box, white and dark legend together fill
    it, the dark legend (measured in the box less a 10 % rim: a number merged with the border
    line is outside the white blob) is in its upper and its lower part, ``border_sides`` sides are
    framed dark, and no orange WORK ZONE plaque sits on top (that is a work-zone sign)."""
    x, y, w, h = b.box
    lo, hi = cfg.speed_limit_aspect
    if not lo <= w / h <= hi:
        return None
    patch = hsv[y:y + h, x:x + w]
    v = patch[..., 2]
    white = b.mask > 0
    ref = float(np.median(v[white & (patch[..., 1] <= cfg.white_max_saturation)]))
    dark = v < 0.55 * ref
    fill = np.count_nonzero(white | dark) / float(w * h)
    if fill < cfg.panel_fill:
        return None
    mx, my = max(1, int(0.1 * w)), max(1, int(0.1 * h))
    core = dark[my:h - my, mx:w - mx]
    share = float(core.mean()) if core.size else 0.0
    top, bottom = core[:int(0.4 * core.shape[0])], core[int(0.5 * core.shape[0]):]
    if not cfg.panel_legend[0] <= share <= cfg.panel_legend[1] or \
            not top.size or not bottom.size or top.mean() < 0.03 or bottom.mean() < 0.03:
        return None
    sides = _dark_sides(hsv[..., 2], b.box, ref, cfg)
    if sides < cfg.border_sides or _plaque_above(hsv, b.box, cfg):
        return None
    return Panel(b.box, 'speed_limit', round(float(0.5 * min(1.0, fill) + 0.125 * sides), 3))


def _plaque_above(hsv: np.ndarray, box, cfg: GeneralConfig) -> bool:
    """True when the band above ``box`` (a third of its height) is mostly saturated orange
    (the WORK ZONE plaque of a work-zone speed limit, R2-1 + G20-5aP)."""
    x, y, w, h = box
    band = hsv[max(0, y - int(0.4 * h)):y, x:x + w]
    if not band.size:
        return False
    hue, sat = band[..., 0], band[..., 1]
    orange = (hue > cfg.red_hue_lo - 2) & (hue < cfg.yellow_hue[0] + 2) & \
        (sat >= cfg.min_saturation)
    return float(orange.mean()) > 0.25


def white_panels(work: colour.Working, cfg: GeneralConfig) -> list[Panel]:
    """R2-1 speed limit panels of the working image."""
    hsv = work.hsv
    mask = colour.clean(colour.white_mask(hsv, cfg), cfg)
    max_area = cfg.max_panel_share * mask.size
    return [p for b in colour.blobs(mask, cfg.min_side_px / work.scale, max_area)
            if (p := _white_panel(hsv, b, cfg)) is not None]


def _green_panel(hsv: np.ndarray, b: colour.Blob, cfg: GeneralConfig) -> Optional[Panel]:
    x, y, w, h = b.box
    a = w / h
    if cfg.guide_aspect[0] <= a <= cfg.guide_aspect[1]:
        key = 'guide'
    elif cfg.mile_aspect[0] <= a <= cfg.mile_aspect[1]:
        key = 'mile_marker'
    else:
        return None
    if b.fill < cfg.panel_fill:
        return None
    patch = hsv[y:y + h, x:x + w]
    inside = b.mask > 0
    green = inside & (patch[..., 1] > cfg.green_min_saturation)
    if not green.any():
        return None
    ref = float(np.median(patch[..., 2][green]))
    legend = inside & (patch[..., 1] <= cfg.white_max_saturation + 20) & \
        (patch[..., 2] > max(1.3 * ref, ref + 30))
    share = np.count_nonzero(legend) / max(1, np.count_nonzero(inside))
    if not cfg.panel_legend[0] <= share <= cfg.panel_legend[1]:
        return None
    return Panel(b.box, key, round(float(min(1.0, b.fill) * min(1.0, 4 * share)), 3))


def green_panels(work: colour.Working, cfg: GeneralConfig) -> list[Panel]:
    """Guide signs and mile markers of the working image: green blobs (pieces of one panel
    cut by a legend line joined) of the loose and the strict green mask (the strict one
    keeps a sign apart from the darker, less saturated foliage behind it)."""
    hsv = work.hsv
    out: list[Panel] = []
    max_area = cfg.max_panel_share * hsv.shape[0] * hsv.shape[1]
    for strict in (False, True):
        mask = colour.clean(colour.green_mask(hsv, cfg, strict), cfg)
        for b in colour.merge_stacked(colour.blobs(mask, 3.0, max_area)):
            if min(b.box[2:]) < cfg.min_side_px / work.scale / 2 or \
                    any(colour.iou(b.box, p.box) > 0.5 for p in out):
                continue
            p = _green_panel(hsv, b, cfg)
            if p is not None:
                out.append(p)
    return out


# ------------------------------------------------------------------ mile number
_READ_H = 160       # the marker is scaled to this height before its digits are cut


def _digit_boxes(ink: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Digit boxes (x, y, w, h) below MILE, top to bottom: the white blobs of the marker's
    lower 70 % that stand in one column near its centre line, of like height."""
    H, W = ink.shape
    mask = (ink >= 0.5).astype(np.uint8)
    mask[:int(0.27 * H)] = 0
    n, _, stats = components_with_stats(mask)
    comps = [tuple(int(v) for v in stats[i, :4]) for i in range(1, n)]
    comps = [c for c in comps if c[3] >= 0.08 * H and c[2] >= 0.05 * c[3]
             and c[0] > 0 and c[0] + c[2] < W and abs(c[0] + c[2] / 2 - W / 2) < 0.25 * W]
    if not comps:
        return []
    tallest = max(c[3] for c in comps)
    out = sorted((c for c in comps if c[3] >= 0.7 * tallest), key=lambda c: c[1])
    # the number fills the marker below MILE: a column that does not is cut or partly lost
    if out[0][1] > 0.45 * H or out[-1][1] + out[-1][3] < 0.8 * H:
        return []
    return out


def read_mile(bgr: np.ndarray, box: tuple[float, float, float, float],
              cfg: GeneralConfig) -> tuple[Optional[int], Optional[float]]:
    """(number, confidence) read from the mile marker at full-image ``box``, or (None,
    None) when its digits are too small, not one clean column of 1-3 digits, or any digit's
    confidence (:mod:`workzone_ros.core.digits`) is below ``min_mile_confidence``."""
    H, W = bgr.shape[:2]
    x, y, w, h = (int(round(v)) for v in box)
    x0, y0, x1, y1 = max(0, x), max(0, y), min(W, x + w), min(H, y + h)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None, None
    lum = bgr[y0:y1, x0:x1].min(axis=2)             # white high, green (R ~ 0) low
    f = _READ_H / lum.shape[0]
    big = cv2.resize(lum, None, fx=f, fy=f, interpolation=cv2.INTER_CUBIC)
    bg, white = np.percentile(big, 30), np.percentile(big, 98)
    if white - bg < 30:
        return None, None
    ink = np.clip((big.astype(np.float32) - bg) / (white - bg), 0.0, 1.0)
    boxes = _digit_boxes(ink)
    if not 1 <= len(boxes) <= 3 or min(b[3] for b in boxes) / f < cfg.min_digit_px:
        return None, None
    glyphs = [digits._fit(ink[by:by + bh, bx:bx + bw], digits.GLYPH_H, digits.GLYPH_W)
              for bx, by, bw, bh in boxes]
    post, d2 = digits.classify_glyphs(glyphs)
    read = [digits._digit_confidence(p, d) for p, d in zip(post, d2)]
    conf = min(c for _, c in read)
    if conf < cfg.min_mile_confidence:
        return None, None
    return int(''.join(str(d) for d, _ in read)), round(float(conf), 3)
