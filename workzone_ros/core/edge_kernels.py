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

* the sample points as numpy's broadcast sums (float64, then float32), made stretch by
  stretch as it is measured; whether any lies outside the image is decided before, from
  each stretch's four corner points (:func:`points_code`), so a stretch that is never
  measured costs four points, not a few thousand;
* the bilinear samples as ``cv2.remap`` (``INTER_LINEAR``, a constant zero border) computes
  them: ``p00 + ax (p01 - p00)`` per row, then the same between the rows, each a fused
  multiply-add in float32 (OpenCV's AVX2 kernel);
* the medians as np.median's: the middle value, or the mean of the middle two in float32,
  of each column sorted by a sorting network (the same exchanges on every column, in
  vectors: a sixth of the time of ranking every value against every other), by selection
  (:func:`~workzone_ros.core.kernels.median_inplace`) for long stretches;
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

__all__ = ['fma', 'bilinear', 'sort_columns', 'column_medians', 'points_code',
           'stretch_points', 'sample_points', 'stretch_profile', 'edge_profiles',
           'model_fits', 'edge_fit', 'valid_models', 'warm']


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
#: :func:`edge_profiles` takes its medians by a sorting network up to this many profiles a
#: stretch (the same exchanges on every column, in vectors), by selection beyond
_NETWORK_MAX = 48


@njit(cache=True)
def _exchange(x: np.ndarray, i: int, j: int) -> None:
    """Each column of ``x``: the smaller of rows ``i`` and ``j`` to row ``i``, the larger to
    row ``j``."""
    xi, xj = x[i], x[j]
    for c in range(xi.size):
        lo, hi = xi[c], xj[c]
        if hi < lo:
            lo, hi = hi, lo
        xi[c], xj[c] = lo, hi


@njit(cache=True)
def sort_columns(x: np.ndarray) -> None:
    """Sort each column of ``x`` (n, m) (NaN-free) in place, all columns at once: Batcher's
    merge exchange (Knuth, TAOCP 3, 5.2.2, algorithm M), a sorting network for any n of
    about n/4 lg^2 n exchanges."""
    n = x.shape[0]
    if n < 2:
        return
    top = 1                 # the largest power of two below n
    while 2 * top < n:
        top *= 2
    p = top
    while p > 0:
        q, r, d = top, 0, p
        while True:
            for i in range(n - d):
                if i & p == r:
                    _exchange(x, i, i + d)
            if q == p:
                break
            d, q, r = q - p, q // 2, p
        p //= 2


@njit(cache=True)
def column_medians(x: np.ndarray, out: np.ndarray) -> None:
    """np.median of each column of float32 ``x`` (nt, m) (NaN-free) into ``out`` (m,): the
    middle value, or the mean of the middle two in float32 (as
    :func:`~workzone_ros.core.kernels.median_inplace`), from the columns sorted in place
    (:func:`sort_columns`)."""
    nt, m = x.shape
    sort_columns(x)
    k = nt // 2
    for j in range(m):
        out[j] = x[k, j] if nt % 2 else (x[k - 1, j] + x[k, j]) / 2


@njit(cache=True)
def _point(s0: float, d: float, t: float, uj: float, nv: float) -> np.float32:
    """One coordinate of a sample point: ``s0 + t d + uj nv - 0.5`` in float64, then
    float32 (numpy's broadcast sums' order)."""
    return np.float32(s0 + t * d + uj * nv - 0.5)


@njit(cache=True)
def stretch_points(segs: np.ndarray, nvecs: np.ndarray, s: int, u: np.ndarray,
                   ts: np.ndarray, mx: np.ndarray, my: np.ndarray) -> None:
    """Edge stretch ``s``'s sample points (:func:`sample_points`) into ``mx``, ``my``
    (len(ts), len(u)) float32."""
    dx = segs[s, 1, 0] - segs[s, 0, 0]
    dy = segs[s, 1, 1] - segs[s, 0, 1]
    for t in range(ts.size):
        for j in range(u.size):
            mx[t, j] = _point(segs[s, 0, 0], dx, ts[t], u[j], nvecs[s, 0])
            my[t, j] = _point(segs[s, 0, 1], dy, ts[t], u[j], nvecs[s, 1])


@njit(cache=True)
def _outside(x: np.float32, y: np.float32, h: int, w: int) -> int:
    """-2 when the point ``(x, y)`` is not a number, -1 when it lies outside an ``h`` x
    ``w`` image (pixel centres from 0 to ``w - 1``, ``h - 1``), else 0."""
    if math.isnan(x) or math.isnan(y):
        return -2
    if x < 0 or y < 0 or x > w - 1 or y > h - 1:
        return -1
    return 0


@njit(cache=True)
def _stretch_code(segs: np.ndarray, nvecs: np.ndarray, s: int, u: np.ndarray,
                  ts: np.ndarray, h: int, w: int) -> int:
    """:func:`_outside` of stretch ``s``'s first sample point that is not a number or lies
    outside the image, point by point (0: none)."""
    dx = segs[s, 1, 0] - segs[s, 0, 0]
    dy = segs[s, 1, 1] - segs[s, 0, 1]
    for t in range(ts.size):
        for j in range(u.size):
            code = _outside(_point(segs[s, 0, 0], dx, ts[t], u[j], nvecs[s, 0]),
                            _point(segs[s, 0, 1], dy, ts[t], u[j], nvecs[s, 1]), h, w)
            if code != 0:
                return code
    return 0


@njit(cache=True)
def _corner_code(segs: np.ndarray, nvecs: np.ndarray, s: int, t_ends: tuple,
                 u_ends: tuple, h: int, w: int) -> int:
    """-1 when one of stretch ``s``'s sample points at the extreme steps ``t_ends`` and
    offsets ``u_ends`` lies outside the image, else 0 (all of them finite)."""
    dx = segs[s, 1, 0] - segs[s, 0, 0]
    dy = segs[s, 1, 1] - segs[s, 0, 1]
    for t in t_ends:
        for uj in u_ends:
            if _outside(_point(segs[s, 0, 0], dx, t, uj, nvecs[s, 0]),
                        _point(segs[s, 0, 1], dy, t, uj, nvecs[s, 1]), h, w) != 0:
                return -1
    return 0


@njit(cache=True)
def points_code(shape: tuple, segs: np.ndarray, nvecs: np.ndarray, u: np.ndarray,
                ts: np.ndarray) -> int:
    """:func:`sample_points`' code without the points: 0 when every sample point lies in
    an image of ``shape`` (h, w), else the first stretch's with one outside (-1) or not a
    number (-2).  A stretch with finite end points and normal (and finite ``ts``, ``u``)
    is decided by its four corner points: each coordinate is a chain of sums and products,
    each rounded, with one term varying along the stretch and one across it, so it is
    monotone in ``t`` and in ``u`` and its extremes lie at their extreme values.  Others
    are checked point by point."""
    if ts.size == 0 or u.size == 0:
        return 0                               # no sample points
    h, w = shape[0], shape[1]
    steps_finite = np.all(np.isfinite(ts)) and np.all(np.isfinite(u))
    t_ends = (ts.min(), ts.max())
    u_ends = (u.min(), u.max())
    for s in range(segs.shape[0]):
        if steps_finite and np.all(np.isfinite(segs[s])) and np.all(np.isfinite(nvecs[s])):
            code = _corner_code(segs, nvecs, s, t_ends, u_ends, h, w)
        else:
            code = _stretch_code(segs, nvecs, s, u, ts, h, w)
        if code != 0:
            return code
    return 0


@njit(cache=True)
def sample_points(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, u: np.ndarray,
                  ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`edge_profiles`' sample points ``s0 + t (s1 - s0) + u n - 0.5`` of each edge
    stretch (``segs`` (n, 2, 2) its end points, ``nvecs`` (n, 2) its inward normal) for each
    ``t`` of ``ts`` and ``u`` of ``u``: ``(x, y, code)``, x and y (n, len(ts), len(u))
    float32 and code 0; -1 when a point lies outside the ``img.shape`` image, -2 when one is
    not a number (whichever comes first, stretch by stretch; the points are then not
    filled)."""
    n, nt, nu = segs.shape[0], ts.size, u.size
    mx = np.empty((n, nt, nu), np.float32)
    my = np.empty((n, nt, nu), np.float32)
    code = points_code(img.shape, segs, nvecs, u, ts)
    if code == 0:
        for s in range(n):
            stretch_points(segs, nvecs, s, u, ts, mx[s], my[s])
    return mx, my, code


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
    if nt <= _NETWORK_MAX:
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
    code = points_code(img.shape, segs, nvecs, u, ts)
    if code < 0:
        return code
    n, nu, nk = segs.shape[0], u.size, valid.size
    # one stretch's sample points at a time: a stretch that is not measured costs none
    mx = np.empty((ts.size, nu), np.float32)
    my = np.empty((ts.size, nu), np.float32)
    prof = np.empty((1, nu))
    # the models' A^T p and coefficients of one stretch (the invalid ones stay zero)
    atb = np.zeros((nk, 3, 1))
    coef = np.zeros((nk, 3, 1))
    seen = 0
    for c in range(n):
        stretch_points(segs, nvecs, c, u, ts, mx, my)
        stretch_profile(img, mx, my, prof[0])
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
