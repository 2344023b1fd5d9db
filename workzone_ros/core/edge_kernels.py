"""The edge model's measurement of a face's edge stretches, compiled (numba).

:func:`workzone_ros.core.detect.edges._edge_offsets` measures a few edge stretches of a sign's
face: per stretch the brightness sampled (bilinear, every quarter pixel along the edge's
normal, one profile per pixel along the edge), the median profile, its least-squares fit by
every model of the edge-offset x blur grid, the best model's offset.  In numpy that was a
dozen array passes over some 10,000 sample points and two BLAS products per call, about
0.2 ms, and a busy real frame makes some thirty calls.  :func:`edge_fit` does the same
without the intermediate arrays, with the same arithmetic in the same order, stretch by
stretch (it stops once more stretches show no step than its caller accepts: on a busy
frame more than half of a diamond's refinement rounds fail so, half of those after three of
their eight stretches):

* the sample points as numpy's broadcast sums (float64, then float32);
* the bilinear samples as ``cv2.remap`` (``INTER_LINEAR``, a constant zero border) computes
  them: ``p00 + ax (p01 - p00)`` per row, then the same between the rows, each a fused
  multiply-add in float32 (OpenCV's AVX2 kernel);
* the medians as np.median's (:func:`~workzone_ros.core.kernels.median_inplace`);
* the two matrix products as OpenBLAS's AVX2 kernels sum them: per element a chain of fused
  multiply-adds over the inner dimension from zero, in order; only the models whose offset
  the grid allows (``valid``) are computed, the others are never read;
* the model choice by :func:`~workzone_ros.core.kernels.edge_choice` itself.

So it returns what the numpy code returned on a machine whose OpenCV and OpenBLAS run their
AVX2 / FMA kernels (this one), bit for bit; elsewhere the two differ by float rounding.
``test/core/test_edge_kernels.py`` checks each part against numpy and OpenCV.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import intrinsic

from workzone_ros.core.kernels import edge_choice, median_inplace

__all__ = ['fma', 'bilinear', 'column_medians', 'sample_points', 'stretch_profile',
           'edge_profiles', 'model_fits', 'edge_fit', 'valid_models', 'warm']


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's ``fma``), for three floats of one type."""
    if not (isinstance(a, types.Float) and a == b == c):
        return None
    sig = a(a, a, a)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return sig, codegen


@njit(cache=True)
def bilinear(img: np.ndarray, x: np.float32, y: np.float32) -> np.float32:
    """``cv2.remap``'s ``INTER_LINEAR`` value of float32 ``img`` at ``(x, y)`` (constant zero
    border), for a point with ``0 <= x <= w - 1`` and ``0 <= y <= h - 1``."""
    h, w = img.shape
    ix, iy = int(x), int(y)                 # (the floor: neither is negative)
    ax = x - np.float32(ix)
    ay = y - np.float32(iy)
    p00 = img[iy, ix]
    if ix + 1 < w and iy + 1 < h:
        p01, p10, p11 = img[iy, ix + 1], img[iy + 1, ix], img[iy + 1, ix + 1]
    else:                                   # on the last column or row: the border's zeros
        zero = np.float32(0.0)
        p01 = img[iy, ix + 1] if ix + 1 < w else zero
        p10 = img[iy + 1, ix] if iy + 1 < h else zero
        p11 = zero
    v0 = fma(ax, p01 - p00, p00)
    v1 = fma(ax, p11 - p10, p10)
    return fma(ay, v1 - v0, v0)


#: :func:`edge_profiles` pads a stretch's profile to a multiple of this many samples (a
#: vector of float32)
_LANES = 16
#: :func:`edge_profiles` takes its medians by rank up to this many profiles a stretch
#: (n^2 comparisons, in vectors), by selection beyond
_RANK_MAX = 48


@njit(cache=True)
def column_medians(x: np.ndarray, out: np.ndarray) -> None:
    """np.median of each column of float32 ``x`` (nt, m) (NaN-free) into ``out`` (m,): the
    middle value, or the mean of the middle two in float32 (as
    :func:`~workzone_ros.core.kernels.median_inplace`), each found by its rank (how many
    values lie below it and how many not above it), every column at once."""
    nt, m = x.shape
    k = nt // 2
    mid = np.zeros(m, np.float32)
    below = np.zeros(m, np.float32)
    lt = np.empty(m, np.int32)
    le = np.empty(m, np.int32)
    for i in range(nt):
        xi = x[i]
        lt[:] = 0
        le[:] = 0
        for t in range(nt):
            xt = x[t]
            for j in range(m):
                lt[j] += np.int32(xt[j] < xi[j])
                le[j] += np.int32(xt[j] <= xi[j])
        for j in range(m):
            if lt[j] <= k < le[j]:
                mid[j] = xi[j]
            if lt[j] <= k - 1 < le[j]:
                below[j] = xi[j]
    for j in range(m):
        out[j] = mid[j] if nt % 2 else (below[j] + mid[j]) / 2


@njit(cache=True)
def sample_points(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, u: np.ndarray,
                  ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`edge_profiles`' sample points ``s0 + t (s1 - s0) + u n - 0.5`` of each edge
    stretch (``segs`` (n, 2, 2) its end points, ``nvecs`` (n, 2) its inward normal) for each
    ``t`` of ``ts`` and ``u`` of ``u``: ``(x, y, code)``, x and y (n, len(ts), len(u))
    float32 and code 0; -1 when a point lies outside the ``img.shape`` image, -2 when one is
    not a number (whichever comes first, stretch by stretch)."""
    n, nt, nu = segs.shape[0], ts.size, u.size
    h, w = img.shape
    mx = np.empty((n, nt, nu), np.float32)
    my = np.empty((n, nt, nu), np.float32)
    for s in range(n):
        dx = segs[s, 1, 0] - segs[s, 0, 0]
        dy = segs[s, 1, 1] - segs[s, 0, 1]
        for t in range(nt):
            ax = segs[s, 0, 0] + ts[t] * dx
            ay = segs[s, 0, 1] + ts[t] * dy
            for j in range(nu):
                x = np.float32(ax + u[j] * nvecs[s, 0] - 0.5)
                y = np.float32(ay + u[j] * nvecs[s, 1] - 0.5)
                if math.isnan(x) or math.isnan(y):
                    return mx, my, -2
                if x < 0 or y < 0 or x > w - 1 or y > h - 1:
                    return mx, my, -1
                mx[s, t, j] = x
                my[s, t, j] = y
    return mx, my, 0


@njit(cache=True)
def stretch_profile(img: np.ndarray, mx: np.ndarray, my: np.ndarray, out: np.ndarray) -> None:
    """The median brightness profile of one edge stretch into ``out`` (nu,): ``img``'s
    bilinear samples at float32 ``mx``, ``my`` (nt, nu) (:func:`sample_points`), the median
    over the nt profiles of each of the nu columns."""
    nt, nu = mx.shape
    # the samples with the columns padded to whole vectors
    nup = (nu + _LANES - 1) // _LANES * _LANES
    samples = np.zeros((nt, nup), np.float32)
    for t in range(nt):
        for j in range(nu):
            samples[t, j] = bilinear(img, mx[t, j], my[t, j])
    if nt <= _RANK_MAX:
        col = np.empty(nup)
        column_medians(samples, col)
        out[:] = col[:nu]
        return
    buf = np.empty(nt, np.float32)
    for j in range(nu):
        for t in range(nt):
            buf[t] = samples[t, j]
        out[j] = median_inplace(buf, nt)


@njit(cache=True)
def edge_profiles(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, u: np.ndarray,
                  ts: np.ndarray) -> np.ndarray:
    """The median brightness profile of each edge stretch: ``segs`` (n, 2, 2) its end points,
    ``nvecs`` (n, 2) its inward normal, sampled at ``s0 + t (s1 - s0) + u n - 0.5`` for each
    ``t`` of ``ts`` and ``u`` of ``u`` (float32 coordinates) in the float32 image ``img``;
    (n, len(u)) float64.  (0, len(u)) when a sample point lies outside ``img``, (0, 0) when
    one is not a number."""
    mx, my, code = sample_points(img, segs, nvecs, u, ts)
    if code == -2:
        return np.empty((0, 0))
    if code == -1:
        return np.empty((0, u.size))
    out = np.empty((segs.shape[0], u.size))
    for s in range(segs.shape[0]):
        stretch_profile(img, mx[s], my[s], out[s])
    return out


@njit(cache=True)
def model_fits(prof_v: np.ndarray, bases_vt: np.ndarray, ata_inv_v: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The least squares of some edge models on each median profile ``prof_v`` (n, nu):
    ``bases_vt`` (nu, 3 m) the m models' bases (transposed), ``ata_inv_v`` (m, 3, 3) their
    normal equations' inverses.  Returns ``A^T p`` and the coefficients, each (n, 3 m), as
    ``bases_t @ prof_v.T`` and ``ata_inv @ atb`` by OpenBLAS's AVX2 kernels: each element a
    chain of fused multiply-adds from zero over the inner dimension in order."""
    n, nu = prof_v.shape
    r_ = bases_vt.shape[1]
    atb = np.zeros((n, r_))
    for c in range(n):
        acc = atb[c]
        for j in range(nu):
            p = prof_v[c, j]
            b = bases_vt[j]
            for r in range(r_):             # (the models side by side: vectorised)
                acc[r] = fma(b[r], p, acc[r])
    coef = np.empty((n, r_))
    for c in range(n):
        for m in range(ata_inv_v.shape[0]):
            x0, x1, x2 = atb[c, 3 * m], atb[c, 3 * m + 1], atb[c, 3 * m + 2]
            for i in range(3):
                coef[c, 3 * m + i] = fma(ata_inv_v[m, i, 2], x2, fma(
                    ata_inv_v[m, i, 1], x1, fma(ata_inv_v[m, i, 0], x0, 0.0)))
    return atb, coef


@njit(cache=True)
def edge_fit(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, u: np.ndarray,
             ts: np.ndarray, bases_vt: np.ndarray, ata_inv_v: np.ndarray,
             models: np.ndarray, valid: np.ndarray, min_contrast: float, u0: np.ndarray,
             sig: np.ndarray, off: np.ndarray, best: np.ndarray, blur: np.ndarray,
             levels: np.ndarray, max_lost: int) -> int:
    """:func:`~workzone_ros.core.detect.edges._edge_offsets` on float32 ``img``, stretch by
    stretch: its median profile (:func:`stretch_profile` at :func:`sample_points`), the
    least squares of the ``valid`` models of the grid (:func:`model_fits`; ``models`` their
    indices, ``bases_vt`` and ``ata_inv_v`` theirs, as :func:`valid_models` gives them) and
    the choice (:func:`~workzone_ros.core.kernels.edge_choice`, ``u0`` the offsets, ``sig``
    the blur widths; the other models it never reads).  Writes ``off``, ``best`` (as
    ``edge_choice``), ``blur`` (n,) the best model's blur width and ``levels`` (n, 2) its
    face and background levels (NaN without a step); returns how many stretches show a
    step; -1 when a sample point lies outside ``img``, -2 when one is not a number, -3 as
    soon as more than ``max_lost`` stretches show none (the later ones not measured)."""
    mx, my, code = sample_points(img, segs, nvecs, u, ts)
    if code < 0:
        return code
    n, nu, nk = segs.shape[0], u.size, valid.size
    prof = np.empty((1, nu))
    # the models' A^T p and coefficients of one stretch (the invalid ones stay zero)
    atb = np.zeros((nk, 3, 1))
    coef = np.zeros((nk, 3, 1))
    seen = 0
    for c in range(n):
        stretch_profile(img, mx[c], my[c], prof[0])
        fit_atb, fit_coef = model_fits(prof, bases_vt, ata_inv_v)
        for m in range(models.size):
            k = models[m]
            for i in range(3):
                atb[k, i, 0] = fit_atb[0, 3 * m + i]
                coef[k, i, 0] = fit_coef[0, 3 * m + i]
        edge_choice(prof, atb, coef, valid, min_contrast, u0, sig.size, off[c:c + 1],
                    best[c:c + 1])
        k = best[c]
        if k < 0:
            blur[c] = np.nan
            levels[c, 0] = levels[c, 1] = np.nan
            if c + 1 - seen > max_lost:
                return -3
        else:
            seen += 1
            blur[c] = sig[k % sig.size]
            levels[c, 0] = coef[k, 0, 0]
            levels[c, 1] = coef[k, 2, 0]
    return seen


def valid_models(bases_t: np.ndarray, ata_inv: np.ndarray, valid: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`edge_fit`'s ``(bases_vt, ata_inv_v, models)`` of an edge profile's bases
    (:func:`~workzone_ros.core.detect.edges._profile_bases`): the ``valid`` models' bases
    transposed (nu, 3 m), their inverses (m, 3, 3) and their indices (m,)."""
    models = np.flatnonzero(valid)
    rows = (3 * models[:, None] + np.arange(3)).reshape(-1)
    return (np.ascontiguousarray(bases_t[rows].T), np.ascontiguousarray(ata_inv[models]),
            models)


def warm() -> None:
    """Compile (or load from the cache) the kernels for the types the detector passes."""
    img = np.zeros((12, 12), np.float32)
    segs = np.array([[[3.0, 3.0], [3.0, 8.0]]])
    nvecs = np.array([[1.0, 0.0]])
    u = np.arange(-1.0, 1.01, 0.25)
    ts = np.linspace(0.0, 1.0, 6)
    valid = np.array([True, False])
    vt, inv, models = valid_models(np.zeros((6, u.size)), np.zeros((2, 3, 3)), valid)
    n = 1
    fixed = ts.copy()
    fixed.flags.writeable = False       # (the sample positions the detector caches)
    for steps in (ts, fixed):
        edge_fit(img, segs, nvecs, u, steps, vt, inv, models, valid, 0.25,
                 np.arange(2, dtype=np.float32), np.ones(1, np.float32), np.empty(n),
                 np.empty(n, np.int64), np.empty(n), np.empty((n, 2)), n)
