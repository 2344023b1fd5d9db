"""Small helpers shared by the colour detector's stages.

Robust statistics of small arrays (the mode of a likelihood histogram, a median without
np.median's overhead), connected components, the colour table lookup, window and box
arithmetic.
"""
from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from workzone_ros.core.blob_kernels import hull_points
from workzone_ros.core.color_model import table_lookup

__all__ = ['pixel_box']


_P_SCALE = 254.0          # probabilities as uint8 0..254; a threshold of 255 never passes


@functools.lru_cache(maxsize=16)
def _bin_edges(dtype: np.dtype, lo: float, hi: float, bins: int) -> np.ndarray:
    """``np.histogram``'s bin edges for ``bins`` bins over ``(lo, hi)`` of ``dtype`` data."""
    edges = np.histogram_bin_edges(np.empty(0, dtype), bins=bins, range=(lo, hi))
    edges.flags.writeable = False
    return edges


def _mode(values: np.ndarray, lo: float = 0.0, hi: float = 1.0, bins: int = 20) -> float:
    """Mode of ``values`` as the centre of the fullest of ``bins`` histogram bins.

    The histogram is ``np.histogram(values, bins, (lo, hi))``'s: bin ``i`` counts the values
    in ``[edges[i], edges[i + 1])``, the last bin also those equal to ``hi``, values outside
    the range none; counted here by a binary search in its edges (np.histogram's own
    set-up costs ~0.1 ms per call).
    """
    if values.size == 0:
        return 0.0
    edges = _bin_edges(values.dtype, lo, hi, bins)
    # slot k: values in [edges[k - 1], edges[k]); slot bins + 1: at or beyond the last edge
    slots = np.bincount(np.searchsorted(edges, values, side='right'), minlength=bins + 2)
    hist = slots[1:bins + 1]
    hist[-1] += np.count_nonzero(values == edges[-1])
    i = int(np.argmax(hist))
    return float(0.5 * (edges[i] + edges[i + 1]))


def _convex_hull(mask: np.ndarray) -> np.ndarray:
    """``cv2.convexHull(cv2.findNonZero(mask))`` of a non-empty 2-d uint8 or bool mask, from
    the pixels that can lie on the hull (:func:`~workzone_ros.core.blob_kernels.hull_points`):
    the same hull, a tenth of the time on a large blob."""
    return cv2.convexHull(hull_points(mask))


def _padded(window: tuple, bw: int, bh: int) -> tuple[int, int, int, int]:
    """A blob's window ``(x0, y0, x1, y1)`` grown by a quarter of the blob's size ``(bw,
    bh)`` + 3 px (a mask fit that is too large puts an edge's outer samples beyond it)."""
    pad = 3 + int(0.25 * max(bw, bh))
    x0, y0, x1, y1 = window
    return x0 - pad, y0 - pad, x1 + pad, y1 + pad


def pixel_box(x: float, y: float, w: float, h: float) -> tuple[float, float, float, float]:
    """The whole-pixel box of the pixels whose centres lie inside an upright rectangle
    ``(x, y, w, h)`` (pixel ``i`` spans ``[i, i + 1)``, its centre at ``i + 0.5``): each edge
    rounded to the nearest pixel boundary.  Box labels drawn from a sign's pixels are whole
    pixels; rounding a sub-pixel measurement the same way matches them exactly when it is
    right to a fraction of a pixel, and is on average never further off than the sub-pixel
    box itself (the label's rounding is independent of the measurement's error)."""
    x0, y0 = math.ceil(x - 0.5), math.ceil(y - 0.5)
    x1, y1 = math.floor(x + w - 0.5) + 1, math.floor(y + h - 0.5) + 1
    return float(x0), float(y0), float(max(x1 - x0, 1)), float(max(y1 - y0, 1))


#: ``table[hue, sat]`` of a colour table, compiled for uint8 channels (one mechanism with
#: :meth:`ColorModel.lookup <workzone_ros.core.color_model.ColorModel.lookup>`).
_lookup = table_lookup


def _paste(dst: np.ndarray, src: np.ndarray, oy: int, ox: int) -> None:
    """``dst[oy:oy + h, ox:ox + w] = src``, clipped to ``dst`` (a blob of a half-resolution
    mask scaled back up can reach a row or column past an odd-sized frame's edge)."""
    h = min(src.shape[0], dst.shape[0] - oy)
    w = min(src.shape[1], dst.shape[1] - ox)
    if h > 0 and w > 0:
        dst[oy:oy + h, ox:ox + w] = src[:h, :w]
