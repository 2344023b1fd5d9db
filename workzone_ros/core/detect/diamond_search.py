"""A warning sign's diamond where its mask gives no start.

:func:`fit_blurred_diamond` fits a blurred diamond to the chroma R - B of a faded or blurred
sign that shows no line; :func:`diamond_holds` checks that a fitted outline holds the blob's
orange.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np
from scipy.special import ndtr

from workzone_ros.core.chroma_fit import lm_fit

__all__ = ['diamond_holds', 'fit_blurred_diamond']


#: :func:`fit_blurred_diamond` fits within this many half-diagonals of the start's centre
FIT_REACH = 3.0
#: a fitted sign keeps at least this share of the window's contrast (its middle's upper
#: quartile less the median beyond the start's outline)
MIN_CONTRAST_KEPT = 0.5


def diamond_holds(pixels: np.ndarray, face: Sequence[float], ratio: float, share: float,
                  slack_px: float = 1.0) -> bool:
    """Whether the sign outline ``ratio`` x the face diamond ``(cx, cy, a, b)`` (continuous
    coordinates) holds the nonzero ``pixels`` (their centres; the outline grown by
    ``slack_px``): False when in three or four of the diamond's quadrants less than
    ``share`` of the quadrant's pixels lie inside (a sign whose orange reaches out all
    round: not the catalogue's layout).  Orange beyond one or two sides (flags above a
    portable stand, a merge with an orange sky or a drum) does not count."""
    ys, xs = np.nonzero(pixels)
    if xs.size == 0:
        return True
    cx, cy, a, b = (float(v) for v in face[:4])
    dx, dy = xs + 0.5 - cx, ys + 0.5 - cy
    out = np.abs(dx) / (ratio * a + slack_px) + np.abs(dy) / (ratio * b + slack_px) > 1.0
    quad = (dx > 0).astype(np.int64) + 2 * (dy > 0)
    n = np.bincount(quad, minlength=4)
    n_out = np.bincount(quad, weights=out, minlength=4)
    return int(np.count_nonzero(n_out > (1.0 - share) * np.maximum(n, 1))) < 3


def _blurred_diamond(p: np.ndarray, xs: np.ndarray, ys: np.ndarray, jac: bool = False
                     ) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """The blurred diamond model of :func:`fit_blurred_diamond` at ``(xs, ys)`` and, with
    ``jac``, its Jacobian (n, 9) in ``p = (cx, cy, a, b, sigma, face, bg, gx, gy)``."""
    cx, cy, a, b, sg, face, bg, gx, gy = (float(v) for v in p)
    r2 = a * a + b * b
    n = a * b / math.sqrt(r2)
    dx, dy = xs - cx, ys - cy
    u, v = dx / a, dy / b
    # signed distances inside the four edges; the blurred indicator of the diamond is the
    # product of the edges' blurred half-planes (exact at a right-angled corner)
    signs = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
    z = np.stack([(1.0 - sx * u - sy * v) * (n / sg) for sx, sy in signs])     # (4, n)
    cdf = ndtr(z)
    prod = cdf.prod(axis=0)
    contrast = face - bg
    model = bg + gx * dx + gy * dy + contrast * prod
    if not jac:
        return model, None
    pdf = np.exp(-0.5 * z * z) * (1.0 / math.sqrt(2.0 * math.pi))
    # d prod / d z_i: the edge's density times the other three edges' blurred half-planes
    others = np.stack([np.prod(np.delete(cdf, i, axis=0), axis=0) for i in range(4)])
    dp_dz = pdf * others                                                      # (4, n)
    dn_da, dn_db = b ** 3 / r2 ** 1.5, a ** 3 / r2 ** 1.5
    out = np.empty((xs.size, 9))
    g = np.zeros((5, xs.size))
    for i, (sx, sy) in enumerate(signs):
        lin = 1.0 - sx * u - sy * v
        g[0] += dp_dz[i] * (sx * n / (a * sg))
        g[1] += dp_dz[i] * (sy * n / (b * sg))
        g[2] += dp_dz[i] * ((sx * u / a) * n + lin * dn_da) / sg
        g[3] += dp_dz[i] * ((sy * v / b) * n + lin * dn_db) / sg
        g[4] += dp_dz[i] * (-z[i] / sg)
    out[:, :5] = contrast * g.T
    out[:, 0] -= gx
    out[:, 1] -= gy
    out[:, 5] = prod
    out[:, 6] = 1.0 - prod
    out[:, 7] = dx
    out[:, 8] = dy
    return model, out


def fit_blurred_diamond(chroma: np.ndarray, start: Sequence[float], max_sigma: float = 4.0,
                        robust: float = 0.15, inner_skip: float = 0.5, max_nfev: int = 60,
                        max_half: float = 10.0
                        ) -> Optional[tuple[float, float, float, float, float, float, float]]:
    """The sign's orange diamond fitted to a blurred chroma image, where its edges are not.

    A faded, rain-washed or motion-blurred sign may show no border line in the brightness
    (:func:`refine_diamond` finds no face-to-line step) and its colour mask stops well short
    of the tips.  Its colour does still place the sign: ``chroma`` (R - B, a linear
    function of a blend of the sign's and the background's colours) is modelled as a
    background plane plus the sign's uniform level times the diamond ``|x - cx| / a +
    |y - cy| / b <= 1`` blurred by a Gaussian of width ``sigma`` (the product of its four
    edges' blurred half-planes); all nine parameters by robust least squares (soft L1 at
    ``robust`` x the start's contrast: legend strokes and a post are outliers) from
    ``start = (cx, cy, a, b)`` (continuous coordinates, pixel ``i`` spans ``[i, i + 1)``),
    over the window less the start's middle (``inner_skip`` of its half-diagonals: the
    legend's place).  A sign larger than ``max_half`` px half-diagonal is fitted on the
    window binned by a whole factor (block means: still linear in the blend) to about that
    size: the cost is about the same for every size (a few ms).  The border line and the
    thin margin outside it blend with the edge: the fitted diamond lies between the sign's
    outline and the face's.  Not claimed: a legend blurred into a small face lowers the
    face's level and puts the edge further out (about 0.5 px at 9 px half-diagonal and
    1.5 px blur, 1 px at 2.5 px blur, on a test sign with a stroke down its middle).

    Returns ``(cx, cy, a, b, sigma, face, bg)`` or None: the fit did not converge, a
    half-diagonal reached half or twice the start's, the blur reached ``max_sigma``, or
    the sign's fitted contrast to its background is under ``MIN_CONTRAST_KEPT`` of the
    window's (a fit to noise).

    The least squares are :func:`workzone_ros.core.chroma_fit.lm_fit` (compiled; SciPy's
    ``least_squares`` reached the same diamond at about three times the cost).
    """
    cx, cy, a, b = (float(v) for v in start[:4])
    h, w = chroma.shape[:2]
    if a < 2 or b < 2 or h < 4 or w < 4:
        return None
    f = max(1, math.ceil(min(a, b) / max_half))
    if f > 1:
        h, w = h // f, w // f
        chroma = chroma[:h * f, :w * f].reshape(h, f, w, f).mean(axis=(1, 3))
        cx, cy, a, b, max_sigma = cx / f, cy / f, a / f, b / f, max_sigma / f
    # a window much larger than the diamond (a sign merged with a big orange surface) is cut
    # to FIT_REACH half-diagonals around it: far pixels only cost time, the background
    # plane is measured near the sign
    x0, y0 = max(0, int(cx - FIT_REACH * a)), max(0, int(cy - FIT_REACH * b))
    x1, y1 = min(w, int(math.ceil(cx + FIT_REACH * a))), min(h, int(math.ceil(cy + FIT_REACH * b)))
    if (x0, y0, x1, y1) != (0, 0, w, h):
        chroma = chroma[y0:y1, x0:x1]
        h, w, cx, cy = y1 - y0, x1 - x0, cx - x0, cy - y0
    ys, xs = np.mgrid[0:h, 0:w]
    xs = xs.ravel() + 0.5
    ys = ys.ravel() + 0.5
    vals = chroma.astype(np.float64).ravel()
    rel = np.abs(xs - cx) / a + np.abs(ys - cy) / b
    inner, outer = vals[rel < 0.7], vals[rel > 1.3]
    if inner.size < 4 or outer.size < 4:
        return None
    face0, bg0 = float(np.percentile(inner, 75)), float(np.median(outer))
    if face0 <= bg0:
        return None
    # the middle holds the legend, and only the face's level: fitted without it
    keep = rel >= inner_skip
    xs, ys, vals = xs[keep], ys[keep], vals[keep]
    p0 = np.array([cx, cy, a, b, 1.0, face0, bg0, 0.0, 0.0])
    inf = np.inf
    lo = np.array([cx - 0.5 * a, cy - 0.5 * b, 0.5 * a, 0.5 * b, 0.3, -inf, -inf, -inf, -inf])
    hi = np.array([cx + 0.5 * a, cy + 0.5 * b, 2.0 * a, 2.0 * b, max_sigma, inf, inf, inf, inf])
    if np.any(p0 < lo) or np.any(p0 > hi):
        return None         # a large sign binned to a blur limit under the start's
    p, status, _ = lm_fit(xs, ys, vals, p0, lo, hi, robust * (face0 - bg0), max_nfev,
                          1e-4, 1e-4)
    if status <= 0:
        return None
    fcx, fcy, fa, fb, fs, face, bg = (float(v) for v in p[:7])
    if face - bg < MIN_CONTRAST_KEPT * (face0 - bg0):
        return None         # a fit to noise: the window's own contrast fell away
    if not (0.505 * a < fa < 1.99 * a and 0.505 * b < fb < 1.99 * b and fs < 0.99 * max_sigma):
        return None
    return (fcx + x0) * f, (fcy + y0) * f, fa * f, fb * f, fs * f, face, bg
