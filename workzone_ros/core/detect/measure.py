"""The sign measurement: one orange blob to a filtered, boxed candidate.

At full resolution: the face region (hysteresis into weak pixels, a closing over the border
line and legend), its shape (solidity, hull fill, aspect), the false-positive filters
(:mod:`.filters`), the kind (diamond or rectangle), then the box: a warning diamond's from its
edges (:mod:`.warning`), a regulatory rectangle's from its edges and white part
(:mod:`.rectangle`, :mod:`.plaque`), else the hull grown by its own border profile.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.blob_kernels import blur_rings
from workzone_ros.core.color_model import apply_gains
from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.detect.common import (
    _P_SCALE,
    _convex_hull,
    _mode,
    _paste,
)
from workzone_ros.core.detect.mask import _clipped_growth
from workzone_ros.core.kernels import components_with_stats

__all__ = ['MeasureMixin']

@dataclass
class _Face:
    """An orange blob's face measured at full resolution (:meth:`MeasureMixin._face_region`)."""

    window: tuple               # (x0, y0, x1, y1): the measuring window in the frame
    margin: int                 # the window's margin around the blob's box (px)
    raw: np.ndarray             # the window as the camera gave it (BGR)
    hsv: np.ndarray             # the window colour-balanced, in HSV
    like: np.ndarray            # the orange likelihood of its pixels
    t: float                    # the blob's likelihood threshold
    blur_t: float               # the blur rings' likelihood level
    region: np.ndarray          # the face region (boolean: the orange and its legend)
    pix: np.ndarray             # the face's orange pixels (uint8)
    area: float                 # their count
    hull: np.ndarray            # their convex hull
    box: tuple                  # (bx0, by0, bw, bh): the hull's box in the window
    hull_fill: float            # hull area / box area
    solidity: float             # area / hull area


class MeasureMixin:
    """The detector's orange measurement."""

    def _measure_orange(self, bgr: np.ndarray, comp: np.ndarray, box: tuple, s: int,
                        thr_base: np.ndarray, lboxes: list, relaxed: bool = False,
                        t_override: Optional[float] = None, t_scale: float = 1.0
                        ) -> Optional[Candidate]:
        """The learned orange path: hysteresis region, sign structure, shape-derived box.

        1. At full resolution, pixels with likelihood >= tau (the posterior threshold of the
           blob's location) near the blob are the face; pixels >= ``weak_threshold`` next to
           them join (hysteresis); a closing bridges the thin black border line.
        2. Structure: solidity (pixels / hull area), hull fill (diamond ~0.5, rectangle ~1),
           aspect, and for blobs of ``structure_min_px`` or more a dark legend or border
           inside the hull.
        3. Box: the orange hull's bounding box; if the ring just outside it is dark (the
           sign's black border, with the thin outer orange margin lost to blending), the
           box grows by ``border_frac`` of the hull's size on every side.

        ``t_scale``: tau at this share of the location's (a blob grown to a lower level,
        :meth:`_grown`).
        """
        face = self._face_region(bgr, comp, box, s, thr_base, relaxed, t_override, t_scale)
        if face is None:
            return None
        cfg = self.config
        x0, y0, x1, y1 = face.window
        bx0, by0, bw, bh = face.box
        raw, hsv, like, t, m = face.raw, face.hsv, face.like, face.t, face.margin
        pix, area, hull, hull_fill = face.pix, face.area, face.hull, face.hull_fill
        solidity, aspect = face.solidity, bw / bh
        # a LiDAR-supported blob needs less colour evidence: looser shape filters, no legend
        # test and no mounting-height test (the LiDAR found a flat retro-reflective panel)
        relax = cfg.roi_relax if relaxed else 1.0
        if (hull_fill < relax * cfg.min_hull_fill or solidity < relax * cfg.min_solidity
                or max(aspect, 1 / aspect) > cfg.max_aspect / relax):
            return None
        checked = self._sign_checks(bgr, pix, hull, like, hsv[..., 2], t, relaxed, (x0, y0),
                                    (bx0, by0, bw, bh))
        if checked is None:
            return None
        needs_outline, pix_fit, hmask, v_ref, dark = checked
        row_fit, trimmed = self._diamond_trim(pix, like, pix_fit, aspect)
        if trimmed is not None:
            pix, like, hmask, (bx0, by0, bw, bh), hull_fill = trimmed
            aspect = bw / bh
        # diamonds are about square; a wide blob is a rectangle (or the orange top of one)
        kind = ('warning' if hull_fill < cfg.diamond_hull_fill
                and max(aspect, 1 / aspect) < cfg.ext_min_aspect else 'regulatory')
        if needs_outline and kind != 'warning':
            return None
        conf = _mode(like[pix > 0])
        grow, feats = self._border_growth(hmask, dark, like, min(bw, bh), face.blur_t)
        if self.debug is not None:
            self.debug[-1].update(hull_box=(x0 + bx0, y0 + by0, bw, bh), vref=v_ref,
                                  relaxed=relaxed, **feats)
        cand = Candidate(x0 + bx0, y0 + by0, bw, bh, 'orange', conf, kind, area, hull_fill)
        if not self._place_box(bgr, hsv, cand, kind, pix, row_fit, (x0, y0, x1, y1),
                               (bx0, by0, bw, bh), needs_outline, grow, feats):
            return None
        return self._regulatory_box(bgr, raw, pix, hsv, v_ref, cand, kind, aspect, relaxed,
                                    (x0, y0, x1, y1), (bx0, by0, bw, bh), m)

    def _diamond_trim(self, pix: np.ndarray, like: np.ndarray, pix_fit: Optional[tuple],
                      aspect: float) -> tuple[Optional[tuple], Optional[tuple]]:
        """:meth:`_measure_orange`'s face without the rows beyond a fitted diamond's corners:
        ``(row_fit, trimmed)``, ``trimmed`` None (and ``row_fit`` the diamond's row fit of
        ``pix``) when no rows are cut, else ``(pix, like, hmask, box, hull_fill)`` of the
        trimmed face (``box``: its hull's ``(bx0, by0, bw, bh)``) and ``row_fit`` None;
        ``(None, None)`` when ``diamond_trim`` is off or the blob (``aspect``) is too wide."""
        cfg = self.config
        if not (cfg.diamond_trim >= 0 and aspect < cfg.ext_min_aspect):
            return None, None
        # rows beyond a fitted diamond's corners are not the face (a portable stand's
        # orange flags above the top corner): shape, kind and box go without them
        trimmed, row_fit = self._trim_to_diamond(pix, cfg.diamond_trim, pix_fit)
        if trimmed is None:
            return row_fit, None
        # the cut-off part must not come back as the border's blur rings
        cut = (pix > 0) & (trimmed == 0)
        like = np.where(cut, np.float32(0), like)
        hull = _convex_hull(trimmed)
        bx0, by0, bw, bh = (int(v) for v in cv2.boundingRect(hull))
        hmask = np.zeros_like(trimmed)
        cv2.fillConvexPoly(hmask, hull, 1)
        hull_fill = max(float(cv2.contourArea(hull)), 1.0) / (bw * bh)
        return None, (trimmed, like, hmask, (bx0, by0, bw, bh), hull_fill)

    def _place_box(self, bgr: np.ndarray, hsv: np.ndarray, cand: Candidate, kind: str,
                   face_px: np.ndarray, row_fit: Optional[tuple], window: tuple, blob: tuple,
                   needs_outline: bool, grow: float, feats: dict) -> bool:
        """:meth:`_measure_orange`'s box of ``cand`` (in place): a warning diamond's outline
        (:meth:`_warning_outline`), else the hull ``blob`` grown by ``grow`` and the blur
        rings, then scaled by ``border_scale``.  False when the blob needs an outline and
        has no diamond edges (a patch of a sign-coloured surface)."""
        cfg = self.config
        bw, bh = blob[2], blob[3]
        outer = sub = None
        refine = cfg.diamond_refine and cfg.border_frac > 0 and cfg.diamond_scale > 0
        blurred = None
        if kind == 'warning' and cfg.diamond_scale > 0:
            outer, sub, blurred = self._warning_outline(
                bgr, hsv, face_px, row_fit, window, blob, needs_outline, grow, refine)
        if outer is not None:
            cand.x, cand.y, cand.w, cand.h = outer
            cand.refined = kind == 'warning' and (sub is not None or blurred is not None)
            cand.chroma_fit = cand.refined and sub is None
        elif grow > 0:
            # the border's share of each side, plus the blur rings (px, the same on every
            # side: as a share of the shorter side they grew a wide blob's width by its
            # aspect times the blur)
            b_px = float(feats['blur']) if cfg.blur_px_growth else 0.0
            g_ = grow - b_px / float(min(bw, bh))
            gx, gy = g_ * bw + b_px, g_ * bh + b_px
            cand.x, cand.y = cand.x - gx, cand.y - gy
            cand.w, cand.h = bw + 2 * gx, bh + 2 * gy
        if needs_outline and not (outer is not None and sub is not None):
            # no legend and no diamond edges: a patch of a sign-coloured surface
            return False
        sx, sy = cfg.border_scale
        if sx != 1.0 or sy != 1.0:
            cand.x -= 0.5 * (sx - 1.0) * cand.w
            cand.y -= 0.5 * (sy - 1.0) * cand.h
            cand.w, cand.h = sx * cand.w, sy * cand.h
        return True

    def _regulatory_box(self, bgr: np.ndarray, raw: np.ndarray, pix: np.ndarray,
                        hsv: np.ndarray, v_ref: float, cand: Candidate, kind: str,
                        aspect: float, relaxed: bool, window: tuple, blob: tuple, m: int
                        ) -> Optional[Candidate]:
        """:meth:`_measure_orange`'s last step for a ``kind == 'regulatory'`` blob: the
        two-colour extension (:meth:`_extend`) and the rectangle box (:meth:`_rectangle_box`);
        ``cand``, or None when its rectangle fit failed and ``rect_needs_edges`` asks for
        one (an unextended, not LiDAR-supported ``regulatory`` candidate)."""
        cfg = self.config
        entry = self.debug[-1] if self.debug is not None else None
        if cfg.extension and kind == 'regulatory' and aspect >= cfg.ext_min_aspect:
            self._extend(bgr, cand, hsv[pix > 0])
        rect_failed = False
        if kind == 'regulatory' and cfg.rect_refine and cfg.border_frac > 0:
            if self._rectangle_box(bgr, raw, pix, v_ref, cand, entry, window, blob, m):
                return cand
            rect_failed = True
        if cfg.rect_needs_edges and rect_failed and cand.kind == 'regulatory' \
                and not cand.extended and not relaxed:
            return None
        return cand

    def _face_region(self, bgr: np.ndarray, comp: np.ndarray, box: tuple, s: int,
                     thr_base: np.ndarray, relaxed: bool, t_override: Optional[float],
                     t_scale: float) -> Optional[_Face]:
        """:meth:`_measure_orange`'s step 1: the blob's face at full resolution (its
        window, likelihood, threshold, region, orange pixels and hull), or None when no
        pixel passes the threshold or the face is too small."""
        cfg = self.config
        H, W = bgr.shape[:2]
        fx, fy, fw, fh = box
        m = 2 * s + 1 + int(0.2 * max(fw, fh))
        x0, y0 = max(0, fx - m), max(0, fy - m)
        x1, y1 = min(W, fx + fw + m), min(H, fy + fh + m)
        win = bgr[y0:y1, x0:x1]
        raw = win
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        like = self._orange_like(hsv)
        cy, cx = (fy + fh // 2) // s, (fx + fw // 2) // s
        cy, cx = min(cy, thr_base.shape[0] - 1), min(cx, thr_base.shape[1] - 1)
        t = t_scale * thr_base[cy, cx] / _P_SCALE
        if relaxed:
            t = min(t, cfg.roi_threshold / cfg.roi_prior)
        if t_override is not None:
            t = t_override
        region = np.zeros(win.shape[:2], np.uint8)
        up = cv2.resize(comp, (fw, fh), interpolation=cv2.INTER_NEAREST) if s > 1 else comp
        _paste(region, up, fy - y0, fx - x0)
        if s > 1:
            region = cv2.dilate(region, np.ones((2 * s + 1, 2 * s + 1), np.uint8))
        strong = ((like >= t - 1e-6) & (region > 0)).astype(np.uint8)
        if not strong.any():
            return None
        weak_t, blur_t = min(cfg.weak_threshold, t), cfg.blur_like
        weak = (like >= weak_t).astype(np.uint8) | strong
        size = max(fw, fh)
        k = max(3, int(round(cfg.close_frac * size)) | 1)
        kern = np.ones((k, k), np.uint8)
        # weak pixels near the blob join it; the closing bridges border and legend strokes
        # (the face as one region; its orange pixels are ``weak`` inside it)
        near = cv2.dilate(strong, kern) & weak
        if cfg.clip_grow > 0:
            near |= _clipped_growth(raw, weak, strong, cfg.clip_grow, near)
        face = cv2.morphologyEx(near, cv2.MORPH_CLOSE, kern)
        n, lab, st = components_with_stats(face)
        if n <= 1:
            return None
        j = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
        region_j = lab == j
        bx0, by0, bw, bh = (int(v) for v in st[j, :4])
        pix = (region_j & (weak > 0)).astype(np.uint8)
        area = float(np.count_nonzero(pix))
        if area < cfg.min_area_px:
            return None
        if bw < 2 or bh < 2:
            return None
        hull = _convex_hull(pix)
        hull_area = max(float(cv2.contourArea(hull)), 1.0)
        hull_fill = hull_area / (bw * bh)
        solidity = area / hull_area
        aspect = bw / bh
        if self.debug is not None:
            self.debug.append(dict(box=(x0 + bx0, y0 + by0, bw, bh), fill=hull_fill,
                                   sol=solidity, aspect=aspect, t=t))
        return _Face((x0, y0, x1, y1), m, raw, hsv, like, t, blur_t, region_j, pix,
                     area, hull, (bx0, by0, bw, bh), hull_fill, solidity)

    def _border_growth(self, hmask: np.ndarray, dark: np.ndarray, like: np.ndarray,
                       size: int, blur_like: Optional[float] = None) -> tuple[float, dict]:
        """Per-side box growth of one blob from its own edge profile (fraction of its size).

        The sign art has a thin outer orange margin and a black border line inside it.  Two
        bands of ``border_frac`` x size are compared: just inside the orange hull and just
        outside it.  If the black line lies outside the hull (the outer band is darker than
        the inner one) the hull stops at the line's inner edge, the margin and line are
        missing and the box grows by ``border_frac``; if the line is inside the hull (the
        margin was found, or bright light pulled the surroundings in) it does not grow.
        ``border_dark`` > 0 replaces the comparison by "outer band dark share >= it".
        """
        cfg = self.config
        blur_like = cfg.blur_like if blur_like is None else blur_like
        r = max(1, int(round(cfg.border_frac * size)))
        k = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
        outer = (cv2.dilate(hmask, k) > 0) & (hmask == 0)
        inner = (hmask > 0) & (cv2.erode(hmask, k) == 0)
        no, ni = np.count_nonzero(outer), np.count_nonzero(inner)
        out_dark = np.count_nonzero(dark & outer) / max(no, 1)
        in_dark = np.count_nonzero(dark & inner) / max(ni, 1)
        # blur width: 1-px rings outside the hull whose mean likelihood still shows the
        # sign's colour blended with the background (soft edges: rain, fog, small signs)
        # (compiled: the rings of repeated 3 x 3 dilations, np.mean's ring means)
        blur = blur_rings(hmask, like, float(blur_like), int(cfg.blur_max_frac * size) + 2)
        feats = dict(ring=out_dark, inner=in_dark, blur=blur)
        if no == 0:
            return 0.0, feats
        line_out = (out_dark >= cfg.border_dark) if cfg.border_dark > 0 else out_dark >= in_dark
        return (cfg.border_frac if line_out else 0.0) + blur / float(size), feats
