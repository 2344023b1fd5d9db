"""Candidates (blobs on their way to a Detection), box overlap and
non-maximum suppression.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from workzone_ros.interfaces import Box, Detection

__all__ = ['Candidate', 'nms', 'box_metrics', 'dominant_color']


@dataclass
class Candidate:
    """A blob on its way to a :class:`Detection` (full-resolution pixels)."""

    x: float
    y: float
    w: float
    h: float
    color: str
    confidence: float
    kind: str = 'unknown'
    area: float = 0.0
    hull_fill: float = 1.0
    extended: bool = False
    refined: bool = False
    chroma_fit: bool = False
    sources: list[str] = field(default_factory=lambda: ['color'])
    roi_id: Optional[int] = None

    @property
    def box(self) -> Box:
        """The candidate's :class:`Box`."""
        return Box(float(self.x), float(self.y), float(self.w), float(self.h))

    def detection(self) -> Detection:
        """The candidate as an interfaces :class:`Detection`."""
        return Detection(box=self.box, confidence=float(min(max(self.confidence, 0.0), 1.0)),
                         color=self.color, kind=self.kind, sources=list(self.sources),
                         roi_id=self.roi_id)


def _iou(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(IoU, intersection / smaller area) of two (x, y, w, h) boxes."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0, 0.0
    inter = iw * ih
    aa, ab = a[2] * a[3], b[2] * b[3]
    return inter / (aa + ab - inter), inter / max(min(aa, ab), 1e-9)


def _contained(a: Sequence[float], b: Sequence[float]) -> float:
    """Share of box ``a``'s area inside box ``b`` (both x, y, w, h)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return 0.0 if iw <= 0 or ih <= 0 else iw * ih / max(a[2] * a[3], 1e-9)


def nms(cands: list[Candidate], iou: float, contain: float,
        by: str = 'confidence') -> list[Candidate]:
    """Greedy non-maximum suppression; every non-overlapping box stays.

    ``by='confidence'``: most confident first (ties: larger first), so a large, weakly
    orange region (sunlit asphalt, a vehicle) does not swallow a sign inside it.
    ``by='area'``: larger first (the MSER path after Balali and Golparvar-Fard, whose nested
    regions of one sign share a confidence scale with their fill).
    """
    if by == 'area':
        order = sorted(cands, key=lambda c: (c.w * c.h, c.confidence), reverse=True)
    else:
        order = sorted(cands, key=lambda c: (round(c.confidence, 2), c.w * c.h),
                       reverse=True)
    kept: list[Candidate] = []
    for c in order:
        b = (c.x, c.y, c.w, c.h)
        if all((lambda r: r[0] <= iou and r[1] <= contain)(_iou(b, (k.x, k.y, k.w, k.h)))
               for k in kept):
            kept.append(c)
    return kept


def box_metrics(det: Box, gt: Box) -> tuple[float, float, float]:
    """(IoU, area precision, area recall) of a detection against a ground-truth box.

    Seo et al., section III.A: precision = |o n g| / |o|, recall = |o n g| / |g|.
    """
    iw = min(det.x2, gt.x2) - max(det.x, gt.x)
    ih = min(det.y2, gt.y2) - max(det.y, gt.y)
    if iw <= 0 or ih <= 0:
        return 0.0, 0.0, 0.0
    inter = iw * ih
    return (inter / (det.area + gt.area - inter), inter / max(det.area, 1e-9),
            inter / max(gt.area, 1e-9))


def dominant_color(hsv: np.ndarray) -> str:
    """The main colour of an HSV patch: orange / red / yellow / green / white."""
    if hsv.size == 0:
        return 'white'
    h, s, v = (hsv[..., i].ravel().astype(np.int32) for i in range(3))
    chroma = (s >= 90) & (v >= 60)
    if chroma.mean() < 0.15:
        return 'white'
    hh = h[chroma]
    votes = {'red': np.count_nonzero((hh <= 6) | (hh >= 168)),
             'orange': np.count_nonzero((hh >= 7) & (hh <= 19)),
             'yellow': np.count_nonzero((hh >= 20) & (hh <= 34)),
             'green': np.count_nonzero((hh >= 35) & (hh <= 95))}
    return max(votes, key=votes.get)
