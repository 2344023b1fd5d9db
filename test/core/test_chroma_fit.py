"""The compiled chroma fit (workzone_ros.core.chroma_fit) solves the problem SciPy's
least_squares solved, to the same diamond."""
import math

import cv2
import numpy as np
import pytest
from scipy.optimize import least_squares

from workzone_ros.core.chroma_fit import lm_fit, normal_equations
from workzone_ros.core.detect.diamond_search import _blurred_diamond


def _sign(cx, cy, a, b, sigma, shape=(48, 52), seed=0):
    """A chroma window: a diamond of level 150 over a tilted background of 20, a legend
    stroke of 0 down its middle, area-sampled, blurred by ``sigma`` px, noisy."""
    ss = 4
    ys, xs = np.mgrid[0:shape[0] * ss, 0:shape[1] * ss]
    x, y = (xs + 0.5) / ss, (ys + 0.5) / ss
    rel = np.abs(x - cx) / a + np.abs(y - cy) / b
    big = np.where(rel <= 1.0, 150.0, 20.0 + 0.4 * (x - cx) - 0.2 * (y - cy))
    big = np.where((np.abs(x - cx) < 0.12 * a) & (rel <= 0.6), 0.0, big)
    img = big.reshape(shape[0], ss, shape[1], ss).mean(axis=(1, 3))
    img = cv2.GaussianBlur(img, (0, 0), sigma)
    return img + np.random.default_rng(seed).normal(0, 3.0, img.shape)


def _problem(img, start):
    """The pixels, start, bounds and loss scale as fit_blurred_diamond sets them up."""
    cx, cy, a, b = start
    ys, xs = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    xs, ys, vals = xs.ravel() + 0.5, ys.ravel() + 0.5, img.ravel().astype(np.float64)
    rel = np.abs(xs - cx) / a + np.abs(ys - cy) / b
    face0, bg0 = np.percentile(vals[rel < 0.7], 75), np.median(vals[rel > 1.3])
    keep = rel >= 0.5
    inf = np.inf
    p0 = np.array([cx, cy, a, b, 1.0, face0, bg0, 0.0, 0.0])
    lo = np.array([cx - 0.5 * a, cy - 0.5 * b, 0.5 * a, 0.5 * b, 0.3, -inf, -inf, -inf, -inf])
    hi = np.array([cx + 0.5 * a, cy + 0.5 * b, 2.0 * a, 2.0 * b, 4.0, inf, inf, inf, inf])
    return xs[keep], ys[keep], vals[keep], p0, lo, hi, 0.15 * (face0 - bg0)


def test_normal_equations_are_the_reweighted_jacobian_sums():
    """The pixel-by-pixel sums equal J^T W J and J^T W r of the numpy model's Jacobian, with
    the soft-L1 weights 1 / sqrt(1 + (r / c)^2), and the cost is the soft-L1 cost."""
    img = _sign(26.3, 24.1, 9.4, 10.2, 1.3)
    xs, ys, vals, _, _, _, c = _problem(img, (26.0, 24.0, 9.0, 10.0))
    p = np.array([26.1, 23.8, 9.1, 10.4, 1.6, 140.0, 22.0, 0.3, -0.1])
    model, jac = _blurred_diamond(p, xs, ys, jac=True)
    r = model - vals
    w = 1.0 / np.sqrt(1.0 + (r / c) ** 2)
    mat, vec = np.empty((9, 9)), np.empty(9)
    cost = normal_equations(p, xs, ys, vals, c, mat, vec)
    assert np.allclose(mat, jac.T @ (w[:, None] * jac), rtol=1e-9, atol=1e-6)
    assert np.allclose(vec, jac.T @ (w * r), rtol=1e-9, atol=1e-6)
    assert cost == pytest.approx(float(np.sum(c * c * (np.sqrt(1.0 + (r / c) ** 2) - 1.0))))


@pytest.mark.parametrize('a, b, sigma, off', [
    (9.3, 10.1, 1.0, (1.0, -0.8)), (9.3, 10.1, 2.5, (-0.6, 0.9)), (7.2, 8.8, 1.8, (0.4, 0.4)),
    (10.0, 9.0, 0.6, (-1.2, 0.3))])
def test_the_fit_finds_scipys_diamond(a, b, sigma, off):
    """From the mask's typical start (15 % small, about 1 px off), the compiled fit ends
    where SciPy's trust-region fit of the same cost ends: centre and half-diagonals within
    0.02 px, blur within 0.02 px, and both converged."""
    cx, cy = 26.3, 24.1
    img = _sign(cx, cy, a, b, sigma)
    xs, ys, vals, p0, lo, hi, c = _problem(img, (cx + off[0], cy + off[1], 0.85 * a, 0.85 * b))
    p, status, nfev = lm_fit(xs, ys, vals, p0, lo, hi, c, 60, 1e-4, 1e-4)
    ref = least_squares(lambda q: _blurred_diamond(q, xs, ys)[0] - vals, p0,
                        jac=lambda q: _blurred_diamond(q, xs, ys, jac=True)[1],
                        bounds=(lo, hi), loss='soft_l1', f_scale=c, x_scale='jac',
                        max_nfev=200, xtol=1e-10, ftol=1e-10)
    assert status > 0 and ref.status > 0 and nfev < 60
    assert np.max(np.abs(p[:5] - ref.x[:5])) < 0.02, (p[:5], ref.x[:5])
    assert max(abs(p[0] - cx), abs(p[1] - cy)) < 0.3


def test_the_fit_stays_within_its_bounds_and_reports_no_convergence():
    """A start far off on a window without a sign keeps every parameter within the bounds;
    too few evaluations is status 0 (the caller's "no fit")."""
    img = np.random.default_rng(2).normal(20.0, 3.0, (40, 40))
    xs, ys, vals, p0, lo, hi, c = _problem(img, (20.0, 20.0, 8.0, 8.0))
    c = max(c, 1.0)
    p, status, _ = lm_fit(xs, ys, vals, p0, lo, hi, c, 60, 1e-4, 1e-4)
    assert np.all(p >= lo) and np.all(p <= hi)
    sign = _sign(26.3, 24.1, 9.3, 10.1, 2.0)
    xs, ys, vals, p0, lo, hi, c = _problem(sign, (27.0, 23.0, 8.0, 8.5))
    assert lm_fit(xs, ys, vals, p0, lo, hi, c, 2, 1e-4, 1e-4)[1] == 0
    assert not math.isnan(float(lm_fit(xs, ys, vals, p0, lo, hi, c, 60, 1e-4, 1e-4)[0][0]))
