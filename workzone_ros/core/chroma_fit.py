"""The chroma fit's robust least squares, compiled (numba).

:func:`workzone_ros.core.detect.diamond_search.fit_blurred_diamond` fits nine parameters
``p = (cx, cy, a, b, sigma, face, bg, gx, gy)`` of a blurred diamond over a background plane
to a few thousand chroma pixels, with a soft-L1 loss.  SciPy's ``least_squares`` (trust
region reflective) spent more time in its own bookkeeping (an SVD of the whole Jacobian and
a dozen numpy calls per step) than in the model: 8 ms a fit on average on real frames,
up to 50, the colour detector's costliest step.  Here the same model is summed straight
into its 9 x 9 normal equations pixel by pixel, and a Levenberg-Marquardt loop solves them
(Marquardt's scaling by the normal matrix's diagonal, Nielsen's damping update, steps
projected into the bounds, soft-L1 by reweighting: each pixel weighs
``1 / sqrt(1 + (r / c)^2)``); no Jacobian is ever stored.  On 196 chroma fits of the real
clips it took 2.5 ms on average; 188 ended as SciPy's did (a diamond or none), those with
a diamond within 0.03 px of SciPy's at the median; the figures of ``evaluate ablation``
(held-out renders, labelled clips) did not change, and on every frame of chicago the boxes
of 3 frames of 627 moved by 1-5 px.

An edge's blurred half-plane is within 1e-16 of 0 or 1 more than 8.5 blur widths away,
and the model's derivatives through it vanish there: the error function is evaluated only
for the edges a pixel is near, so most of a window costs a few multiplications; there the
cdf and density come from one exponential and Cody's rational approximation
(:func:`~workzone_ros.core.normal_cdf.normal_cdf_pdf`, relative error below 1e-11), not
``math.erfc`` and ``math.exp`` (up to three exponentials).  Numba's cache knows a compiled
function by its own file's source alone: a change to :mod:`~workzone_ros.core.normal_cdf`
takes effect here once this file changes too (or its cache is cleared).

``test/core/test_chroma_fit.py`` compares the fit with SciPy's on blurred test signs.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from workzone_ros.core.normal_cdf import normal_cdf_pdf

__all__ = ['lm_fit', 'normal_equations', 'warm']

#: beyond this many blur widths an edge's blurred half-plane is 0 or 1 to float64 precision
_Z_FAR = 8.5
#: the four edges' signs ``(sx, sy)``: the edge ``sx u + sy v = 1``
_SX = np.array([-1.0, 1.0, 1.0, -1.0])
_SY = np.array([-1.0, -1.0, 1.0, 1.0])


@njit(cache=True)
def normal_equations(p: np.ndarray, xs: np.ndarray, ys: np.ndarray, vals: np.ndarray,
                     c: float, mat: np.ndarray, vec: np.ndarray) -> float:
    """The soft-L1 cost of the blurred-diamond model ``p`` at pixels ``(xs, ys)`` against
    ``vals`` (``c``: the loss's scale), and in ``mat`` (9 x 9) and ``vec`` (9) the reweighted
    normal equations ``J^T W J`` and ``J^T W r`` (``r``: model less value)."""
    cx, cy, a, b, sg, face, bg, gx, gy = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]
    r2 = a * a + b * b
    n = a * b / math.sqrt(r2)
    dn_da, dn_db = b ** 3 / r2 ** 1.5, a ** 3 / r2 ** 1.5
    contrast = face - bg
    mat[:, :] = 0.0
    vec[:] = 0.0
    cost = 0.0
    z = np.empty(4)
    lin = np.empty(4)
    cdf = np.empty(4)
    pdf = np.empty(4)
    row = np.empty(9)
    for k in range(xs.size):
        dx, dy = xs[k] - cx, ys[k] - cy
        u, v = dx / a, dy / b
        outside = False
        for i in range(4):
            lin[i] = 1.0 - _SX[i] * u - _SY[i] * v
            z[i] = lin[i] * (n / sg)
            if z[i] < -_Z_FAR:
                outside = True
        g0 = g1 = g2 = g3 = g4 = 0.0
        prod = 0.0
        if not outside:
            prod = 1.0
            for i in range(4):
                if z[i] > _Z_FAR:
                    cdf[i], pdf[i] = 1.0, 0.0
                else:
                    cdf[i], pdf[i] = normal_cdf_pdf(z[i])
                prod *= cdf[i]
            for i in range(4):
                if pdf[i] == 0.0:
                    continue
                others = 1.0
                for j in range(4):
                    if j != i:
                        others *= cdf[j]
                d = pdf[i] * others
                g0 += d * (_SX[i] * n / (a * sg))
                g1 += d * (_SY[i] * n / (b * sg))
                g2 += d * ((_SX[i] * u / a) * n + lin[i] * dn_da) / sg
                g3 += d * ((_SY[i] * v / b) * n + lin[i] * dn_db) / sg
                g4 += d * (-z[i] / sg)
        res = bg + gx * dx + gy * dy + contrast * prod - vals[k]
        q = (res / c) ** 2
        root = math.sqrt(1.0 + q)
        cost += c * c * (root - 1.0)
        w = 1.0 / root
        row[0] = contrast * g0 - gx
        row[1] = contrast * g1 - gy
        row[2] = contrast * g2
        row[3] = contrast * g3
        row[4] = contrast * g4
        row[5] = prod
        row[6] = 1.0 - prod
        row[7] = dx
        row[8] = dy
        for i in range(9):
            wi = w * row[i]
            vec[i] += wi * res
            for j in range(i, 9):
                mat[i, j] += wi * row[j]
    for i in range(9):
        for j in range(i):
            mat[i, j] = mat[j, i]
    return cost


@njit(cache=True)
def _damped_step(mat: np.ndarray, vec: np.ndarray, lam: float, out: np.ndarray) -> bool:
    """``out`` = the solution of ``(mat + lam diag(mat)) out = -vec`` by Cholesky; False
    when the damped matrix is not positive definite."""
    m = mat.shape[0]
    low = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            s = mat[i, j]
            if i == j:
                s += lam * max(mat[i, i], 1e-12)
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                if s <= 0.0:
                    return False
                low[i, i] = math.sqrt(s)
            else:
                low[i, j] = s / low[j, j]
    y = np.empty(m)
    for i in range(m):
        s = -vec[i]
        for k in range(i):
            s -= low[i, k] * y[k]
        y[i] = s / low[i, i]
    for i in range(m - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, m):
            s -= low[k, i] * out[k]
        out[i] = s / low[i, i]
    return True


@njit(cache=True)
def lm_fit(xs: np.ndarray, ys: np.ndarray, vals: np.ndarray, p0: np.ndarray,
           lo: np.ndarray, hi: np.ndarray, c: float, max_nfev: int, xtol: float,
           ftol: float) -> tuple:
    """The blurred diamond's parameters minimising the soft-L1 cost (scale ``c``) within
    ``[lo, hi]``, from ``p0``: ``(p, status, nfev)``.  ``status`` 1: the cost fell by less
    than ``ftol`` of itself, 2: the step was shorter than ``xtol (xtol + |p|)``, 0: no
    convergence within ``max_nfev`` model evaluations (SciPy's meanings)."""
    m = p0.size
    p = np.minimum(np.maximum(p0, lo), hi)
    mat, vec = np.empty((m, m)), np.empty(m)
    mat_new, vec_new = np.empty((m, m)), np.empty(m)
    cost = normal_equations(p, xs, ys, vals, c, mat, vec)
    nfev, lam, grow, status = 1, 1e-3, 2.0, 0
    step = np.zeros(m)
    while nfev < max_nfev:
        if not _damped_step(mat, vec, lam, step):
            lam *= grow
            grow *= 2.0
            if lam > 1e12:
                break
            continue
        p_new = np.minimum(np.maximum(p + step, lo), hi)
        moved = math.sqrt(np.sum((p_new - p) ** 2))
        small = moved <= xtol * (xtol + math.sqrt(np.sum(p * p)))
        cost_new = normal_equations(p_new, xs, ys, vals, c, mat_new, vec_new)
        nfev += 1
        # the reduction the damped quadratic model promised (Madsen, Nielsen and Tingleff)
        promised = 0.0
        for i in range(m):
            promised += 0.5 * step[i] * (lam * max(mat[i, i], 1e-12) * step[i] - vec[i])
        if cost_new < cost:
            fell = cost - cost_new
            gain = fell / promised if promised > 0.0 else 1.0
            p, cost = p_new, cost_new
            mat, mat_new = mat_new, mat
            vec, vec_new = vec_new, vec
            lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3), 1e-12)
            grow = 2.0
            if fell <= ftol * cost:
                status = 1
                break
            if small:
                status = 2
                break
        else:
            if small:
                status = 2       # no lower cost within a step this short: a minimum
                break
            lam *= grow
            grow *= 2.0
    return p, status, nfev


def warm() -> None:
    """Compile (or load from the cache) the fit for the types the detector passes."""
    ys, xs = np.mgrid[0:12, 0:12]
    xs, ys = xs.ravel() + 0.5, ys.ravel() + 0.5
    vals = np.where(np.abs(xs - 6) + np.abs(ys - 6) < 4, 100.0, 10.0)
    p0 = np.array([6.0, 6.0, 4.0, 4.0, 1.0, 100.0, 10.0, 0.0, 0.0])
    lo = np.array([4.0, 4.0, 2.0, 2.0, 0.3, -np.inf, -np.inf, -np.inf, -np.inf])
    hi = np.array([8.0, 8.0, 8.0, 8.0, 4.0, np.inf, np.inf, np.inf, np.inf])
    lm_fit(xs, ys, vals, p0, lo, hi, 13.5, 60, 1e-4, 1e-4)
