"""LiDAR fusion: ROI support of colour blobs and lidar-only detections.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.color_model import apply_gains
from workzone_ros.core.detect.candidates import Candidate, _contained, _iou
from workzone_ros.core.detect.common import _lookup
from workzone_ros.core.kernels import components_with_stats
from workzone_ros.interfaces import Roi

__all__ = ['LidarMixin']


class LidarMixin:
    """The detector's LiDAR fusion."""

    def _fuse(self, cands: list[Candidate], rois: Sequence[Roi], bgr: np.ndarray,
              thr_base: np.ndarray) -> list[Candidate]:
        """Mark LiDAR-supported blobs; add LiDAR-only detections (Cahail et al., as fusion).

        A colour blob whose centre lies in an (expanded) ROI gets the ROI's id, both sources
        and a noisy-OR confidence; an unsupported blob keeps its own.  An ROI that no colour
        blob explains is examined at full resolution (``_lidar_only``).
        """
        cfg = self.config
        used = set()
        for c in cands:
            best, best_score = None, 0.0
            for j, r in enumerate(rois):
                mx, my = r.box.w * cfg.roi_margin, r.box.h * cfg.roi_margin
                inside = (r.box.x - mx <= c.x + c.w / 2 <= r.box.x2 + mx
                          and r.box.y - my <= c.y + c.h / 2 <= r.box.y2 + my)
                score = max(_iou((c.x, c.y, c.w, c.h), (r.box.x, r.box.y, r.box.w,
                                                         r.box.h))[0], 0.01 if inside else 0.0)
                if score > best_score:
                    best, best_score = j, score
            if best is not None:
                used.add(best)
                c.sources = ['color', 'lidar']
                c.roi_id = int(rois[best].candidate_id)
                c.confidence = 1.0 - (1.0 - c.confidence) * (1.0 - cfg.lidar_confidence)
        if cfg.lidar_only and cfg.method == 'learned' and 'orange' in self._idx:
            for j, r in enumerate(rois):
                if j in used:
                    continue
                c = self._lidar_only(bgr, r, thr_base)
                if c is not None and all(_iou((c.x, c.y, c.w, c.h), (k.x, k.y, k.w, k.h))[1]
                                         <= cfg.nms_contain for k in cands):
                    cands.append(c)
        return cands

    def _lidar_only(self, bgr: np.ndarray, roi: Roi, thr_base: np.ndarray
                    ) -> Optional[Candidate]:
        """A detection from a LiDAR ROI whose colour evidence alone was too weak.

        Inside the ROI (full resolution) the pixels with likelihood >= ``lidar_only_threshold``
        are grouped; the largest group must span ``lidar_only_min_share`` ..
        ``lidar_only_max_share`` of the ROI's larger side (the projector sizes ROIs from the
        candidate's radius and range, so a sign is a predictable share of it: a few orange
        pixels or a whole orange ROI are not a sign) and pass the relaxed shape filters.
        The box is measured like a colour blob's; sources ``lidar`` only.
        """
        cfg = self.config
        H, W = bgr.shape[:2]
        x0, y0 = max(0, int(roi.box.x)), max(0, int(roi.box.y))
        x1, y1 = min(W, int(math.ceil(roi.box.x2))), min(H, int(math.ceil(roi.box.y2)))
        if x1 - x0 < 4 or y1 - y0 < 4:
            return None
        win = bgr[y0:y1, x0:x1]
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        i = self._idx['orange']
        like = _lookup(self.model.luts[i], hsv[..., 0], self._sat(hsv))
        like[hsv[..., 2] < self.model.v_min[i]] = 0.0
        mask = (cv2.blur(like, (3, 3)) >= cfg.lidar_only_threshold).astype(np.uint8)
        n, lab, st = components_with_stats(mask)
        if n <= 1:
            return None
        j = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
        bx, by, bw, bh, area = (int(v) for v in st[j])
        share = max(bw, bh) / float(max(x1 - x0, y1 - y0))
        if area < cfg.min_area_px or not (cfg.lidar_only_min_share <= share
                                          <= cfg.lidar_only_max_share):
            return None
        comp = (lab[by:by + bh, bx:bx + bw] == j).astype(np.uint8)
        c = self._measure_orange(bgr, comp, (x0 + bx, y0 + by, bw, bh), 1, thr_base, [],
                                 relaxed=True, t_override=cfg.lidar_only_threshold)
        if (c is None or _contained((c.x, c.y, c.w, c.h), (x0, y0, x1 - x0, y1 - y0))
                < cfg.roi_contain or min(c.w, c.h) < 2 * cfg.min_radius_px + 4):
            return None
        c.sources = ['lidar']
        c.roi_id = int(roi.candidate_id)
        c.confidence = cfg.lidar_only_confidence
        return c
