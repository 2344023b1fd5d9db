"""Blobs of the colour mask: morphology, components, size filters.

Each blob that passes the radius and area filters is measured at full resolution: the
learned orange path (:mod:`.measure`), or the fixed HSV ranges' filters of the HSV baseline.
A blob that passes no test is handed to the recovery steps (:mod:`.recovery`).
"""
from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.color_model import HSV_RANGES
from workzone_ros.core.detect.candidates import Candidate, _contained
from workzone_ros.core.detect.common import _P_SCALE, _lookup, _mode, _paste
from workzone_ros.core.kernels import components_with_stats

__all__ = ['BlobMixin']


class BlobMixin:
    """The detector's blob stage (opening, closing, components, filters)."""

    def _blobs(self, mask: np.ndarray, bgr: np.ndarray, color: str, off: tuple[int, int],
               s: int, thr_base: np.ndarray, lboxes: list,
               grow: Optional[tuple] = None) -> list[Candidate]:
        """Candidates from the blobs of a mask-resolution ``mask``.  ``grow``: the
        smoothed likelihood, the thresholds and the pass's limit mask (or None) that a blob
        passing no test is grown with (:meth:`_grown`)."""
        cfg = self.config
        if not cv2.countNonZero(mask):
            return []               # nothing to open, close or label (most red / yellow masks)
        if cfg.method == 'hsv':
            # Cahail et al.: erosion removes speckle, dilation reconnects the remaining blobs
            k = np.ones((3, 3), np.uint8)
            mask = cv2.dilate(cv2.erode(mask, k), k, iterations=2)
        else:
            if cfg.open_px > 1:
                mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN,
                                        np.ones((cfg.open_px, cfg.open_px), np.uint8))
            if cfg.close_px > 1:
                mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE,
                                        np.ones((cfg.close_px, cfg.close_px), np.uint8))
        n, labels, stats = components_with_stats(mask)
        out = []
        min_area_small = cfg.min_area_px / (s * s)
        # the largest blobs first: they take the frame's budget of costly measurements
        # (max_blur_fits, max_grown); the candidates keep the components' order
        for i in sorted(range(1, n), key=lambda j: (-int(stats[j, 4]), j)):
            x, y, w, h, area = (int(v) for v in stats[i])
            if area < min_area_small:
                continue
            fx, fy, fw, fh = (x + off[0]) * s, (y + off[1]) * s, w * s, h * s
            # a plaque thinner than the radius filter: a small two-colour sign's orange part
            thin = (color == 'orange' and cfg.extension and cfg.thin_min_radius_px > 0
                    and fh / 2.0 < cfg.min_radius_px <= fw / 2.0
                    and fh / 2.0 >= cfg.thin_min_radius_px and fw >= cfg.ext_min_aspect * fh)
            if (min(fw, fh) / 2.0 < cfg.min_radius_px and not thin) \
                    or max(fw, fh) / 2.0 > cfg.max_radius_px:
                continue
            comp = (labels[y:y + h, x:x + w] == i).astype(np.uint8)
            c = self._measure(bgr, comp, (fx, fy, fw, fh), color, s, thr_base, lboxes,
                              area / float(w * h))
            if thin and (c is None or not c.extended):
                continue            # kept only with its white part below it
            if c is None and grow is not None and self._spend('grown'):
                c = self._grown(i, labels, mask, grow, stats, bgr, off, s, thr_base, lboxes)
            if c is not None:
                out.append((i, c))
        return [c for _, c in sorted(out, key=lambda ic: ic[0])]

    def _spend(self, kind: str) -> bool:
        """Take one of the frame's ``kind`` measurements (``grown``, ``blur_fit`` or
        ``shifted``) from its budget (``max_grown``, ``max_blur_fits``, ``max_shifted``);
        False when none is left, or on a frame measured lean (:meth:`detect`)."""
        if self.lean:
            return False
        left = self._budget.get(kind, 0)
        if left <= 0:
            self.budget_spent.add(kind)
            return False
        self._budget[kind] = left - 1
        return True

    def _measure(self, bgr: np.ndarray, comp: np.ndarray, box: tuple, color: str, s: int,
                 thr_base: np.ndarray, lboxes: list, blob_fill: float = 1.0
                 ) -> Optional[Candidate]:
        """Refine a blob at full resolution, measure its shape, score and filter it."""
        cfg = self.config
        if cfg.method == 'learned' and color == 'orange':
            # judged on colour alone first (LiDAR support never changes a box the colour
            # evidence already makes); only a blob that fails is re-judged with relaxed
            # filters inside its ROI, and must then lie mostly inside that ROI
            c = self._measure_orange(bgr, comp, box, s, thr_base, lboxes)
            roi = self._in_roi(box, s, lboxes) if c is None else None
            if roi is not None:
                c = self._measure_orange(bgr, comp, box, s, thr_base, lboxes, relaxed=True)
                if c is not None and _contained((c.x, c.y, c.w, c.h), roi) < cfg.roi_contain:
                    c = None
            return c
        H, W = bgr.shape[:2]
        fx, fy, fw, fh = box
        m = 2 * s + 1
        x0, y0 = max(0, fx - m), max(0, fy - m)
        x1, y1 = min(W, fx + fw + m), min(H, fy + fh + m)
        win = bgr[y0:y1, x0:x1]
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        region = np.zeros(win.shape[:2], np.uint8)
        up = cv2.resize(comp, (fw, fh), interpolation=cv2.INTER_NEAREST) if s > 1 else comp
        _paste(region, up, fy - y0, fx - x0)
        if s > 1:
            region = cv2.dilate(region, np.ones((4 * s + 1, 4 * s + 1), np.uint8))
        if cfg.method == 'learned':
            i = self._idx[color]
            like = _lookup(self.model.luts[i], hsv[..., 0], hsv[..., 1])
            like[hsv[..., 2] < self.model.v_min[i]] = 0.0
            # posterior threshold at full resolution: tau / prior, or the ROI threshold
            cy, cx = (fy + fh // 2) // s, (fx + fw // 2) // s
            cy, cx = min(cy, thr_base.shape[0] - 1), min(cx, thr_base.shape[1] - 1)
            t = thr_base[cy, cx] / _P_SCALE
            for bx0, by0, bx1, by1 in lboxes:
                if bx0 <= cx < bx1 and by0 <= cy < by1:
                    t = min(t, cfg.roi_threshold / cfg.roi_prior)
            pix = (like >= t - 1e-6) & (region > 0)
            post = like
        else:
            pix = np.zeros(win.shape[:2], bool)
            for h_lo, h_hi, s_lo, v_lo in HSV_RANGES[color]:
                pix |= cv2.inRange(hsv, (h_lo, s_lo, v_lo), (h_hi, 255, 255)) > 0
            pix &= region > 0
            post = pix.astype(np.float32)
        if cfg.refine and pix.any():
            ys, xs = np.nonzero(pix)
            bx0, by0, bx1, by1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
        else:
            bx0, by0 = fx - x0, fy - y0
            bx1, by1 = bx0 + fw, by0 + fh
            pix = region > 0 if not pix.any() else pix
        bw, bh = int(bx1 - bx0), int(by1 - by0)
        if bw < 2 or bh < 2:
            return None
        gx, gy = cfg.border_scale
        area = float(np.count_nonzero(pix))
        if area < cfg.min_area_px:
            return None
        pts = cv2.findNonZero(pix.astype(np.uint8))
        hull_fill = float(cv2.contourArea(cv2.convexHull(pts))) / (bw * bh)
        # Cahail et al. compares the (dilated) blob's area with its box's
        fill = blob_fill if cfg.method == 'hsv' else area / (bw * bh)
        aspect = bw / bh
        if color == 'orange' and cfg.method == 'learned':
            if hull_fill < cfg.min_hull_fill or max(aspect, 1 / aspect) > cfg.max_aspect:
                return None
            kind = 'warning' if hull_fill < cfg.diamond_hull_fill else 'regulatory'
        else:
            # Cahail et al.: width/height close to 1, blob fills much of its box
            if max(aspect, 1 / aspect) > cfg.general_max_aspect or fill < cfg.general_min_fill:
                return None
            if color == 'orange':
                kind = 'warning' if hull_fill < cfg.diamond_hull_fill else 'regulatory'
            else:
                kind = 'general'
        conf = _mode(post[pix]) if cfg.method == 'learned' else fill
        cand = Candidate(x0 + bx0, y0 + by0, bw, bh, color, conf, kind, area, hull_fill)
        if color == 'orange' and (gx != 1.0 or gy != 1.0):
            cand.x -= 0.5 * (gx - 1.0) * bw
            cand.y -= 0.5 * (gy - 1.0) * bh
            cand.w, cand.h = gx * bw, gy * bh
        if (color == 'orange' and cfg.method == 'learned' and cfg.extension
                and kind == 'regulatory' and aspect >= cfg.ext_min_aspect):
            self._extend(bgr, cand, hsv[by0:by1, bx0:bx1][pix[by0:by1, bx0:bx1]])
        return cand

    @staticmethod
    def _in_roi(box: tuple, s: int, lboxes: list) -> Optional[tuple]:
        """The (expanded) LiDAR ROI, full-resolution (x, y, w, h), holding a box's centre."""
        cx, cy = (box[0] + box[2] / 2) / s, (box[1] + box[3] / 2) / s
        for x0, y0, x1, y1 in lboxes:
            if x0 <= cx < x1 and y0 <= cy < y1:
                return (x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s)
        return None
