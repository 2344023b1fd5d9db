"""Geometry of ``(x, y, w, h)`` boxes shared by the tracker's modules."""
from __future__ import annotations

from typing import Sequence

__all__ = ['box_iou', 'ioa', 'blend']


def box_iou(a: Sequence[float], b: Sequence[float]) -> float:
    """IoU of two ``(x, y, w, h)`` boxes (0 when either is empty)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def ioa(a: Sequence[float], b: Sequence[float]) -> float:
    """Share of box ``b``'s area inside box ``a`` (0 when ``b`` is empty)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0 or b[2] <= 0 or b[3] <= 0:
        return 0.0
    return iw * ih / (b[2] * b[3])


def blend(a: Sequence[float], b: Sequence[float], wb: float
          ) -> tuple[float, float, float, float]:
    """Weighted mean of two ``(x, y, w, h)`` boxes (corners averaged; ``wb`` is b's weight)."""
    wa = 1.0 - wb
    x0 = wa * a[0] + wb * b[0]
    y0 = wa * a[1] + wb * b[1]
    x1 = wa * (a[0] + a[2]) + wb * (b[0] + b[2])
    y1 = wa * (a[1] + a[3]) + wb * (b[1] + b[3])
    return (x0, y0, x1 - x0, y1 - y0)
