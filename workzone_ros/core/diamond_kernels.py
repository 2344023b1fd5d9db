"""One round of a warning diamond's edge measurement, compiled (numba).

:func:`workzone_ros.core.detect.diamond.refine_diamond` measures a face's four edges in
rounds: from the current diamond, the edges' end points, directions and inward normals, two
stretches on each edge, their offsets by the edge model
(:func:`~workzone_ros.core.edge_kernels.edge_fit`).  A busy real frame runs some 25-55
rounds; in numpy the geometry of a round (a dozen small arrays) cost about as much as the
edge measurement itself.  :func:`diamond_round` does it in one call, with numpy's arithmetic
in numpy's order (the same values), and stops the measurement once more stretches show no
step than the round accepts (the stretches left are never sampled: most rounds of a busy
frame fail after three or four of their eight).  ``test/core/test_diamond_kernels.py``
checks it against the numpy code.

Numba caches a compiled function by its own file's time stamp, and the edge measurement is
compiled into :func:`diamond_round`: a change to :mod:`~workzone_ros.core.edge_kernels`
takes effect here once this file changes too (or its cache is cleared).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from workzone_ros.core.edge_kernels import edge_fit

__all__ = ['diamond_frame', 'unit_steps', 'diamond_round', 'warm']


@njit(cache=True)
def diamond_frame(cx: float, cy: float, a: float, b: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The four edges of the diamond ``|x - cx| / a + |y - cy| / b = 1`` (left corner to top,
    top to right, right to bottom, bottom to left): ``(p0, e, nvec)``, each (4, 2), the
    edges' first corners, their vectors to the next corner and their inward unit normals."""
    p0 = np.empty((4, 2))
    p0[0, 0], p0[0, 1] = cx - a, cy
    p0[1, 0], p0[1, 1] = cx, cy - b
    p0[2, 0], p0[2, 1] = cx + a, cy
    p0[3, 0], p0[3, 1] = cx, cy + b
    e = np.empty((4, 2))
    nvec = np.empty((4, 2))
    for i in range(4):
        j = (i + 1) % 4
        ex, ey = p0[j, 0] - p0[i, 0], p0[j, 1] - p0[i, 1]
        e[i, 0], e[i, 1] = ex, ey
        norm = math.hypot(ex, ey)
        nx, ny = -(ey / norm), ex / norm
        # towards the centre from the edge's middle
        inward = (nx * (cx - 0.5 * (p0[i, 0] + p0[j, 0]))
                  + ny * (cy - 0.5 * (p0[i, 1] + p0[j, 1])))
        if inward < 0:
            nx, ny = nx * -1.0, ny * -1.0
        nvec[i, 0], nvec[i, 1] = nx, ny
    return p0, e, nvec


@njit(cache=True)
def unit_steps(n: int) -> np.ndarray:
    """``np.linspace(0, 1, n)`` (n >= 2) as numpy fills it: ``i * (1 / (n - 1)) + 0``, the
    last exactly 1."""
    step = 1.0 / (n - 1)
    ts = np.empty(n)
    for i in range(n):
        ts[i] = np.float64(i) * step + 0.0
    ts[n - 1] = 1.0
    return ts


@njit(cache=True)
def diamond_round(img: np.ndarray, cx: float, cy: float, a: float, b: float,
                  f_from: np.ndarray, f_to: np.ndarray, shown: np.ndarray, u: np.ndarray,
                  bases_vt: np.ndarray, ata_inv_v: np.ndarray, models: np.ndarray,
                  valid: np.ndarray, min_contrast: float, u0: np.ndarray, sig: np.ndarray,
                  bright: float, max_lost: int):
    """One round of :func:`~workzone_ros.core.detect.diamond.refine_diamond` on the float32
    brightness ``img`` from the diamond ``(cx, cy, a, b)``: its eight edge stretches (two on
    each edge, from fraction ``f_from`` to ``f_to`` (4, 2) of it; ``shown`` (8,): those
    measured) and their offsets along the inward normals by
    :func:`~workzone_ros.core.edge_kernels.edge_fit` (``u``, ``bases_vt``, ``ata_inv_v``,
    ``models``, ``valid``: the edge profile's, as it takes them), each taken ``bright`` px
    further out where the fitted background is brighter than the face.

    Returns ``(code, segs, mids, nv, off, blur)``: the stretches' end points (8, 2, 2), their
    middles and inward normals (8, 2), their offsets and fitted blur widths (8,; NaN: not
    shown, or no step); ``code`` how many shown stretches show no step, -1 when the round
    fails (a sample point outside ``img``, no stretch with a step, or more than
    ``max_lost`` without one: then not all are measured), -2 when the numpy code must
    measure them (fewer than two shown, or a sample point that is not a number)."""
    p0, e, nvec = diamond_frame(cx, cy, a, b)
    segs = np.empty((8, 2, 2))
    mids = np.empty((8, 2))
    nv = np.empty((8, 2))
    for s in range(8):
        i, j = s // 2, s % 2
        for d in range(2):
            segs[s, 0, d] = p0[i, d] + f_from[i, j] * e[i, d]
            segs[s, 1, d] = p0[i, d] + f_to[i, j] * e[i, d]
            mids[s, d] = 0.5 * (segs[s, 0, d] + segs[s, 1, d])
            nv[s, d] = nvec[i, d]
    off = np.full(8, np.nan)
    blur = np.full(8, np.nan)
    idx = np.flatnonzero(shown)
    n = idx.size
    if n < 2:
        return -2, segs, mids, nv, off, blur
    segs_s = np.empty((n, 2, 2))
    nv_s = np.empty((n, 2))
    for c in range(n):
        segs_s[c] = segs[idx[c]]
        nv_s[c] = nv[idx[c]]
    length = math.hypot(segs_s[0, 1, 0] - segs_s[0, 0, 0], segs_s[0, 1, 1] - segs_s[0, 0, 1])
    ts = unit_steps(max(3, int(length) + 1))
    o_, best, b_, lv = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty((n, 2))
    seen = edge_fit(img, segs_s, nv_s, u, ts, bases_vt, ata_inv_v, models, valid,
                    min_contrast, u0, sig, o_, best, b_, lv, min(max_lost, n - 1))
    if seen == -2:
        return -2, segs, mids, nv, off, blur
    if seen <= 0:
        return -1, segs, mids, nv, off, blur
    for c in range(n):
        o = o_[c]
        if bright > 0 and lv[c, 1] > lv[c, 0]:
            o = o - bright
        off[idx[c]] = o
        blur[idx[c]] = b_[c]
    return n - seen, segs, mids, nv, off, blur


def warm() -> None:
    """Compile (or load from the cache) the kernels for the types the detector passes."""
    from workzone_ros.core.detect.diamond import _ALL_SHOWN, _EDGE_FROM, _EDGE_TO
    diamond_frame(20.0, 20.0, 10.0, 10.0)
    img = np.zeros((40, 40), np.float32)
    u = np.arange(-1.0, 1.01, 0.25)
    valid = np.array([True, False])
    vt, inv, models = np.zeros((u.size, 3)), np.zeros((1, 3, 3)), np.zeros(1, np.int64)
    u0, sig = np.arange(2, dtype=np.float32), np.ones(1, np.float32)
    # the stretches every round uses (read-only constants), and those above an occluder
    for stretches in ((_EDGE_FROM, _EDGE_TO, _ALL_SHOWN),
                      (_EDGE_FROM.copy(), _EDGE_TO.copy(), _ALL_SHOWN.copy())):
        diamond_round(img, 20.0, 20.0, 10.0, 10.0, *stretches, u, vt, inv, models, valid,
                      0.25, u0, sig, 0.0, 2)
