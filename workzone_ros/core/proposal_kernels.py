"""Compiled helper of the recall-first colour proposals (numba).

The proposals (:mod:`workzone_ros.core.proposals`) measure the components of four masks of
each frame: their mean likelihood, saturation and brightness and the brightness's spread.
Done in numpy (``cv2.findNonZero`` of the mask, then ``np.bincount`` of four maps weighted
at those pixels) that cost about 0.15 ms a mask on a real 361 x 203 frame, for every
component, though only the few that pass the size, aspect and fill tests are candidates.
:func:`component_sums` reads the maps only at the kept components' pixels, in one pass, and
adds in the same order as ``np.bincount`` (row by row), so the sums are the same to the bit.

``test/core/test_proposal_kernels.py`` checks it against numpy.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ['component_sums', 'warm']


@njit(cache=True)
def component_sums(labels: np.ndarray, mask: np.ndarray, keep: np.ndarray,
                   prob: np.ndarray, sat: np.ndarray, val: np.ndarray) -> np.ndarray:
    """Per label of ``labels`` (0 is the background): the sums over its pixels of ``prob``,
    ``sat``, ``val`` and ``val`` squared, in float64; zeros for a label ``keep`` is false
    for.  ``mask`` is the labelled mask (its zeros are read a byte each)."""
    h, w = labels.shape
    out = np.zeros((keep.size, 4), np.float64)
    for r in range(h):
        for c in range(w):
            if mask[r, c] == 0:
                continue
            lab = labels[r, c]
            if not keep[lab]:
                continue
            v = np.float64(val[r, c])
            out[lab, 0] += np.float64(prob[r, c])
            out[lab, 1] += np.float64(sat[r, c])
            out[lab, 2] += v
            out[lab, 3] += np.float64(np.float32(v) * np.float32(v))
    return out


def warm() -> None:
    """Compile (or load from the cache) the kernel for the types the proposals pass."""
    mask = np.zeros((6, 6), np.uint8)
    mask[1:5, 2:4] = 1
    labels = mask.astype(np.int32)
    hsv = np.zeros((6, 6, 3), np.uint8)
    component_sums(labels, mask, np.ones(2, np.bool_), np.zeros((6, 6), np.float32),
                   hsv[..., 1], hsv[..., 2])
