"""Rectangle fit of a regulatory sign's orange part and white part.

:func:`refine_rectangle` measures the left, right and top edges (and the white part's bottom)
on the brightness (:mod:`.edges`); :func:`white_beyond` looks at where a two-colour sign's
white part ends beside it.  :class:`RectangleMixin` boxes a measured candidate with them.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.detect.common import pixel_box
from workzone_ros.core.detect.edges import (
    _PROFILE_SIG,
    _PROFILE_U0,
    _edge_offsets,
    _edge_profile,
    _taper,
)
from workzone_ros.core.detect.plaque import _ratio_error

__all__ = [
    'RECT_TOP_STRETCHES', 'refine_rectangle', 'white_beyond',
    'RectangleMixin',
]


#: refine_rectangle's top-edge stretches (fractions of the face's width): clear of a centred
#: legend (the catalogue's WORK ZONE / END lines start at 0.17 of the face's width) and of
#: the side lines' blur.  Over the middle (0.2-0.45, 0.55-0.8), tuning regulatory P / R
#: 0.975 / 0.957, dusk 0.964 / 0.947; here 0.979 / 0.955, dusk 0.971 / 0.951.
RECT_TOP_STRETCHES = ((0.06, 0.2), (0.8, 0.94))


def _shifted_offsets(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, prof: tuple,
                     min_contrast: float, shifts: Sequence[float] = (1.5, 3.0)
                     ) -> Optional[np.ndarray]:
    """:func:`_edge_offsets` of edge stretches moved out (against their inward normals) by
    each of ``shifts`` px in turn (negative: moved in), as offsets from where they were: the
    first shift at which every stretch shows a step short of the search's outer end (the
    edge is not further out still).  None when none does or a stretch leaves ``img``."""
    outer = float(_PROFILE_U0[prof[3][::_PROFILE_SIG.size]].min())
    for sh in shifts:
        off = _edge_offsets(img, segs - sh * nvecs[:, None], nvecs, prof, min_contrast)
        if off is None:
            continue
        if (off > outer + 0.1).all():
            return off - sh
    return None


def _white_sides(img: np.ndarray, x: float, w: float, y0: float, y1: float, prof: tuple,
                 min_contrast: float) -> Optional[np.ndarray]:
    """The left and right edge offsets (from ``x`` and ``x + w``, inwards) of a two-colour
    sign's white part (rows ``y0`` to ``y1``) on two stretches each (20-45 % and 55-80 % of
    its height): ``(2, 2)``, NaN where a stretch shows no step; None when the part is too
    short or a stretch leaves ``img``."""
    if y1 - y0 < 4:
        return None
    segs, nvecs = _side_stretches(x, w, y0, y1 - y0)
    off = _edge_offsets(img, segs, nvecs, prof, min_contrast, missing=True)
    return None if off is None else off.reshape(2, 2)


def _side_stretches(x: float, w: float, y: float, h: float,
                    at: tuple = ((0.2, 0.45), (0.55, 0.8))) -> tuple[np.ndarray, np.ndarray]:
    """A rectangle's side stretches (the left edge ``x`` and right edge ``x + w`` of rows
    ``y`` to ``y + h``, at the fractions ``at`` of the height: 20-45 % and 55-80 %) and
    their inward normals, in the order left, right, left, right: ``((4, 2, 2), (4, 2))``."""
    segs = np.array([((xe, y + f0 * h), (xe, y + f1 * h))
                     for f0, f1 in at for xe in (x, x + w)], float)
    return segs, np.array([(1.0, 0.0), (-1.0, 0.0)] * 2)


def refine_rectangle(value: np.ndarray, box: Sequence[float], size: float,
                     border_rel: float = 0.03, margin_rel: float = 0.015,
                     max_change: float = 0.2, min_contrast: float = 0.25,
                     bottom: Optional[float] = None, free_top: bool = False,
                     top_at: tuple = RECT_TOP_STRETCHES, inward: Sequence[float] = ()
                     ) -> Optional[tuple[Optional[float], Optional[float], Optional[float],
                                         Optional[float]]]:
    """Sub-pixel left, right and top edges of a rectangular sign's orange face.

    ``box = (x, y, w, h)``: a first estimate of the orange part (continuous coordinates), e.g.
    its hull's box; ``size``: the sign's shorter side (its width for a two-colour sign, px).
    As :func:`refine_diamond`, on the brightness: the left and right edges on two stretches
    each (20-45 % and 55-80 % of the height), the top edge on two near the corners (``top_at``,
    fractions of the width: a rectangle's legend is centred and its first line starts just
    under the top border, so stretches over the middle measured the legend's dark strokes as
    part of the edge profile), each fitted with the face / border line / margin / background
    model; the line's width and the margin outside it are ``border_rel`` and ``margin_rel`` x
    ``size`` (defaults: the catalogue's rectangles, a line 3 % of the shorter side at 1.5-4.5 %
    from the edge).  The bottom of the orange part (a divider line over the white part, or the
    sign's own bottom) is not measured; ``bottom``: the row where the caller found the sign's
    face to end (the white part's last white row of a two-colour sign), whose edge is measured
    the same way.

    ``free_top``: the sign is known to be a rectangle (a two-colour sign's white part was
    found below it): its top is measured on those of its stretches that show a step, and
    is None when neither does (a small sign's legend runs into its top line).

    A stretch whose profiles would leave ``value`` (a sign at the image's edge) is not
    measured: a side (or the top) with such a stretch is returned as None.  A side of the
    orange part without a step is measured on the white part below it when ``bottom`` is
    given (:func:`_white_sides`), else with its stretches moved out by 1.5 or 3 px
    (:func:`_shifted_offsets`: a hull short of a pale face), then in by each of ``inward``
    (px: a hull that took in a pale wall beside the face); without ``bottom`` such a side
    fails the fit (the blob may be a diamond merged with a sky of its colour).

    Returns the face's ``(left, right, top, bottom)`` (``bottom`` None when not asked for or
    not measurable) or None when a side (on neither part) or top stretch in ``value`` shows
    no face-to-border step (but ``free_top``), neither side is measured, or the width moves
    by more than ``max_change``.
    """
    x, y, w, h = (float(v) for v in box[:4])
    if w < 6 or h < 4:
        return None
    img = np.ascontiguousarray(value, dtype=np.float32)
    border, margin = border_rel * size, margin_rel * size
    prof = _edge_profile(min(0.5 * w, h), border, margin)
    # start half-way between the hull's edge and the face's edge without margin and line:
    # the face's edge is then within the search either way
    inset = 0.5 * (border + margin)
    x, y, w = x + inset, y + inset, w - 2 * inset
    got = _rect_stretch_offsets(img, (x, y, w, h), top_at, prof, min_contrast, free_top)
    if got is None or not _mend_lost_sides(img, got, prof, min_contrast, (x, y, w, h), bottom,
                                           inset, inward):
        return None
    edges = _rect_edges(got[2], got[3], x, y, w, inset, max_change)     # side, shown
    return None if edges is None else (
        *edges, _rect_bottom(img, x, w, bottom, inset, prof, min_contrast))


def _rect_stretch_offsets(img: np.ndarray, rect: tuple, top_at: tuple, prof: tuple,
                          min_contrast: float, free_top: bool
                          ) -> Optional[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`refine_rectangle`'s first measurement: the edge offsets of the inset box
    ``rect = (x, y, w, h)``'s stretches.  Returns ``(segs, nvecs, side, shown)``: the
    stretches, their inward normals, the two stretch pairs' left, right and top offsets
    (``(2, 3)``, NaN where a stretch shows no step or is not measured) and which stretches
    lie in ``img``; None when none does, the measurement fails, or a top stretch in ``img``
    shows no step (but ``free_top``)."""
    x, y, w, h = rect
    # per stretch pair: left, right (20-45 % and 55-80 % of the height), top (``top_at``)
    sides, side_n = _side_stretches(x, w, y, h)
    tops = np.array([((x + g0 * w, y), (x + g1 * w, y)) for g0, g1 in top_at], float)
    segs = np.concatenate([sides[:2], tops[:1], sides[2:], tops[1:]])
    nvecs = np.concatenate([side_n[:2], [(0.0, 1.0)], side_n[2:], [(0.0, 1.0)]])
    # a stretch whose profiles leave the image (a sign at its edge) is not measured
    u = prof[0]
    ends = np.concatenate([segs + u[0] * nvecs[:, None], segs + u[-1] * nvecs[:, None]], 1)
    inside = ((ends >= 0.5).all(axis=(1, 2)) & (ends[..., 0] <= img.shape[1] - 0.5).all(1)
              & (ends[..., 1] <= img.shape[0] - 0.5).all(1))
    if not inside.any():
        return None
    off = np.full(len(segs), np.nan)
    o_ = _edge_offsets(img, segs[inside], nvecs[inside], prof, min_contrast, missing=True)
    if o_ is None:
        return None
    off[inside] = o_
    side = off.reshape(2, 3)                  # the two stretches' left, right, top offsets
    shown = inside.reshape(2, 3)
    if not (free_top or (np.isfinite(side[:, 2]) | ~shown[:, 2]).all()):
        return None
    return segs, nvecs, side, shown


def _mend_lost_sides(img: np.ndarray, stretches: tuple, prof: tuple, min_contrast: float,
                     rect: tuple, bottom: Optional[float], inset: float,
                     inward: Sequence[float]) -> bool:
    """:func:`refine_rectangle`'s sides without a step, measured again: ``stretches`` is
    :func:`_rect_stretch_offsets`' ``(segs, nvecs, side, shown)`` (``side`` updated in
    place), ``rect`` the inset box; on the white part below (:func:`_white_sides`, when
    ``bottom`` is given), else on the stretches moved out, then in by each of ``inward``
    (:func:`_shifted_offsets`).  False when such a side cannot be measured (or ``bottom`` is
    None)."""
    segs, nvecs, side, shown = stretches
    lost = shown[:, :2] & ~np.isfinite(side[:, :2])
    if not lost.any():
        return True
    x, y, w, h = rect
    # a side of the orange part shows no step (a small plaque's legend runs up to
    # it, a dim one's line merges with a dark background): that side of the white
    # part below it, when there is one
    if bottom is None:
        return False            # (not known to be a rectangle: a diamond merged with a sky)
    white = _white_sides(img, x, w, y + h, float(bottom) - inset, prof, min_contrast)
    for k in (0, 1):
        if not lost[:, k].any():
            continue
        if white is not None and np.isfinite(white[:, k]).all():
            side[:, k] = white[:, k]
            continue
        # or the edge lies beyond the search (a hull short of a pale face's side):
        # the side's stretches moved out by a search's width or two
        got = _shifted_offsets(img, segs[[k, 3 + k]], nvecs[[k, 3 + k]], prof,
                               min_contrast, (1.5, 3.0) + tuple(-v for v in inward))
        if got is None:
            return False
        side[:, k] = got
    return True


def _rect_edges(side: np.ndarray, shown: np.ndarray, x: float, y: float, w: float,
                inset: float, max_change: float
                ) -> Optional[tuple[Optional[float], Optional[float], Optional[float]]]:
    """:func:`refine_rectangle`'s ``(left, right, top)`` from the stretches' offsets ``side``
    (of the inset box ``x``, ``y``, ``w``); None when neither side is measured or the width
    moves by more than ``max_change``."""
    # a side off the image is the box's own (the caller clips it to the image)
    left = x + float(side[:, 0].mean()) if shown[:, 0].all() else None
    right = x + w - float(side[:, 1].mean()) if shown[:, 1].all() else None
    tops = side[np.isfinite(side[:, 2]), 2]
    top = y + float(tops.mean()) if tops.size else None
    if left is None and right is None:
        return None
    if left is not None and right is not None and not abs(
            (right - left) / (w + 2 * inset) - 1) <= max_change:
        return None
    return left, right, top


def _rect_bottom(img: np.ndarray, x: float, w: float, bottom: Optional[float], inset: float,
                 prof: tuple, min_contrast: float) -> Optional[float]:
    """:func:`refine_rectangle`'s bottom edge near row ``bottom`` (the inset box's ``x``,
    ``w``), on two stretches (20-45 % and 55-80 % of the width); None when ``bottom`` is
    None or either stretch shows no step."""
    if bottom is None:
        return None
    yb = float(bottom) - inset
    ob = _edge_offsets(img, np.array([((x + 0.2 * w, yb), (x + 0.45 * w, yb)),
                                      ((x + 0.55 * w, yb), (x + 0.8 * w, yb))]),
                       np.array([(0.0, -1.0), (0.0, -1.0)]), prof, min_contrast)
    if ob is None:
        return None
    return yb - 0.5 * (ob[0] + ob[1])


def _white_columns(bgr: np.ndarray, left: float, right: float, r0: int, r1: int, c0: int,
                   c1: int) -> Optional[np.ndarray]:
    """Per column ``c0``..``c1`` (inclusive): the share of rows ``r0``..``r1`` (exclusive)
    that are white by a two-colour sign's white part's own level (brightness at least 0.85
    x its 75th percentile between the face's sides ``left`` and ``right``; saturation at
    most 90 of 255).  None when no column lies between the sides."""
    hsv = cv2.cvtColor(bgr[r0:r1, c0:c1 + 1], cv2.COLOR_BGR2HSV)
    v, sat = hsv[..., 2].astype(np.float32), hsv[..., 1]
    inner = v[:, int(math.ceil(left)) + 1 - c0:int(right) - 1 - c0]
    if inner.size == 0:
        return None
    level = float(np.percentile(inner, 75))
    return ((v >= 0.85 * level) & (sat <= 90)).mean(axis=0)


def white_beyond(bgr: np.ndarray, face: Sequence[float], rows: Sequence[float],
                 gap: float) -> bool:
    """Whether a two-colour sign's white part (``rows = (top, bottom)``, its middle 10-90 %
    looked at) is white (:func:`_white_columns`, at least half the rows) on every column of
    ``gap`` px just outside either side of ``face = (left, right)``: a side measured inside
    the sign.  False at the image's edge."""
    left, right = float(face[0]), float(face[1])
    h, w = bgr.shape[:2]
    top, bottom = float(rows[0]), float(rows[1])
    r0, r1 = int(math.ceil(top + 0.1 * (bottom - top))), int(bottom - 0.1 * (bottom - top))
    g = max(1, int(round(gap)))
    c0, c1 = int(math.floor(left)) - g, int(math.ceil(right)) + g - 1
    if r1 - r0 < 3 or right - left < 4 or c0 < 0 or c1 >= w or r0 < 0 or r1 > h:
        return False
    share = _white_columns(bgr, left, right, r0, r1, c0, c1)
    if share is None:
        return False
    white = share >= 0.5
    return bool(white[:g].all() or white[-g:].all())


class RectangleMixin:
    """The detector's rectangle steps: a regulatory sign's box from its measured edges."""

    def _rectangle_box(self, bgr: np.ndarray, raw: np.ndarray, pix: np.ndarray, v_ref: float,
                       cand: Candidate, entry: Optional[dict], window: tuple, blob: tuple,
                       m: int) -> bool:
        """:meth:`_measure_orange`'s regulatory box: ``cand``'s box from its orange part's
        edges (and its white part's) measured on the brightness; False (``cand``
        unchanged) when no fit measures them.  ``window``: the blob's window ``(x0, y0, x1,
        y1)``; ``blob``: its hull box there; ``m``: the window's margin; ``pix``: the
        face's orange pixels in ``raw``, the window as the camera gave it."""
        cfg = self.config
        x0, y0, x1, y1 = window
        bx0, by0, bw, bh = blob
        # the orange part's left, right and top edges from the brightness profile; the
        # sign's outer edges lie the border line and margin further out (in units of
        # the sign's shorter side: the width of a two-colour sign)
        face_frac = 1.0 - 2.0 * (cfg.rect_border_rel + cfg.rect_margin_rel)
        size = (bw if cand.extended else min(bw, bh)) / face_frac
        # the brightness a few pixels beyond the blob's window, down over the white part
        # when the extension found it (its bottom edge is measured too)
        pad = 3 + int(0.05 * max(bw, bh))
        y_end = max(y1, int(cand.y + cand.h) + m) if cand.extended else y1
        value, ox, oy = self._value(bgr, x0 - pad, y0 - pad, x1 + pad, y_end + pad)
        dx, dy = x0 - ox, y0 - oy
        low = cand.y + cand.h - oy if cand.extended else None
        hx, hw = bx0 + dx, bw                   # the orange part's columns (window)
        sub = refine_rectangle(value, (hx, by0 + dy, hw, bh), size,
                               cfg.rect_border_rel, cfg.rect_margin_rel,
                               cfg.rect_max_change, bottom=low,
                               free_top=cand.extended)
        sub, hx, hw, size = self._rect_refit(bgr, value, (ox, oy), cand, entry, sub,
                                             (hx, hw, size), low, window, blob)
        if entry is not None:
            entry['rect_refined'] = sub is not None
        if sub is None:
            return False
        self._rect_apply(bgr, raw, pix, v_ref, cand, (ox, oy), sub,
                         (hx, hw, size), window, blob)
        return True

    def _rect_refit(self, bgr: np.ndarray, value: np.ndarray, org: tuple, cand: Candidate,
                    entry: Optional[dict], sub: Optional[tuple], start: tuple,
                    low: Optional[float], window: tuple, blob: tuple) -> tuple:
        """The rectangle fit made again with a lost side moved in (``rect_inward``) when the
        orange part's own fit ``sub`` (from ``start = (hx, hw, size)``, in the brightness
        window ``value`` at ``org``) fails.  Returns ``(sub, hx, hw, size)``: the fit kept
        and its start."""
        cfg = self.config
        ox, oy = org
        hx, hw, size = start
        y0 = window[1]
        bx0, by0, bw, bh = blob
        dy = y0 - oy
        face_frac = 1.0 - 2.0 * (cfg.rect_border_rel + cfg.rect_margin_rel)
        if sub is None and cfg.rect_inward and cand.extended:
            # no side on either start's search: a pale wall right beside the sign took
            # the hull (and the white part) past the side, whose edge then lies inside
            # the search: the lost side's stretches moved in.  Kept when the sign has a
            # catalogue shape and its white part does not run on past a side
            sub3 = refine_rectangle(value, (hx, by0 + dy, hw, bh), size,
                                    cfg.rect_border_rel, cfg.rect_margin_rel,
                                    cfg.rect_max_change, bottom=low, free_top=True,
                                    inward=cfg.rect_inward)
            if sub3 is None or sub3[0] is None or sub3[1] is None or sub3[3] is None:
                return sub, hx, hw, size
            top3 = sub3[2] if sub3[2] is not None else by0 + dy
            r_out = (sub3[3] - top3) / max(sub3[1] - sub3[0], 1.0) * face_frac \
                + 1.0 - face_frac
            fl, fr = ox + sub3[0], ox + sub3[1]
            ok = _ratio_error(np.array([r_out]), 1.0)[0] <= cfg.ext_ratio_tol \
                and not white_beyond(bgr, (fl, fr), (y0 + by0 + bh, oy + sub3[3]),
                                     max(2.0, 0.1 * (fr - fl)))
            if entry is not None:
                entry.setdefault('inward', []).append((round(r_out, 3), ok))
            if ok:
                sub = sub3
        return sub, hx, hw, size

    def _rect_apply(self, bgr: np.ndarray, raw: np.ndarray, pix: np.ndarray, v_ref: float,
                    cand: Candidate, org: tuple, sub: tuple, start: tuple, window: tuple,
                    blob: tuple) -> None:
        """``cand``'s box from the measured face ``sub`` (in the brightness window at
        ``org``; ``start = (hx, hw, size)``: the fit's start): the edges' biases, the
        border line and margin outside them, clipped to the frame, in whole pixels."""
        cfg = self.config
        H, W = bgr.shape[:2]
        ox, oy = org
        hx, hw, size = start
        y0 = window[1]
        bx0, by0, bw, bh = blob
        dy = y0 - oy
        face_frac = 1.0 - 2.0 * (cfg.rect_border_rel + cfg.rect_margin_rel)
        left, right, top, low = sub            # in the brightness window
        q = cfg.rect_edge_bias
        qs = q - _taper(cfg.rect_dim_bias, v_ref)
        qb = q
        if cfg.rect_clip_bias > 0:
            # clipped faces: the blurred edge's half level is above 255, so the
            # clipped ramp puts the edge further out than it is
            face_v = raw[pix > 0].max(axis=1)
            qs += cfg.rect_clip_bias * float(np.count_nonzero(face_v >= 250)) / max(
                float(face_v.size), 1.0)
            if low is not None:
                wy0 = int(max(y0 + by0 + bh, oy + low - 0.4 * (low - (by0 + dy + bh))))
                wy1 = int(oy + low - 1)
                wx0, wx1 = int(ox + hx + 0.2 * hw), int(math.ceil(ox + hx + 0.8 * hw))
                part = bgr[wy0:wy1, wx0:wx1]
                if part.size:
                    qb += cfg.rect_clip_bias * float((part.max(axis=2) >= 250).mean())
        # a side off the image: the hull's (the box is clipped to the image below)
        left = hx if left is None else left + qs
        right = hx + hw if right is None else right - qs
        out = (cfg.rect_border_rel + cfg.rect_margin_rel) * (
            (right - left) / face_frac if cand.extended else size)
        bottom = cand.y + cand.h if low is None else oy + low - qb + out
        cand.x, cand.w = ox + left - out, right - left + 2 * out
        if top is not None:
            cand.y = oy + top + qs - out
        else:
            # the orange part's top as its hull's, moved out like the sides (not a
            # diamond fit's box: the part may have been taken for one)
            cand.y = y0 + by0 - out
        cand.h = bottom - cand.y
        # no further than the image (labels are the visible part's box)
        x_a, y_a = max(cand.x, 0.0), max(cand.y, 0.0)
        cand.w = min(cand.x + cand.w, float(W)) - x_a
        cand.h = min(cand.y + cand.h, float(H)) - y_a
        cand.x, cand.y = x_a, y_a
        if cfg.pixel_boxes:
            cand.x, cand.y, cand.w, cand.h = pixel_box(cand.x, cand.y, cand.w, cand.h)
