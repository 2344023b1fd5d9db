"""The blurred edge model of a sign's face, border line and margin.

A face's edge is measured on the brightness: the median of its profiles along the edge's
normal is fitted with a face / black border line / outer margin / background step model,
blurred by a Gaussian, over a grid of edge offsets and blur widths.  Used by the diamond
(:mod:`.diamond`) and rectangle (:mod:`.rectangle`) fits.
"""
from __future__ import annotations

import functools
from typing import Optional, Sequence

import cv2
import numpy as np
from scipy.special import ndtr

from workzone_ros.core.edge_kernels import edge_fit, valid_models
from workzone_ros.core.kernels import edge_choice, profile_medians

__all__ = ['EDGE_MIN_CONTRAST']


_PROFILE_U0 = np.arange(-3.0, 3.0 + 1e-6, 0.1, dtype=np.float32)
_PROFILE_SIG = np.array([0.45, 0.65, 0.9, 1.2, 1.6], np.float32)


@functools.lru_cache(maxsize=256)
def _profile_bases(u_out: float, u_in: float, border: float, margin: float) -> tuple:
    """Blurred step-profile bases of a sign edge and their normal-equation inverses.

    Samples ``u`` every quarter pixel from ``-u_out`` (outside) to ``u_in`` (inside).  For
    every edge offset ``u0`` in :data:`_PROFILE_U0` and blur width in :data:`_PROFILE_SIG`:
    a face at ``u > u0`` (level ``hi``), the black border line ``border`` px wide outside it
    (``lo``), a thin outer margin of the face's colour ``margin`` px wide (``hi``), then the
    background (``bg``), each step blurred by a Gaussian (optics, motion and the pixel's own
    width).  Returns ``(u, bases, inv(bases^T bases) (k, 3, 3), valid (k,), models)``; the
    profile is a linear combination of the hi, lo and bg bases (returned transposed, (k * 3,
    len(u)), for one matrix product per profile); ``models``: the valid ones' arrays as the
    compiled fit takes them (:func:`edge_kernels.valid_models`).
    """
    u = np.arange(-u_out, u_in + 1e-6, 0.25, dtype=np.float64)
    d = u[None, None, :] - _PROFILE_U0.astype(np.float64)[:, None, None]
    sg = _PROFILE_SIG.astype(np.float64)[None, :, None]
    f_in = ndtr(d / sg)
    f_bl = ndtr((d + border) / sg)
    f_mg = ndtr((d + border + margin) / sg)
    bases = np.stack(np.broadcast_arrays(f_in + (f_mg - f_bl), f_bl - f_in, 1.0 - f_mg),
                     axis=-1).reshape(-1, u.size, 3)
    ata = np.einsum('kui,kuj->kij', bases, bases) + 1e-6 * np.eye(3)
    # offsets that leave at least a pixel of face inside and of background outside
    ok = (_PROFILE_U0 <= u_in - 1.0) & (_PROFILE_U0 >= border + margin + 1.0 - u_out)
    bases_t = np.ascontiguousarray(bases.transpose(0, 2, 1).reshape(-1, u.size))
    ata_inv, valid = np.linalg.inv(ata), np.repeat(ok, _PROFILE_SIG.size)
    return u, bases_t, ata_inv, valid, valid_models(bases_t, ata_inv, valid)


def _valid_models(prof: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`edge_kernels.valid_models` of a :func:`_profile_bases` tuple (made with it, so
    once per cached tuple)."""
    return prof[4]


def _edge_profile(extent: float, border: float, margin: float) -> tuple:
    """:func:`_profile_bases` for a face ``extent`` px from its middle to its edge (inside
    samples reach a fifth of it, 1.5-3.5 px, plus a pixel) with the line and margin outside
    (plus 2.5 px of background); widths rounded so that faces of about the same size share
    the cached bases."""
    u_in = round(2 * min(max(1.5, 0.2 * extent), 3.5)) / 2 + 1.0
    u_out = round(4 * (border + margin)) / 4 + 2.5
    return _profile_bases(u_out, u_in, round(4 * border) / 4, round(4 * margin) / 4)


@functools.lru_cache(maxsize=256)
def _unit_steps(n: int) -> np.ndarray:
    """``np.linspace(0, 1, n)``, read-only (the sample positions along an edge stretch)."""
    ts = np.linspace(0.0, 1.0, n)
    ts.flags.writeable = False
    return ts


def _taper(spec: Sequence[float], x: float) -> float:
    """``spec = (px, x0, x1)``: ``px`` at ``x <= x0``, none from ``x1``, linear between (0
    when ``px`` is 0).  The shift of ``DetectorConfig.diamond_bright_bias`` by the border
    line's width (px), and of ``rect_dim_bias`` by the plaque's brightness.

    ``diamond_bright_bias``: an edge stretch whose fitted background is brighter than the
    face is taken this much further out.  A line and margin under a pixel wide, blurred,
    leave only a shallow dip between a background brighter than the face and the face,
    and the edge model places the edge further in than it is there: the catalogue art
    drawn over grey (luma 60 -> 240, the face's about 100), blurred 0.6 px, measures a
    14 px diamond's half-diagonal 0.34 px less and a 16 px one's 0.22 px less (18 px and
    more: no difference); on the simulator's frames small signs come out 0.2-0.4 px short
    against bright backgrounds up to about 30 px."""
    px, x0, x1 = (float(v) for v in spec)
    if px == 0.0:
        return 0.0
    return px * min(1.0, max(0.0, (x1 - x) / max(x1 - x0, 1e-9)))


def _edge_offsets(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, prof: tuple,
                  min_contrast: float, missing: bool = False,
                  blur: Optional[np.ndarray] = None,
                  levels: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
    """Offsets (px, along each inward normal) of the face edge on several edge stretches.

    ``segs`` (n, 2, 2): each stretch's end points; ``nvecs`` (n, 2): its inward unit
    normal.  Per stretch: the median of its brightness profiles along the normal (bilinear,
    every quarter pixel), the best fit of the edge model over the offset x blur grid of
    :func:`_profile_bases`, a parabola through the neighbouring offsets.  None when a
    stretch lies outside ``img`` or shows no face-to-border step (contrast below
    ``min_contrast`` of the face at every offset); with ``missing`` such a stretch's offset
    is NaN instead (None when no stretch shows one).  ``blur`` (n,), when given, receives
    each stretch's fitted blur width (px, NaN without a step); ``levels`` (n, 2), when
    given, its fitted face and background levels (NaN without a step).
    """
    u, bases_t, ata_inv, valid = prof[:4]
    length = float(np.hypot(*(segs[0, 1] - segs[0, 0])))
    ts = _unit_steps(max(3, int(length) + 1))
    n = segs.shape[0]
    if img.dtype == np.float32 and img.ndim == 2 and n >= 2:
        # compiled, the same arithmetic (:func:`edge_kernels.edge_fit`; one stretch's
        # products are numpy's matrix-vector ones, summed otherwise)
        off, best = np.empty(n), np.empty(n, np.int64)
        b_, lv = np.empty(n), np.empty((n, 2))
        seen = edge_fit(img, np.ascontiguousarray(segs, np.float64),
                        np.ascontiguousarray(nvecs, np.float64), u, ts, *_valid_models(prof),
                        valid, float(min_contrast), _PROFILE_U0, _PROFILE_SIG, off, best,
                        b_, lv, n - 1 if missing else 0)
        if seen != -2:
            if seen < 0 or not (seen > 0 if missing else seen == n):
                return None
            if blur is not None:
                blur[:] = b_
            if levels is not None:
                levels[:] = lv
            return off
    return _edge_offsets_numpy(img, segs, nvecs, prof, min_contrast, ts, missing, blur,
                               levels)


def _edge_offsets_numpy(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, prof: tuple,
                        min_contrast: float, ts: np.ndarray, missing: bool,
                        blur: Optional[np.ndarray], levels: Optional[np.ndarray]
                        ) -> Optional[np.ndarray]:
    """:func:`_edge_offsets` in numpy and OpenCV (one stretch, an image of another type than
    float32, or a sample point that is not a number); ``ts``: the sample positions along a
    stretch."""
    u, bases_t, ata_inv, valid = prof[:4]
    # the sample points ``s0 + t (s1 - s0) + u n`` (n, t, u): the part along the stretch
    # (n, t) and the part along the normal (n, u) each once, then summed per point in that
    # order (the same sums as over the broadcast (n, t, u, 2) points, at a fraction of the
    # multiplications)
    along = segs[:, None, 0, :] + ts[None, :, None] * (segs[:, 1] - segs[:, 0])[:, None, :]
    across = u[None, :, None] * nvecs[:, None, :]
    mx = (along[:, :, None, 0] + across[:, None, :, 0] - 0.5).astype(np.float32)
    my = (along[:, :, None, 1] + across[:, None, :, 1] - 0.5).astype(np.float32)
    h, w = img.shape[:2]
    if mx.min() < 0 or my.min() < 0 or mx.max() > w - 1 or my.max() > h - 1:
        return None
    n, nt, nu = mx.shape
    samples = cv2.remap(img, mx.reshape(n * nt, nu), my.reshape(n * nt, nu), cv2.INTER_LINEAR)
    prof_v = profile_medians(samples, n, nt)                                    # (n, u)
    atb = (bases_t @ prof_v.T).reshape(-1, 3, n)                                # (k, 3, n)
    coef = ata_inv @ atb
    # per stretch: the best model among those showing a step (the border line is dark: a
    # plain step is the face's edge against a background as dark as the line, never the
    # margin's outer edge with a line as bright as the face), its offset moved by the
    # parabola through its neighbours' residuals (compiled: :func:`kernels.edge_choice`)
    off = np.empty(n)
    best = np.empty(n, np.int64)
    seen = edge_choice(prof_v, atb, coef, valid, float(min_contrast), _PROFILE_U0,
                       _PROFILE_SIG.size, off, best)
    if not (seen > 0 if missing else seen == n):
        return None
    if blur is not None or levels is not None:
        shown = best >= 0
        k = np.where(shown, best, 0)
        if blur is not None:
            blur[:] = np.where(shown, _PROFILE_SIG[k % _PROFILE_SIG.size], np.nan)
        if levels is not None:
            cols = np.arange(n)
            levels[:] = np.where(shown[:, None], np.stack([coef[k, 0, cols], coef[k, 2, cols]],
                                                         axis=1), np.nan)
    return off


# the smallest face-to-line contrast (a share of the face's brightness) an edge must show
EDGE_MIN_CONTRAST = 0.25
