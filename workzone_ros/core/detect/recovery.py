"""Recovery of blobs that pass no test.

A sign merged with a surface of nearly its colour is peeled out at higher likelihood levels
(:meth:`RecoveryMixin._peel`); a blob whose face is paler in part is grown into its neighbours
(:meth:`RecoveryMixin._grown`); pieces of one diamond cut by its symbol are measured as one
(:meth:`RecoveryMixin._merge_fragments`).
"""
from __future__ import annotations

import itertools
import math
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.detect.common import _median

__all__ = ['RecoveryMixin']


class RecoveryMixin:
    """The detector's blob recovery: peel, grow, merge fragments."""

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
        hull = cv2.convexHull(cv2.findNonZero(comp))
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

    def _merge_fragments(self, parts: dict, out: list[Candidate], labels: np.ndarray,
                         stats: np.ndarray, bgr: np.ndarray, off: tuple[int, int], s: int,
                         thr_base: np.ndarray, lboxes: list
                         ) -> tuple[list[Candidate], set]:
        """Two or three blobs that are the pieces of one warning diamond, measured together.

        A symbol that runs from edge to edge (the lane-ends arrow, a reverse curve) cuts a
        diamond's orange face into pieces; each is half a diamond, measured as a narrow sign
        or none.  Blobs (of the ``merge_max`` largest, no refined diamond among them) whose
        boxes lie within a quarter of their joint box of each other and whose joint box is
        about square are measured as one blob: when that gives a warning diamond whose
        edges the brightness confirms (a refined one), it replaces the pieces.  Then, with
        ``merge_triples``, three blobs the same way, refined pieces among them too when the
        joint diamond holds every piece's box (a bold legend in rain light cuts a face into
        three pieces, two of which refine as small diamonds of their own).  Returns the
        candidates and the components merged.
        """
        cfg = self.config
        # a piece boxed by the chroma fit alone (no edge measured) may be a fragment too
        keys = sorted((i for i, c in parts.items() if c is None or not c.refined
                       or c.chroma_fit),
                      key=lambda i: -int(stats[i, cv2.CC_STAT_AREA]))[:cfg.merge_max]
        used: set = set()
        for a, b in itertools.combinations(keys, 2):
            if a in used or b in used:
                continue
            c = self._merged((a, b), labels, stats, bgr, off, s, thr_base, lboxes)
            if c is None or (c.chroma_fit and any(
                    parts[i] is not None and parts[i].refined for i in (a, b))):
                continue
            used |= {a, b}
            out = [o for o in out if o is not parts[a] and o is not parts[b]] + [c]
        if not cfg.merge_triples:
            return out, used
        keys = sorted((i for i in parts if i not in used),
                      key=lambda i: -int(stats[i, cv2.CC_STAT_AREA]))[:cfg.merge_max]
        for trio in itertools.combinations(keys, 3):
            if used & set(trio):
                continue
            c = self._merged(trio, labels, stats, bgr, off, s, thr_base, lboxes)
            if c is None or c.chroma_fit:
                continue
            # the joint diamond holds every piece's box (to a mask pixel)
            px0, py0 = (stats[trio, 0] + off[0]) * s, (stats[trio, 1] + off[1]) * s
            px1, py1 = px0 + stats[trio, 2] * s, py0 + stats[trio, 3] * s
            if not ((px0 >= c.x - s).all() and (px1 <= c.x + c.w + s).all()
                    and (py0 >= c.y - s).all() and (py1 <= c.y + c.h + s).all()):
                continue
            used |= set(trio)
            out = [o for o in out if all(o is not parts[i] for i in trio)] + [c]
        return out, used

    def _merged(self, ids: tuple, labels: np.ndarray, stats: np.ndarray, bgr: np.ndarray,
                off: tuple[int, int], s: int, thr_base: np.ndarray, lboxes: list
                ) -> Optional[Candidate]:
        """Blobs ``ids`` measured as one (:meth:`_merge_fragments`): None unless each lies
        within a quarter of their joint box of the others, the joint box is about square and
        more than 1.25 x each blob's box, and the measure gives a refined diamond."""
        cfg = self.config
        boxes = [tuple(int(v) for v in stats[i, :4]) for i in ids]
        x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
        x1 = max(b[0] + b[2] for b in boxes)
        y1 = max(b[1] + b[3] for b in boxes)
        w, h = x1 - x0, y1 - y0
        if not 0.7 <= w / h <= 1.4 or max(b[2] * b[3] for b in boxes) > 0.8 * w * h:
            return None

        def near(p: tuple, q: tuple) -> bool:
            gx = max(p[0], q[0]) - min(p[0] + p[2], q[0] + q[2])
            gy = max(p[1], q[1]) - min(p[1] + p[3], q[1] + q[3])
            return max(gx, 0) <= max(1, 0.25 * w) and max(gy, 0) <= max(1, 0.25 * h)

        # each piece next to another
        if not all(any(near(p, q) for q in boxes if q is not p) for p in boxes):
            return None
        fx, fy, fw, fh = (x0 + off[0]) * s, (y0 + off[1]) * s, w * s, h * s
        if max(fw, fh) / 2.0 > cfg.max_radius_px:
            return None
        sub = labels[y0:y1, x0:x1]
        comp = np.isin(sub, ids).astype(np.uint8)
        c = self._measure(bgr, comp, (fx, fy, fw, fh), 'orange', s, thr_base, lboxes,
                          float(np.count_nonzero(comp)) / (w * h), None, whole=True)
        return c if c is not None and c.refined else None

    def _peel(self, comp: np.ndarray, prob: np.ndarray, org: tuple[int, int],
              bgr: np.ndarray, s: int, thr_base: np.ndarray, lboxes: list
              ) -> list[Candidate]:
        """A blob that passed no test, judged again at higher likelihood levels: a sign
        merged with a surface of nearly its colour (an orange dusk sky, a brick wall) is
        where the likelihood is clearly higher.  Levels, lowest first, each at least
        ``peel_gap`` above the blob's median: Otsu's level over the blob's pixels, then
        ``peel_levels``; the first level whose cores give candidates wins."""
        vals = prob[comp > 0]
        floor = float(_median(vals)) + self.config.peel_gap * 255
        otsu, _ = cv2.threshold(vals.reshape(-1, 1), 0, 255,
                                cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        levels = sorted({lv for lv in [float(otsu)] + [255 * v for v in self.config.peel_levels]
                         if floor <= lv < 254})
        for level in levels:
            core = ((prob > level) & (comp > 0)).astype(np.uint8) * 255
            # the sign's orange around a legend or symbol, at the mask's resolution
            core = cv2.morphologyEx(core, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) & \
                (comp * 255)
            out = self._blobs(core, bgr, 'orange', org, s, thr_base, lboxes,
                              peel_t=(level + 1) / 255.0)
            if out:
                return out
        return []
