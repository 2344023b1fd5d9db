"""Recovery of blobs that pass no test.

A blob whose face is paler in part is grown into its neighbours
(:meth:`RecoveryMixin._grown`).
"""
from __future__ import annotations

import math
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.detect.common import _convex_hull

__all__ = ['RecoveryMixin']


class RecoveryMixin:
    """The detector's blob recovery: grow."""

    def _grown(self, i: int, labels: np.ndarray, mask: np.ndarray, grow: tuple,
               stats: np.ndarray, bgr: np.ndarray, off: tuple[int, int], s: int,
               thr_base: np.ndarray, lboxes: list) -> Optional[Candidate]:
        """Blob ``i`` (of ``labels``, mask resolution) that passed no test, grown into the
        pixels whose likelihood is at least ``grow_level`` x the threshold (``grow``: the
        smoothed likelihood, thresholds and limit mask of the pass; opened as ``mask`` is)
        connected to it within ``grow_reach`` x its larger side beyond its box, and
        measured again at that level: the candidate when that gives a refined warning
        diamond (not the chroma fit's), else None."""
        cfg = self.config
        x, y, w, h, _ = (int(v) for v in stats[i])
        g = int(math.ceil(cfg.grow_reach * max(w, h)))
        H, W = labels.shape
        ya, yb, xa, xb = max(0, y - g), min(H, y + h + g), max(0, x - g), min(W, x + w + g)
        blob = labels[ya:yb, xa:xb] == i
        prob, thr, keep = (a[ya:yb, xa:xb] if a is not None else None for a in grow)
        part = cv2.compare(prob, cv2.convertScaleAbs(thr, alpha=cfg.grow_level), cv2.CMP_GE)
        if keep is not None:
            part &= keep
        if cfg.open_px > 1:
            # specks of a warm surface join nothing
            part = cv2.morphologyEx(part, cv2.MORPH_OPEN,
                                    np.ones((cfg.open_px, cfg.open_px), np.uint8))
        part = part | mask[ya:yb, xa:xb]
        lab = cv2.connectedComponents(part, connectivity=8)[1]
        r, c = np.unravel_index(int(np.argmax(blob)), blob.shape)
        comp = ((lab == lab[r, c]) | blob).astype(np.uint8)
        bx, by, bw, bh = cv2.boundingRect(comp)
        if bw * bh < 1.4 * w * h or max(bw, bh) * s / 2.0 > cfg.max_radius_px \
                or min(bw, bh) * s < cfg.grow_min_px:
            return None     # a rim (not a part of the face), past any sign's size, or small
        comp = comp[by:by + bh, bx:bx + bw]
        # only a diamond is kept: about square, its hull about half its box (checked again
        # at full resolution by the measure)
        hull = _convex_hull(comp)
        if max(bw / bh, bh / bw) >= cfg.ext_min_aspect or \
                cv2.contourArea(hull) >= cfg.diamond_hull_fill * bw * bh:
            return None
        box = ((xa + bx + off[0]) * s, (ya + by + off[1]) * s, bw * s, bh * s)
        # its face at full resolution to the same lower level
        cand = self._measure_orange(bgr, comp, box, s, thr_base, lboxes,
                                    t_scale=cfg.grow_level)
        if cand is not None and cand.kind == 'warning' and cand.refined \
                and not cand.chroma_fit:
            return cand
        return None
