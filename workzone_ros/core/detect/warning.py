"""A warning sign's diamond measured in its blob's window.

Starts from the mask's diamond are refined on the brightness (:func:`.diamond.refine_diamond`);
the outline must hold the blob's orange; an occluder across the lower part is found and the
face measured above it; when no start refines, the blurred chroma is fitted
(:mod:`.diamond_search`); the result is clamped and boxed in whole pixels.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from workzone_ros.core.blob_kernels import masked_median_u8
from workzone_ros.core.color_model import _quantile
from workzone_ros.core.detect.common import _padded
from workzone_ros.core.detect.diamond import (
    diamond_pixel_box,
    fit_diamond,
    fit_diamond_2d,
    frame_edges,
    refine_diamond,
    refine_shifted,
)
from workzone_ros.core.detect.diamond_search import (
    diamond_holds,
    fit_blurred_diamond,
)
from workzone_ros.core.detect.edges import EDGE_MIN_CONTRAST
from workzone_ros.core.profiles import row_extents

__all__ = ['WarningMixin']


class WarningMixin:
    """The detector's warning-diamond steps."""

    def _warning_outline(self, bgr: np.ndarray, hsv: np.ndarray, face_px: np.ndarray,
                         row_fit: Optional[tuple], window: tuple, blob: tuple,
                         needs_outline: bool, grow: float, refine: bool
                         ) -> tuple[Optional[tuple], Optional[tuple], Optional[tuple]]:
        """:meth:`_measure_orange`'s warning box: ``(outer, sub, blurred)``, the sign's box
        in the frame (None: none measured), the face refined on the brightness and the
        chroma fit's diamond (each None when not found).  ``window``: the blob's window
        ``(x0, y0, x1, y1)``; ``blob``: its hull box there ``(bx0, by0, bw, bh)``;
        ``face_px``: its face pixels."""
        cfg = self.config
        x0, y0, x1, y1 = window
        bx0, by0, bw, bh = blob
        outer = None
        # the box of the diamond fitted to the face (its corners extrapolated from the
        # straight edges), scaled out by the border; never further out than
        # ``diamond_clamp`` x the half-diagonal beyond the face seen (an occluded or
        # cut-off corner is not invented)
        if row_fit is None:
            row_fit = fit_diamond(face_px)
        fd = fit_diamond_2d(face_px, rows=row_fit)
        # an occluder across the face's lower part (a guardrail in front of a sign on
        # a stand): its edges are measured above it, from the rows' own diamond
        cut_row = self._cut_row(face_px, row_fit)
        sub, blurred, larger, cut_row = self._face_fit(
            bgr, hsv, face_px, fd, row_fit, cut_row, window, blob, needs_outline, refine)
        if self.debug is not None:
            self.debug[-1].update(refined=sub is not None,
                                  blur_fit=blurred is not None,
                                  cut=None if cut_row is None else y0 + cut_row)
        diamond = None
        if sub is not None:
            # the face's edges from the brightness profile; the sign is the face
            # scaled by the art's ratio (border line and margin outside the face);
            # the clamp allows a pixel more (blur eats about a pixel of a small face)
            diamond = (*sub, cfg.diamond_face_ratio, cfg.diamond_clamp_px)
        elif blurred is not None:
            diamond = (*blurred, cfg.blur_fit_ratio, cfg.diamond_clamp_px)
        elif fd is not None and fd[4] >= 0.5:
            k_ = cfg.diamond_scale
            if cfg.border_frac <= 0:
                k_ = 1.0                    # configured: no border outside the face
            elif grow <= 0:
                k_ = 1.0
            diamond = (*fd[:4], k_, 0.0)
        if diamond is not None:
            cut = cut_row is not None and sub is not None
            box_ = self._diamond_box(diamond, sub is not None or blurred is not None,
                                     (bx0, by0, bw, bh), larger, cut,
                                     self._box_bias(sub))
            if box_ is not None:
                outer = (x0 + box_[0], y0 + box_[1], box_[2], box_[3])
        return outer, sub, blurred

    def _face_fit(self, bgr: np.ndarray, hsv: np.ndarray, face_px: np.ndarray,
                  fd: Optional[tuple], row_fit: Optional[tuple], cut_row: Optional[int],
                  window: tuple, blob: tuple, needs_outline: bool, refine: bool,
                  ) -> tuple:
        """The warning face measured: from the mask's starts refined on the brightness,
        else the chroma fit, else the starts moved.  Returns ``(sub, blurred, larger,
        cut_row)``: the refined face (None: none), the chroma fit's diamond (None: none),
        whether the blob is larger than the sign, and the occluder's cut row the face was
        measured above (None: none)."""
        cfg = self.config
        x0, y0, x1, y1 = window
        bx0, by0, bw, bh = blob
        larger = False
        sub = None
        if refine:
            # the brightness a few pixels beyond the blob's window (a mask fit that is
            # too large puts the edge's outer samples outside it)
            value, ox, oy = self._diamond_value(bgr, (x0, y0, x1, y1), bw, bh)
            dx, dy = x0 - ox, y0 - oy
            # start from the mask's diamond, else from the diamond in the hull's box (a
            # big symbol that cuts the face leaves the mask's corners far off), else
            # from the rows' own diamond (a rail or a car across the face's lower part
            # cuts its columns, which the mask's diamond takes its height from)
            starts = [fd[:4]] if fd is not None and fd[4] >= 0.5 else []
            starts.append((bx0 + 0.5 * bw, by0 + 0.5 * bh, 0.5 * bw, 0.5 * bh))
            if row_fit is not None and row_fit[4] >= 0.5:
                starts.append(row_fit[:4])
            # else from the hull's box grown (a faded or rain-washed face whose mask
            # covers less than the face); such a fit on a whole blob
            # needs a clear line (``search_min_contrast``: the sign's outer edge
            # against a dark background is no face's edge against its line)
            n_mask = len(starts)
            starts += [(bx0 + 0.5 * bw, by0 + 0.5 * bh, 0.5 * g * bw, 0.5 * g * bh)
                       for g in cfg.diamond_grown_starts]
            # above a cut: first from the rows' diamond (the others take the face's
            # height from its cut columns), then as without one (a tip thinned by blur
            # looks cut too; its lower edges are then measured all the same)
            passes = [(None, list(enumerate(starts)))]
            if cut_row is not None:         # (a cut is found on a row fit only)
                passes.insert(0, (cut_row + dy, [(n_mask - 1, starts[n_mask - 1])] + [
                    (i_, st) for i_, st in enumerate(starts) if i_ != n_mask - 1]))
            for hidden, order in passes:
                for i_, st in order:
                    mc_ = EDGE_MIN_CONTRAST if i_ < n_mask else cfg.search_min_contrast
                    sub = self._refine(value, (st[0] + dx, st[1] + dy, st[2], st[3]),
                                       mc_, hidden)
                    if sub is not None:
                        sub, held = self._held(bgr, hsv, face_px, sub, dx, dy,
                                               (x0, y0, x1, y1), bw, bh)
                        if sub is not None:
                            larger = held == 'blended'
                            break
                if sub is not None:
                    break
                cut_row = None
        blurred = None
        if sub is None and refine and cfg.blur_fit and not needs_outline \
                and self._spend('blur_fit'):
            # no line to measure: the sign's blurred colour
            blurred = self._blur_fit(bgr, (x0, y0, x1, y1), (bx0, by0, bw, bh),
                                     fd if fd is not None and fd[4] >= 0.5 else None)
        if sub is None and blurred is None and refine and \
                0 < cfg.shift_min_px <= min(bw, bh) and self._spend('shifted'):
            # nothing measured: a large face whose mask's starts are a few pixels off
            # (the mask took in a surface of its colour beside it)
            held_args = (bgr, hsv, face_px, dx, dy, (x0, y0, x1, y1), bw, bh)
            got = refine_shifted(
                [(st[0] + dx, st[1] + dy, st[2], st[3]) for st in starts[:n_mask]],
                lambda st: self._refine(value, st),
                lambda f: self._held_reaching(f, held_args, (x0 + bx0, y0 + by0)))
            if got is not None:
                sub, larger = got[0], got[1] == 'blended'
        return sub, blurred, larger, cut_row

    def _diamond_value(self, bgr: np.ndarray, window: tuple, bw: int, bh: int
                       ) -> tuple[np.ndarray, int, int]:
        """The brightness (:meth:`_value`, luma with ``diamond_luma``) a few pixels beyond
        the blob's window ``(x0, y0, x1, y1)`` (a quarter of the blob's size, + 3 px: a mask
        fit that is too large puts an edge's outer samples outside the window)."""
        return self._value(bgr, *_padded(window, bw, bh), self.config.diamond_luma)

    def _diamond_box(self, diamond: tuple, refined: bool, blob: tuple, larger: bool,
                     cut: bool = False, bias: float = 0.0) -> Optional[tuple]:
        """The sign's box ``(x, y, w, h)`` in the blob's window from ``diamond = (cx, cy, a,
        b, scale, pad)`` (the face and the sign / face ratio): no side further out than the
        clamp (``diamond_clamp``, ``refined_clamp`` for a refined face, x the
        half-diagonal, + ``pad``) beyond the blob's box ``blob``; a
        refined outline in whole pixels (``pixel_boxes``).  None when far from the blob's
        own box (it may be ``larger`` than the sign when it took in a surface or a blended
        rim beyond it: a face :meth:`_holds` calls blended).  ``cut``: the
        outline was measured above an occluder across the face's lower part; its bottom
        is not clamped (a guardrail in front of a sign on a stand hides a band of the face,
        and the labels, which are the visible pixels' box, take in the tip below it).
        ``bias``: the face's half-diagonals less this (px) for the box only
        (``diamond_box_bias``, the operating point; the checks before took the face as
        measured)."""
        cfg = self.config
        bx0, by0, bw, bh = blob
        cx_, cy_, a_, b_, k_, pad = diamond
        a_, b_ = a_ - bias, b_ - bias
        if refined and not cut and abs(a_ - b_) * 2 * k_ <= cfg.diamond_square_px and \
                (a_ + b_) * k_ < cfg.diamond_square_max:
            # a far sign seen about face on: its width and height are one measurement
            a_ = b_ = 0.5 * (a_ + b_)
        cl_ = cfg.diamond_clamp
        if refined:
            # a refined outline is the sign's from its own edges: a hidden tip (a guardrail
            # across the lower corner) is extrapolated further
            cl_ = max(cl_, cfg.refined_clamp)
        ca, cb = cl_ * a_ + pad, cl_ * b_ + pad
        if refined and cfg.pixel_boxes:
            # whole pixels, as box labels are drawn (the window's origin is a whole pixel)
            l_, t_, r_, u_ = diamond_pixel_box(cx_, cy_, k_ * a_, k_ * b_)
            l_, t_ = max(l_, round(bx0 - ca)), max(t_, round(by0 - cb))
            r_ = min(r_, round(bx0 + bw + ca))
            if not cut:
                u_ = min(u_, round(by0 + bh + cb))
        else:
            l_ = max(cx_ - k_ * a_, bx0 - ca)
            r_ = min(cx_ + k_ * a_, bx0 + bw + ca)
            t_ = max(cy_ - k_ * b_, by0 - cb)
            u_ = cy_ + k_ * b_ if cut else min(cy_ + k_ * b_, by0 + bh + cb)
        lo_ = 0.0 if larger else 0.8
        if lo_ * bw <= r_ - l_ <= 1.5 * bw + 2 and lo_ * bh <= u_ - t_ <= 1.5 * bh + 2:
            return l_, t_, r_ - l_, u_ - t_
        return None

    def _box_bias(self, face: Optional[Sequence[float]]) -> float:
        """``diamond_box_bias`` for a face :meth:`_refine` measured on sharp edges this
        frame, else 0: heavily blurred faces have their own bias (``diamond_blur_bias``),
        and there 0.15 px more cost winter signs 0.01 of recall for 0.003 of precision on
        40 held-out renders (sunny gained 0.006 of precision)."""
        if face is None or (float(face[2]), float(face[3])) not in self._sharp_faces:
            return 0.0
        return self.config.diamond_box_bias

    def _held_reaching(self, sub: Sequence[float], held_args: tuple, blob_xy: tuple
                       ) -> tuple[Optional[tuple], Optional[str]]:
        """:meth:`_held` (``held_args``: its arguments but ``sub``) of a fit from a moved
        start (:func:`refine_shifted`); of a blob (its box's corner ``blob_xy`` in the frame)
        the frame's edge cuts, only when the sign's diamond reaches past each edge the blob
        touches (a smaller whole diamond inside the frame fits part of the sign)."""
        bgr, hsv, face_px, dx, dy, window, bw, bh = held_args
        got = self._held(bgr, hsv, face_px, sub, dx, dy, window, bw, bh)
        if got[0] is None:
            return got
        x0, y0 = window[0], window[1]
        H, W = bgr.shape[:2]
        cut = frame_edges(blob_xy[0], blob_xy[1], bw, bh, W, H)
        if not any(cut):
            return got
        cx, cy, a, b = got[0]
        k = self.config.diamond_face_ratio
        reach = frame_edges(x0 + cx - k * a, y0 + cy - k * b, 2 * k * a, 2 * k * b, W, H, 1.0)
        return got if all(r for c, r in zip(cut, reach) if c) else (None, None)

    def _held(self, bgr: np.ndarray, hsv: np.ndarray, face_px: np.ndarray,
              sub: Sequence[float], dx: float, dy: float, window: tuple, bw: int, bh: int
              ) -> tuple[Optional[tuple], Optional[str]]:
        """A refined face ``sub`` (brightness window offset by ``dx, dy``) moved to the
        blob's window, and :meth:`_holds`'s verdict; ``(None, None)`` when the catalogue's
        outline does not hold the sign's orange pixels (a sign whose border line lies
        further in, a wider margin, is not measured so) or the mask stops short of a faded
        sign and so does this outline (:meth:`_inside_sign`).  ``'blended'``: the blob took
        in a blended rim and is larger than the sign."""
        sub = (sub[0] - dx, sub[1] - dy, sub[2], sub[3])
        held = self._holds(hsv, face_px, sub)
        if held == 'holds' and self._inside_sign(bgr, window, sub, bw, bh):
            held = None
        return (sub, held) if held else (None, None)

    def _holds(self, hsv: np.ndarray, face_px: np.ndarray, sub: Sequence[float]
               ) -> Optional[str]:
        """Whether the refined face ``sub`` (the blob's window) is the sign's.

        Yes when the catalogue's outline holds the blob's orange (:func:`diamond_holds`).
        Otherwise the orange it leaves out must be a background blended into, or merged
        with, the blob's edge (a dusk sky, rain haze; 5-30 % of a blob's pixels beyond a
        correct outline on tuning renders), not the face's own orange: fewer than half of
        the blob's pixels beyond the outline, and fewer than half of the ring half a pixel
        to a pixel and a half beyond it on each of the four sides, are as saturated as
        ``hold_sat`` x the face's median and not dark.  A fit on a line further in than the
        catalogue's (a wider margin, a symbol's edge) leaves the face's orange out.  Returns
        ``'holds'``, ``'blended'`` (the blob is larger than the sign) or None."""
        cfg = self.config
        k = cfg.diamond_face_ratio
        if diamond_holds(face_px, sub, k, cfg.diamond_hold):
            return 'holds'
        if cfg.hold_sat <= 0:
            return None
        cx, cy, a, b = (float(v) for v in sub[:4])
        h, w = face_px.shape
        ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]      # (broadcast: np.mgrid's)
        rel = np.abs(xs + 0.5 - cx) / a + np.abs(ys + 0.5 - cy) / b
        dist = (rel - k) * (a * b / math.hypot(a, b))      # px beyond the outline
        ring = (dist >= 0.5) & (dist <= 1.5)
        inside = (face_px > 0) & (rel <= 0.9)               # the face's own orange
        if not ring.any() or not inside.any():
            return None
        sat, val = hsv[..., 1], hsv[..., 2]
        # the face's own orange: as saturated and not dark (a legend stroke is neither)
        face_like = (sat >= cfg.hold_sat * masked_median_u8(sat, inside)) & (
            val >= cfg.dark_rel * masked_median_u8(val, inside))
        # the blob's pixels beyond the outline: a background blended in or merged with the
        # sign is not the face's orange; a fit inside a larger face leaves that face out
        beyond = (face_px > 0) & (dist >= 0.5)
        if np.count_nonzero(face_like & beyond) >= 0.5 * max(np.count_nonzero(beyond), 1):
            return None
        # and on every side the ring just beyond the outline is not the face's orange
        for right in (False, True):
            for low in (False, True):
                side = ring & ((xs + 0.5 > cx) == right) & ((ys + 0.5 > cy) == low)
                if np.count_nonzero(face_like & side) >= 0.5 * max(np.count_nonzero(side), 1):
                    return None
        return 'blended'

    def _cut_row(self, face: np.ndarray, row_fit: Optional[tuple]) -> Optional[int]:
        """The row where an occluder across a warning face's lower part begins, or None.

        The face's rows fit a diamond (:func:`fit_diamond`, ``row_fit``) whose bottom corner
        lies at least ``max(2, 0.15 b)`` px below the face's last row, and one of its last
        three rows, below the diamond's middle, is at least ``cut_min_width`` x as wide as
        the diamond there (the rows after it blend into the occluder): a straight
        horizontal cut, not a tip thinned by blur.  The cut is the row after that one."""
        frac = self.config.cut_min_width
        if frac <= 0 or row_fit is None or row_fit[4] < 0.5:
            return None
        cx, cy, a, b = row_fit[:4]
        yc, left, right = row_extents(face)
        if yc.size < 3 or yc[-1] + 0.5 > cy + b - max(2.0, 0.15 * b):
            return None
        for k in range(yc.size - 1, yc.size - 4, -1):
            if yc[k] <= cy:
                break
            if right[k] - left[k] >= frac * 2 * a * (1 - (yc[k] - cy) / b):
                return int(yc[k] + 0.5)
        return None

    def _refine(self, value: np.ndarray, start: Sequence[float],
                min_contrast: float = EDGE_MIN_CONTRAST, hidden: Optional[float] = None
                ) -> Optional[tuple[float, float, float, float]]:
        """:func:`refine_diamond` with this detector's settings; the face's half-diagonals
        less ``diamond_edge_bias`` (a blurred border line puts the measured edge that far
        out, whatever the sign's size), or less ``diamond_blur_bias`` when the edges' fitted
        blur is ``diamond_blur_sigma`` px or more; the height at most ``diamond_tall_max`` x
        the width and the width at most ``diamond_wide_max`` x the height; the edge stretches a
        stroke runs into are left out (``diamond_stroke_steps``)."""
        cfg = self.config
        info: dict = {}
        sub = refine_diamond(value, start, cfg.diamond_border_rel, cfg.diamond_margin_rel,
                             cfg.diamond_max_change, min_contrast, info=info,
                             hidden_below=hidden,
                             stroke_steps=cfg.diamond_stroke_steps,
                             bright_bias=cfg.diamond_bright_bias)
        if sub is None:
            return None
        bias = cfg.diamond_edge_bias
        sharp = info.get('blur', 0.0) < cfg.diamond_blur_sigma
        if not sharp:
            bias = cfg.diamond_blur_bias          # heavily blurred edges (defocus, motion)
        a, b = self._plausible(sub[2] - bias, sub[3] - bias)
        if sharp:
            self._sharp_faces.add((a, b))
        return sub[0], sub[1], a, b

    def _plausible(self, a: float, b: float) -> tuple[float, float]:
        """Half-diagonals ``a, b`` of a measured face cut back to a plausible shape: a square
        sign facing the road is as tall as wide, taller when turned away
        (``diamond_tall_max``), wider only a little (``diamond_wide_max``)."""
        b = min(b, self.config.diamond_tall_max * a)
        return min(a, self.config.diamond_wide_max * b), b

    def _inside_sign(self, bgr: np.ndarray, window: tuple, sub: Sequence[float], bw: int,
                     bh: int) -> bool:
        """Whether the sign outline of the face ``sub`` (the blob's window ``(x0, y0, x1,
        y1)``) lies inside a sign that goes on: the chroma of the ring 0.5-1.5 px beyond it
        is on average more than ``rim_chroma`` of the way from the background's (3-6 px
        beyond) to the face's (its middle's upper quartile)."""
        cfg = self.config
        if cfg.rim_chroma <= 0:
            return False
        # a few pixels beyond the blob's window, as :meth:`_diamond_value`
        chroma, ox, oy = self._chroma(bgr, *_padded(window, bw, bh))
        cx, cy = sub[0] + window[0] - ox, sub[1] + window[1] - oy
        a, b = float(sub[2]), float(sub[3])
        k = cfg.diamond_face_ratio
        h, w = chroma.shape
        # a column and a row of coordinates, broadcast (np.mgrid's full grids hold the same
        # values on every row and column)
        ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]
        dx, dy = np.abs(xs + 0.5 - cx), np.abs(ys + 0.5 - cy)
        rel = dx / (k * a) + dy / (k * b)
        dist = (rel - 1.0) * (k * a * k * b / math.hypot(k * a, k * b))
        ring = (dist >= 0.5) & (dist <= 1.5)
        back = (dist >= 3.0) & (dist <= 6.0)
        middle = dx / a + dy / b < 0.6
        if not (ring.any() and back.any() and middle.any()):
            return False
        bg = float(np.median(chroma[back]))
        # (np.percentile(..., 75)'s value, without its generic machinery)
        face = float(_quantile(chroma[middle], 0.75))
        if face <= bg:
            return False
        return float(chroma[ring].mean()) - bg > cfg.rim_chroma * (face - bg)

    def _blur_fit(self, bgr: np.ndarray, window: tuple, blob: tuple, fd: Optional[tuple]
                  ) -> Optional[tuple[float, float, float, float]]:
        """The sign's diamond ``(cx, cy, a, b)`` (the blob's window ``(x0, y0, x1, y1)``) by
        :func:`fit_blurred_diamond` on the chroma R - B of the colour-balanced frame, from the
        mask's diamond ``fd`` or the blob's box ``blob``, less ``blur_fit_bias``; None when the
        blob touches the frame's edge, the fit fails, its centre lies outside the blob's box
        or the sign would be smaller than the blob's box by more than a pixel a side."""
        cfg = self.config
        x0, y0, x1, y1 = window
        bx, by, bw, bh = blob
        pad = 3 + int(0.3 * max(bw, bh))
        H, W = bgr.shape[:2]
        if any(frame_edges(x0 + bx, y0 + by, bw, bh, W, H, 1.0)):
            return None             # cut off by the frame's edge: no whole diamond to fit
        chroma, wx0, wy0 = self._chroma(bgr, x0 + bx - pad, y0 + by - pad,
                                        x0 + bx + bw + pad, y0 + by + bh + pad)
        dx, dy = x0 - wx0, y0 - wy0
        if fd is not None:
            start = (fd[0] + dx, fd[1] + dy, fd[2], fd[3])
        else:
            start = (bx + 0.5 * bw + dx, by + 0.5 * bh + dy, 0.5 * bw, 0.5 * bh)
        fit = fit_blurred_diamond(chroma, start, cfg.blur_fit_max_sigma)
        if fit is None:
            return None
        cx, cy = fit[0] - dx, fit[1] - dy
        bias = cfg.blur_fit_bias / cfg.blur_fit_ratio
        a, b = fit[2] - bias, fit[3] - bias
        # the sign holds its own orange: a fit on an edge inside the mask (a line further
        # in than the catalogue's, the orange margin outside it left out) is no sign's
        k = cfg.blur_fit_ratio
        if not (bx <= cx <= bx + bw and by <= cy <= by + bh
                and 2 * k * a >= bw - 2 and 2 * k * b >= bh - 2):
            return None
        return (cx, cy, *self._plausible(a, b))      # the shape limits of a refined face
