"""Compiled row profiles of a blob's strip: the cone / drum band tests' loops (numba).

:mod:`workzone_ros.core.profiles` reads a strip of columns over a blob one row at a time;
in numpy each test summed whole boolean masks along their rows (three passes for the band
test, one per flank for the background rows, an argmax each way for the taper) and then
walked the rows in Python: 30-100 us a blob, a few blobs a frame.  The kernels here give
the same answers in one pass over the masks:

* :func:`banded_kernel`: :func:`workzone_ros.core.profiles.banded_rows`'s search;
* :func:`row_share_at_least`: which rows of a mask are at least a share non-zero;
* :func:`taper_kernel`: :func:`workzone_ros.core.profiles.row_taper` (its rows' widths are
  whole pixels, so their means are exact in any order of summation).

``test/core/test_profile_kernels.py`` checks each against the numpy forms.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from workzone_ros.core.blob_kernels import row_ends

__all__ = ['row_share_at_least', 'banded_kernel', 'taper_kernel', 'warm']


@njit(cache=True)
def row_share_at_least(mask: np.ndarray, share: float) -> np.ndarray:
    """Per row of a 2-D mask: its count of non-zero pixels over its width is at least
    ``share`` (``np.count_nonzero(mask, axis=1) / width >= share``; none of a mask of no
    columns)."""
    h, w = mask.shape
    out = np.zeros(h, np.bool_)
    if w == 0:
        return out
    for y in range(h):
        n = 0
        for x in range(w):
            if mask[y, x]:
                n += 1
        out[y] = n / w >= share
    return out


@njit(cache=True)
def _band_rows(orange: np.ndarray, white: np.ndarray, dark: np.ndarray, min_white: float,
               min_orange: float, line: float) -> tuple:
    """Per row of a strip: (at least ``min_white`` white, at least ``min_orange`` orange and
    not white, at least ``line`` dark)."""
    h, w = orange.shape
    fw = float(w)
    is_w = np.empty(h, np.bool_)
    is_o = np.empty(h, np.bool_)
    is_d = np.empty(h, np.bool_)
    for y in range(h):
        no = nw = nd = 0
        for x in range(w):
            if orange[y, x]:
                no += 1
            if white[y, x]:
                nw += 1
            if dark[y, x]:
                nd += 1
        is_w[y] = nw / fw >= min_white
        is_o[y] = no / fw >= min_orange and not is_w[y]
        is_d[y] = nd / fw >= line
    return is_w, is_o, is_d


@njit(cache=True)
def banded_kernel(orange: np.ndarray, white: np.ndarray, dark: np.ndarray, top: int,
                  bottom: int, min_run: int, gap: int, max_band: int, min_beyond: int,
                  min_white: float, min_orange: float, line: float) -> bool:
    """:func:`workzone_ros.core.profiles.banded_rows` on non-empty masks of one shape."""
    n = orange.shape[0]
    is_w, is_o, is_d = _band_rows(orange, white, dark, min_white, min_orange, line)
    for side in range(2):
        start, step = (top - 1, -1) if side == 0 else (bottom, 1)
        i, n_white, first = start, 0, -1
        while 0 <= i < n and not is_d[i]:
            if is_w[i]:
                n_white += 1
                if first < 0:
                    first = i
            elif is_o[i]:
                k = i
                while 0 <= k < n and is_o[k]:
                    k += step
                if first >= 0 and n_white >= min_run and abs(k - i) >= min_beyond:
                    return True
                if first < 0 and abs(i - start) >= gap:
                    break
                if first >= 0:
                    i = k
                    continue
            if first < 0 and abs(i - start) >= gap + 1:
                break
            if first >= 0 and abs(i - first) >= max_band:
                break
            i += step
    end = min(bottom, n)
    i = top
    while i < end:
        if is_o[i] or not (is_w[i] or not is_d[i]) or i == top:
            i += 1
            continue
        j = i
        while j < end and not is_o[j] and not is_d[j]:
            j += 1
        if j < end and is_o[j] and is_o[i - 1]:
            nw = 0
            for r in range(i, j):
                if is_w[r]:
                    nw += 1
            if nw >= min_run:
                return True
        i = j + 1
    return False


@njit(cache=True)
def taper_kernel(mask: np.ndarray) -> float:
    """:func:`workzone_ros.core.profiles.row_taper` of a 2-D mask."""
    h = mask.shape[0]
    left = np.full(h, -1, np.int64)
    right = np.full(h, -1, np.int64)
    first_row = last_row = -1
    n_rows = 0
    for y in range(h):
        left[y], right[y] = row_ends(mask, y)
        if left[y] >= 0:
            first_row = y if first_row < 0 else first_row
            last_row = y
            n_rows += 1
    if n_rows < 5:
        return 1.0
    y0 = (first_row + 0.5) - 0.5
    span = (last_row + 0.5) + 0.5 - y0
    s_up = s_lo = 0.0
    n_up = n_lo = 0
    for y in range(first_row, last_row + 1):
        if left[y] < 0:
            continue
        width = float(right[y] + 1) - float(left[y])
        t = ((y + 0.5) - y0) / span
        if 0.15 <= t <= 0.4:
            s_up += width
            n_up += 1
        elif 0.6 <= t <= 0.85:
            s_lo += width
            n_lo += 1
    if n_up == 0 or n_lo == 0:
        return 1.0
    return (s_up / n_up) / max(s_lo / n_lo, 1e-6)


def warm() -> None:
    """Compile (or load from the cache) the kernels for the types the detector passes."""
    strip = np.zeros((12, 6), np.bool_)
    strip[2:9, 1:5] = True
    for m in (strip, strip[:, 1:5]):                # (a strip and a flank: slices)
        row_share_at_least(m, 0.5)
    banded_kernel(strip, strip, strip, 2, 9, 2, 2, 9, 3, 0.5, 0.2, 0.9)
    mask = strip.astype(np.uint8)
    for m in (mask, mask[1:, 1:], strip, strip[1:, 1:]):          # (a blob's window: a slice)
        taper_kernel(m)
