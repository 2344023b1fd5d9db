"""Compiled helpers of the colour detector's blob measurement (numba).

Each orange blob of a frame has its face's likelihood looked up, its convex hull taken and
a few medians of its pixels' brightness; a busy real frame measures 10-16 blobs.  Done on
all of a blob's pixels in numpy and OpenCV (``cv2.findNonZero`` then ``cv2.convexHull``;
``np.median`` of a masked selection), these cost 20-90 us each; the kernels here give the
same results from less:

* :func:`hull_points`: the pixels that can lie on a mask's convex hull (each row's first
  and last pixel, every pixel of the first and last rows), in ``cv2.findNonZero``'s form
  and order.  Every point on the hull's boundary is one of them (a point on a slanted or
  vertical hull edge is its row's first or last; a horizontal edge is the first or last
  row), so ``cv2.convexHull`` of them is the hull of all the pixels;
* :func:`masked_median_u8`: np.median of the uint8 values under a mask, by their
  histogram (the middle value, or the mean of the middle two, in float64 as np.median's);
* :func:`gated_likelihood`: a colour table's likelihood of a window's HSV pixels, its
  saturation through the frame's table and its brightness floor in the same pass (numpy
  made three);
* :func:`clipped_outside`: whether a face has pixels of clipped red it does not hold yet
  (most have none; numpy built four masks of the window to say so);
* :func:`blur_rings`: how many 1-px rings around a face's hull show its colour blended
  with the background: the rings of repeated 3 x 3 dilations are those of the chessboard
  distance (:func:`chessboard_distance`, one pass each way), each ring's mean likelihood
  as np.mean takes it of float32 values (:func:`mean32`: numpy's pairwise sum in float32,
  divided in float64 and rounded to float32);
* :func:`surround_ring`: the mean likelihood of the ring around a face's hull (between two
  square dilations) and its share at a level, from the same distances (numpy and OpenCV
  dilated the hull twice and gathered the ring).

``test/core/test_blob_kernels.py`` checks each against OpenCV and numpy.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ['row_ends', 'hull_points', 'masked_median_u8', 'gated_likelihood', 'clipped_outside',
           'pairwise_sum32', 'mean32', 'chessboard_distance', 'blur_rings', 'surround_ring',
           'warm']


@njit(cache=True)
def row_ends(mask: np.ndarray, y: int) -> tuple[int, int]:
    """The first and last non-zero column of ``mask``'s row ``y`` ((-1, -1): none)."""
    w = mask.shape[1]
    first = -1
    for x in range(w):
        if mask[y, x]:
            first = x
            break
    if first < 0:
        return -1, -1
    last = first
    for x in range(w - 1, first, -1):
        if mask[y, x]:
            last = x
            break
    return first, last


@njit(cache=True)
def hull_points(mask: np.ndarray) -> np.ndarray:
    """The pixels of a 2-d ``mask`` (non-zero: in) that can lie on its convex hull, as
    ``cv2.findNonZero`` gives points ((k, 1, 2) int32 ``(x, y)``, row by row, left to right):
    every pixel of the first and the last row holding any, the first and last pixel of each
    row between.  (0, 1, 2) for an empty mask."""
    h, w = mask.shape
    top, bottom = -1, -1
    for y in range(h):
        if row_ends(mask, y)[0] >= 0:
            if top < 0:
                top = y
            bottom = y
    out = np.empty((max(0, bottom - top + 1) * 2 + 2 * w, 1, 2), np.int32)
    k = 0
    for y in range(max(top, 0), bottom + 1):
        first, last = row_ends(mask, y)
        if first < 0:
            continue
        edge_row = y == top or y == bottom
        for x in range(first, last + 1):
            if x == first or x == last or (edge_row and mask[y, x]):
                out[k, 0, 0] = x
                out[k, 0, 1] = y
                k += 1
    return out[:k]


@njit(cache=True)
def masked_median_u8(values: np.ndarray, mask: np.ndarray) -> float:
    """``np.median(values[mask != 0])`` of a 2-d uint8 ``values`` (NaN when the mask is
    empty): from the values' histogram, the middle one or the mean of the middle two."""
    hist = np.zeros(256, np.int64)
    n = 0
    h, w = values.shape
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                hist[values[y, x]] += 1
                n += 1
    if n == 0:
        return np.nan
    # the values of rank n // 2 and (n - 1) // 2 (0-based; the same one when n is odd)
    lo_rank, hi_rank = (n - 1) // 2, n // 2
    lo = hi = -1
    seen = 0
    for v in range(256):
        seen += hist[v]
        if lo < 0 and seen > lo_rank:
            lo = v
        if seen > hi_rank:
            hi = v
            break
    return (np.float64(lo) + np.float64(hi)) / 2.0


@njit(cache=True)
def gated_likelihood(table: np.ndarray, hsv: np.ndarray, sat_tab: np.ndarray, v_min: int
                     ) -> np.ndarray:
    """``table[hue, sat_tab[sat]]`` of each pixel of a (h, w, 3) uint8 HSV image, 0 where its
    value is below ``v_min``: a colour table's likelihood (its dtype) with the frame's
    saturation table (``cv2.LUT``'s) and the table's brightness floor."""
    h, w = hsv.shape[:2]
    nh, ns = table.shape
    out = np.empty((h, w), table.dtype)
    for y in range(h):
        for x in range(w):
            hue, sat = hsv[y, x, 0], sat_tab[hsv[y, x, 1]]
            if hue >= nh or sat >= ns:
                raise IndexError('gated_likelihood: a hue or saturation past the table')
            out[y, x] = table[hue, sat] if hsv[y, x, 2] >= v_min else 0
    return out


@njit(cache=True)
def clipped_outside(bgr: np.ndarray, weak: np.ndarray, near: np.ndarray) -> bool:
    """Whether any pixel of a (h, w, 3) uint8 BGR window is of ``weak`` likelihood (non-zero)
    with its red clipped (250 or more, above its green) and not in ``near`` (zero)."""
    h, w = weak.shape
    for y in range(h):
        for x in range(w):
            r = bgr[y, x, 2]
            if weak[y, x] and near[y, x] == 0 and r >= 250 and bgr[y, x, 1] < r:
                return True
    return False


@njit(cache=True)
def _block_sum32(a: np.ndarray, lo: int, n: int) -> np.float32:
    """numpy's float32 sum of at most 128 values ``a[lo:lo + n]``: fewer than 8 in turn from
    -0.0; else in eight interleaved partial sums combined as a tree, the rest after them in
    turn."""
    if n < 8:
        res = np.float32(-0.0)
        for i in range(n):
            res += a[lo + i]
        return res
    r = a[lo:lo + 8].copy()
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def pairwise_sum32(a: np.ndarray, lo: int, n: int) -> np.float32:
    """``np.add.reduce`` of float32 ``a[lo:lo + n]``: numpy's pairwise summation in float32,
    blocks of up to 128 values (:func:`_block_sum32`) summed as the two halves of each longer
    range (split at a multiple of 8), left + right.  (numpy recurses; here an explicit stack
    does, a cached recursive kernel being unsafe to load in numba.)"""
    if n <= 128:
        return _block_sum32(a, lo, n)
    # ranges to sum (start, length, 1: a marker to add the last two sums) and the sums
    todo = np.empty((200, 3), np.int64)
    sums = np.empty(100, np.float32)
    todo[0, 0], todo[0, 1], todo[0, 2] = lo, n, 0
    t, k = 1, 0
    while t > 0:
        t -= 1
        start, m, add = todo[t, 0], todo[t, 1], todo[t, 2]
        if add:
            sums[k - 2] = sums[k - 2] + sums[k - 1]
            k -= 1
        elif m <= 128:
            sums[k] = _block_sum32(a, start, m)
            k += 1
        else:
            half = m // 2
            half -= half % 8
            # (a stack: the last pushed is summed first)
            todo[t, 0], todo[t, 1], todo[t, 2] = start, m, 1
            todo[t + 1, 0], todo[t + 1, 1], todo[t + 1, 2] = start + half, m - half, 0
            todo[t + 2, 0], todo[t + 2, 1], todo[t + 2, 2] = start, half, 0
            t += 3
    return sums[0]


@njit(cache=True)
def mean32(a: np.ndarray, lo: int, n: int) -> np.float32:
    """``a[lo:lo + n].mean()`` of float32 values (n > 0) as numpy takes it: the float32 sum
    from zero (:func:`pairwise_sum32`), divided by the count in float64, rounded to
    float32."""
    s = np.float32(0.0) + pairwise_sum32(a, lo, n)
    return np.float32(np.float64(s) / np.float64(n))


@njit(cache=True)
def chessboard_distance(mask: np.ndarray, cap: int) -> np.ndarray:
    """Each pixel's chessboard (8-neighbour) distance in pixels to the nearest non-zero pixel
    of ``mask`` within the image, at most ``cap + 1`` (int32; two raster passes, exact)."""
    h, w = mask.shape
    far = cap + 1
    d = np.empty((h, w), np.int32)
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                d[y, x] = 0
                continue
            v = far
            if x > 0:
                v = min(v, d[y, x - 1] + 1)
            if y > 0:
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    v = min(v, d[y - 1, xx] + 1)
            d[y, x] = v
    for y in range(h - 1, -1, -1):
        for x in range(w - 1, -1, -1):
            v = d[y, x]
            if x < w - 1:
                v = min(v, d[y, x + 1] + 1)
            if y < h - 1:
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    v = min(v, d[y + 1, xx] + 1)
            d[y, x] = v
    return d


@njit(cache=True)
def blur_rings(mask: np.ndarray, like: np.ndarray, level: float, max_rings: int) -> int:
    """How many of the 1-px rings around ``mask`` (the pixels each further 3 x 3 dilation
    adds, as ``cv2.dilate`` grows it inside the image), in turn from the innermost, have a
    mean of the float32 ``like`` (np.mean's) of at least ``level``: the count before the
    first empty ring, the first below ``level``, or ``max_rings``."""
    h, w = mask.shape
    d = chessboard_distance(mask, max_rings)
    # each ring's values in row-major order (as ``like[ring]`` gathers them)
    start = np.zeros(max_rings + 2, np.int64)
    for y in range(h):
        for x in range(w):
            if 0 < d[y, x] <= max_rings:
                start[d[y, x] + 1] += 1
    for k in range(1, max_rings + 2):
        start[k] += start[k - 1]
    vals = np.empty(start[max_rings + 1], np.float32)
    fill = start.copy()
    for y in range(h):
        for x in range(w):
            k = d[y, x]
            if 0 < k <= max_rings:
                vals[fill[k]] = like[y, x]
                fill[k] += 1
    for k in range(1, max_rings + 1):
        n = start[k + 1] - start[k]
        if n == 0 or np.float64(mean32(vals, start[k], n)) < level:
            return k - 1
    return max_rings


@njit(cache=True)
def surround_ring(mask: np.ndarray, like: np.ndarray, r_in: int, r_out: int, level: float
                  ) -> tuple[float, float]:
    """(mean, share of values at least ``level``) of the float32 ``like`` over the ring of
    pixels more than ``r_in`` and at most ``r_out`` px (chessboard distance: what square
    ``cv2.dilate`` kernels of those radii add, inside the image) from the non-zero pixels
    of ``mask``; the mean as np.mean takes it (:func:`mean32`), ``level`` compared in
    float32 as numpy compares a float32 array with a Python float; (0, 0) for an empty
    ring."""
    h, w = mask.shape
    d = chessboard_distance(mask, r_out)
    n = 0
    for y in range(h):
        for x in range(w):
            if r_in < d[y, x] <= r_out:
                n += 1
    if n == 0:
        return 0.0, 0.0
    vals = np.empty(n, np.float32)
    lev = np.float32(level)
    k = hits = 0
    for y in range(h):
        for x in range(w):
            if r_in < d[y, x] <= r_out:
                vals[k] = like[y, x]
                if vals[k] >= lev:
                    hits += 1
                k += 1
    return np.float64(mean32(vals, 0, n)), hits / n


def warm() -> None:
    """Compile (or load from the cache) the kernels for the types the detector passes."""
    mask = np.zeros((6, 6), np.uint8)
    mask[1:5, 2:4] = 1
    for m in (mask, mask > 0, mask[1:, 1:]):      # (a blob's window: a slice)
        hull_points(m)
    hsv = np.zeros((6, 6, 3), np.uint8)
    for values in (hsv[..., 2], np.zeros((6, 6), np.uint8), np.zeros((6, 8), np.uint8)[:, 1:7]):
        masked_median_u8(values, mask)
        masked_median_u8(values, mask > 0)
    bgr = np.zeros((8, 8, 3), np.uint8)
    win = bgr[1:7, 1:7]                            # (a window of the frame)
    ident = np.arange(256, dtype=np.uint8)
    for table in (np.zeros((180, 256), np.float32), np.zeros((180, 256), np.uint8)):
        gated_likelihood(table, np.zeros((6, 6, 3), np.uint8), ident, 40)
    clipped_outside(win, mask, mask)
    blur_rings(mask, np.zeros((6, 6), np.float32), 0.1, 3)
    surround_ring(mask, np.zeros((6, 6), np.float32), 1, 2, 0.1)
