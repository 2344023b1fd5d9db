"""False-positive filters and shape tests of an orange blob.

A patch of a larger sign-coloured surface (:meth:`FilterMixin._surround_like`), a cone or a
drum (white bands, :meth:`FilterMixin._banded`), and below the usual mounting height anything
but a clear diamond face (:meth:`FilterMixin._clear_diamond`); the rows of a portable stand's
flags are trimmed off a diamond first.
"""
from __future__ import annotations

import math
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.blob_kernels import masked_median_u8, surround_ring
from workzone_ros.core.color_model import apply_gains
from workzone_ros.core.detect.common import _convex_hull, _lookup
from workzone_ros.core.detect.diamond import fit_diamond
from workzone_ros.core.profiles import (
    banded_rows,
    open_background_rows,
    row_taper,
    white_cap,
)

__all__ = ['FilterMixin']


class FilterMixin:
    """The detector's false-positive filters and diamond trims."""

    def _sign_checks(self, bgr: np.ndarray, pix: np.ndarray, hull: np.ndarray,
                     like: np.ndarray, vch: np.ndarray, t: float, relaxed: bool,
                     org: tuple[int, int], blob: tuple
                     ) -> Optional[tuple[bool, Optional[tuple], np.ndarray, float,
                                         np.ndarray]]:
        """:meth:`_measure_orange`'s tests of an orange face (``pix``, its ``hull``, the
        window's likelihood ``like`` and value ``vch`` at ``org``; ``blob``: the hull's
        box in the window): mounting height, surroundings, legend, bands.  None: not a
        sign; else ``(needs_outline, pix_fit, hmask, v_ref, dark)``: kept only with its
        diamond edges measured, the diamond fit of ``pix`` when the mounting test made it,
        the hull mask, the face's median value and its dark pixels."""
        cfg = self.config
        x0, y0 = org
        bx0, by0, bw, bh = blob
        geo = self._geometry
        pix_fit = None              # fit_diamond(pix), when the mounting test needed it
        # no legend seen, or an unclear face below the usual mounting: kept only if its
        # diamond outline is measured in the brightness below (``outline_evidence``)
        needs_outline = False
        if geo is not None and self._ref_row is not None and not relaxed:
            # signs are mounted high: their bottom edge is above the prior's reference row
            # (drums, cones and vehicles stand on the road below it); in units of box height.
            # Below the usual mounting (soft limit; portable stands stand low) only a clear
            # diamond face passes; below the lowest training sign (hard limit) nothing does.
            rel = (y0 + by0 + bh - self._ref_row) / bh
            if self.debug is not None:
                self.debug[-1]['mount'] = rel
            if rel > geo[1]:
                return None
            if rel > geo[2]:
                if cfg.diamond_trim >= 0:
                    # the diamond test fits ``pix`` either way; the trim below reuses it
                    pix_fit = fit_diamond(pix)
                if not self._clear_diamond(pix, pix_fit):
                    if not (cfg.outline_evidence and cfg.diamond_refine):
                        return None
                    needs_outline = True      # a face behind a guardrail: its edges may tell
        hmask = np.zeros_like(pix)
        cv2.fillConvexPoly(hmask, hull, 1)
        v_ref = masked_median_u8(vch, pix)         # (np.median(vch[pix > 0]))
        if cfg.max_surround_like < 1.0 and not relaxed:
            # a sign is an object on its own: beyond its border the background is not the
            # sign's colour on average; a patch of a larger sign-coloured surface (dirt, a
            # brick wall, a vehicle's panel) is
            sl, sh = self._surround_like(hmask, like, max(bw, bh), t - 1e-6)
            if self.debug is not None:
                self.debug[-1].update(surround=sl, surround_face=sh)
            if sl > cfg.max_surround_like and sh > cfg.min_surround_face:
                return None
        dark = vch < cfg.dark_rel * v_ref
        if min(bw, bh) >= cfg.structure_min_px and not relaxed:
            inside = hmask > 0
            dfrac = np.count_nonzero(dark & inside) / max(np.count_nonzero(inside), 1)
            if self.debug is not None:
                self.debug[-1]['dark'] = dfrac
            if dfrac < cfg.min_dark_inside:
                if not (cfg.outline_evidence and cfg.diamond_refine):
                    return None
                else:
                    needs_outline = True
        if cfg.band_test and bh >= cfg.band_min_px and not relaxed:
            if self._banded(bgr, x0 + bx0, y0 + by0, bw, bh, pix, v_ref, t):
                if self.debug is not None:
                    self.debug[-1]['banded'] = True
                # a drum or cone (the fusion's channelizer evidence): one per place
                self.channelizers.add(((x0 + bx0 + bw // 2) // 16, (y0 + by0 + bh // 2) // 16))
                return None
        return needs_outline, pix_fit, hmask, v_ref, dark

    def _surround_like(self, hmask: np.ndarray, like: np.ndarray, size: int, level: float
                       ) -> tuple[float, float]:
        """(mean likelihood, share of pixels of likelihood >= ``level``) of the ring from
        ``surround_in`` to ``surround_out`` x ``size`` outside the blob's hull (beyond a
        sign's border and the blur of its edge); zeros when the ring is empty."""
        cfg = self.config
        r1 = max(1, int(round(cfg.surround_in * size)))
        r2 = max(r1 + 1, int(round(cfg.surround_out * size)))
        # the ring between two square dilations of the hull (compiled; the dilations' form is
        # in its test); the colour table's likelihood is float32 already
        return surround_ring(hmask, like.astype(np.float32, copy=False), r1, r2, level)

    def _banded(self, bgr: np.ndarray, bx: int, by: int, bw: int, bh: int, pix: np.ndarray,
                v_ref: float, t: float) -> bool:
        """:func:`banded_rows` (and the cone cap) on a strip over the blob's middle half of
        columns, reaching a blob height and two blends above and below it (a drum's stripes
        are as high as its orange ones).  Orange: likelihood at least ``t``; white: see
        ``band_test``, and not a row whose white runs on past both of the blob's sides
        (half its width either side: the background); dark relative to ``v_ref``."""
        cfg = self.config
        H, W = bgr.shape[:2]
        # the strip's columns: the middle half of the blob's (a cone's tip is narrow), with
        # flanks of half the blob's width either side
        q = max(1, bw // 4)
        c0, c1 = max(0, bx + q), min(W, bx + bw - q)
        f0, f1 = max(0, bx - bw // 2), min(W, bx + bw + bw // 2)
        gap = max(2, int(round(0.15 * bh)))
        reach = bh + 2 * gap + 2             # a band as high as the blob, blend either side
        r0, r1 = max(0, by - reach), min(H, by + bh + reach)
        if c1 <= c0 or r1 <= r0:
            return False
        wide = bgr[r0:r1, f0:f1]
        if self._gains is not None:
            wide = apply_gains(wide, self._gains)
        # one conversion of the flanked window; the strip is a view of it
        whsv = cv2.cvtColor(wide, cv2.COLOR_BGR2HSV)
        wluma = cv2.cvtColor(wide, cv2.COLOR_BGR2GRAY)
        hsv = whsv[:, c0 - f0:c1 - f0]
        i = self._idx['orange']
        like = _lookup(self.model.luts[i], hsv[..., 0], self._sat(hsv))
        v = hsv[..., 2]
        # the orange beyond a band (a cone's tip) at the blob's own threshold
        orange = (like >= t - 1e-6) & (v >= self.model.v_min[i])
        # white sheeting reflects every channel: brighter (luma) than the orange face under
        # the same light, where a legend or a grey patch lifted by rain or fog is not
        luma = wluma[:, c0 - f0:c1 - f0]
        face = orange[by - r0:by + bh - r0]
        if not face.any():
            return False
        y_ref = masked_median_u8(luma[by - r0:by + bh - r0], face)
        white = (hsv[..., 1] <= cfg.white_s_max) & (luma >= cfg.band_white_luma * y_ref)
        # a band is the object's own: bounded by its silhouette; white that runs on past
        # the blob's sides on both flanks is the background (an overcast sky, snow, a
        # wall), e.g. above a sign's top corner, below its portable stand's flags
        wwhite = (whsv[..., 1] <= cfg.white_s_max) & (wluma >= cfg.band_white_luma * y_ref)
        lf, rf = wwhite[:, :max(0, bx - f0)], wwhite[:, min(f1, bx + bw) - f0:]
        open_rows = open_background_rows(lf, rf, max(1, bw // 4))
        if open_rows is not None:
            white = white & ~open_rows[:, None]
        dark = v < cfg.dark_rel * v_ref
        # MUTCD bands: a cone's narrower band (4 in.) is about a quarter of the orange part
        # below it with the base (less the blend of its two edges when small), a drum's
        # stripes are as high as its orange ones; a sign's white outline or margin is a few
        # per cent of its size
        run = max(2, int(round(cfg.band_min_rows * bh)))
        # the orange beyond: a cone's tip is thin and blurred, half a band's rows will do
        beyond = max(3, int(round(0.1 * bh)))
        if banded_rows(orange, white, dark, by - r0, by + bh - r0, run, gap, bh + gap, beyond):
            return True
        # a cone whose tip is white or lost: a white band right over a blob that is taller
        # than wide and widens downward (a diamond is symmetric; a diamond's top half alone
        # is twice as wide as high)
        return (bh >= bw and row_taper(pix) <= cfg.cone_taper
                and white_cap(white, by - r0, run, gap))

    def _clear_diamond(self, pix: np.ndarray, row_fit: Optional[tuple] = None) -> bool:
        """Whether a blob is a clear diamond face, what may stand below the usual mounting
        height (a portable stand's sign): about square, diamond-filled, its rows and
        columns each a two-sided tent (:func:`fit_diamond`; its corners about the blob's
        middle: a triangle's rows follow a one-sided tent, its apex at the base), and solid
        (``low_min_solidity``) or following the tents on ``low_min_inliers`` of its rows and
        columns (a large black symbol, a lane-shift arrow, cuts the orange face but not its
        outline).  A blob whose rows beyond the fitted diamond's corners (a stand's flags)
        spoil this is judged without them.  ``row_fit``: :func:`fit_diamond` of ``pix``
        when already known."""
        cfg = self.config
        for k in range(2):
            if k == 1:
                if cfg.diamond_trim < 0:
                    return False
                pix, _ = self._trim_to_diamond(pix, cfg.diamond_trim, row_fit)
                if pix is None:
                    return False
                row_fit = None
            count = cv2.countNonZero(pix)
            if count < 5:
                return False
            hull = _convex_hull(pix)
            hull_area = max(float(cv2.contourArea(hull)), 1.0)
            # the hull's box is the pixels' box
            x, y, w, h = cv2.boundingRect(hull)
            solidity, fill = count / hull_area, hull_area / (w * h)
            if fill >= cfg.diamond_hull_fill or max(w / h, h / w) > cfg.low_max_aspect:
                continue
            fr = row_fit if row_fit is not None else fit_diamond(pix)
            fc = fit_diamond(np.ascontiguousarray(pix.T))
            if fr is None or fc is None:
                continue
            centred = (abs(fr[1] - (y + 0.5 * h)) <= 0.15 * h
                       and abs(fc[1] - (x + 0.5 * w)) <= 0.15 * w)
            if centred and (solidity >= cfg.low_min_solidity
                            or min(fr[4], fc[4]) >= cfg.low_min_inliers):
                return True
        return False

    @staticmethod
    def _trim_to_diamond(pix: np.ndarray, tol: float, row_fit: Optional[tuple] = None
                         ) -> tuple[Optional[np.ndarray], Optional[tuple]]:
        """(``pix`` without the rows beyond the fitted diamond's corners, or None when none
        are; :func:`fit_diamond`'s row fit of ``pix``).

        Rows further than ``0.5 + tol x b`` px above the top corner or below the bottom
        corner of :func:`fit_diamond`'s diamond are dropped (the margin keeps a corner that
        the fit's noisy slope put a little short).  ``row_fit``: :func:`fit_diamond` of
        ``pix`` when already known.
        """
        fd = row_fit if row_fit is not None else fit_diamond(pix)
        if fd is None:
            return None, fd
        _, cy, _, b, inl = fd
        if inl < 0.5:
            return None, fd
        margin = 0.5 + tol * b
        lo, hi = int(math.floor(cy - b - margin)), int(math.ceil(cy + b + margin))
        rows = np.nonzero(pix.any(axis=1))[0]
        if rows.size == 0 or (rows[0] >= lo and rows[-1] < hi):
            return None, fd
        out = pix.copy()
        out[:max(lo, 0)] = 0
        out[max(hi, 0):] = 0
        if np.count_nonzero(out) < 0.5 * np.count_nonzero(pix):
            return None, fd
        return out, fd
