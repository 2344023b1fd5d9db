"""Diamond fits of a warning sign: from its mask and from its edges.

:func:`fit_diamond` fits a tent to a blob's rows (and, in :func:`fit_diamond_2d`, columns);
:func:`refine_diamond` measures the face's four edges on the brightness at sub-pixel
precision (:mod:`.edges`) and fits the upright diamond through them (:func:`fit_rhombus`);
:func:`diamond_pixel_box` boxes the result in whole pixels, as labels are drawn.
"""
from __future__ import annotations

import functools
import itertools
import math
from typing import Callable, Optional, Sequence

import numpy as np

from workzone_ros.core.detect.edges import (
    _PROFILE_SIG,
    _PROFILE_U0,
    EDGE_MIN_CONTRAST,
    _edge_offsets,
    _edge_profile,
    _taper,
    _valid_models,
)
from workzone_ros.core.diamond_kernels import diamond_frame, diamond_round
from workzone_ros.core.kernels import NO_PIXEL, diamond_tent, rhombus_fit, tip_pixel

__all__ = [
    'fit_diamond', 'fit_diamond_2d', 'diamond_pixel_box', 'fit_rhombus',
    'START_SHIFT_PX', 'refine_shifted', 'frame_edges', 'start_shrink', 'refine_diamond',
]


@functools.lru_cache(maxsize=8)
def _slope_grid(lo: float, hi: float) -> np.ndarray:
    """:func:`fit_diamond`'s six tent slopes from ``lo`` to ``hi`` (read-only)."""
    ss = np.linspace(lo, hi, 6)
    ss.flags.writeable = False
    return ss


def fit_diamond(mask: np.ndarray, min_rows: int = 5, slopes: tuple[float, float] = (0.7, 1.4)
                ) -> Optional[tuple[float, float, float, float, float]]:
    """Fit a diamond (axis-aligned diagonals) to a blob: ``(cx, cy, a, b, inliers)``.

    A diamond ``|x - cx| / a + |y - cy| / b <= 1`` has half-width ``a - s |y - cy|`` at
    row ``y`` (``s = a / b``): a tent over the rows, centred on ``cx`` on every row.  A
    warning sign is a square diamond facing the road, so ``s`` lies near 1 (``slopes``:
    the range allowed, for yaw and lens distortion).  The tent is found by consensus: for
    every apex row ``cy`` on a grid (half a pixel, coarser for large blobs) and slope in
    ``slopes`` the peak ``a`` is the median over (at most ~24 of) the rows, and the
    (cy, s) with the most rows within ``max(1, a/10)`` px of the tent wins; least squares
    over those rows, the apex row on a quarter-pixel grid, refines it.  An appendage of the same
    colour (a portable stand's flags above the top corner, a post) does not follow the
    tent and is left out; corners thinned by blur are extrapolated from the straight
    edges.  ``inliers``: the share of the blob's rows on the tent.  Continuous
    coordinates (pixel ``i`` spans ``[i, i + 1)``).  None: fewer than ``min_rows`` rows
    or no tent.  Computed by the compiled :func:`~workzone_ros.core.kernels.diamond_tent`
    (numpy's arithmetic, the same values); ``mask``: any 2-d array, non-zero on the blob.
    """
    m = mask if mask.dtype == np.uint8 else (mask > 0).view(np.uint8)
    out = diamond_tent(np.ascontiguousarray(m), min_rows, _slope_grid(*slopes),
                       float(slopes[0]), float(slopes[1]))
    return None if math.isnan(out[0]) else tuple(out.tolist())


def fit_diamond_2d(mask: np.ndarray, min_rows: int = 5, rows: Optional[tuple] = None
                   ) -> Optional[tuple[float, float, float, float, float]]:
    """:func:`fit_diamond` over the rows and over the columns, combined.

    Each fit measures two things well: the peak of its tent (the half-width ``a`` from
    the rows, the half-height ``b`` from the columns: many rows or columns near the
    middle agree on it) and the centre across the tent (``cx`` from the rows' midpoints,
    ``cy`` from the columns'); the apex position along the tent and the slope, from the
    few short rows near the corners, are the noisy parts and are not used.  Returns
    ``(cx, cy, a, b, inliers)`` (the smaller inlier share) or None.  ``rows``: the row
    fit of this mask when already known.
    """
    fr = rows if rows is not None else fit_diamond(mask, min_rows)
    fc = fit_diamond(np.ascontiguousarray(mask.T), min_rows)
    if fr is None or fc is None:
        return None
    return fr[0], fc[0], fr[2], fc[2], min(fr[4], fc[4])


#: sub-pixel sample offsets for the coverage of a pixel (8 x 8 samples)
_SUBPIXEL = (np.arange(8) + 0.5) / 8


def _tip_pixel(c: float, r: float, c2: float, r2: float) -> Optional[int]:
    """The first pixel index, from the low side along one axis, of a pixel more than half
    covered by the diamond ``|x - c| / r + |y - c2| / r2 <= 1`` (``x`` along the axis,
    ``y`` across it), from the pixels about its tip (three across; along, a few and more for
    a narrow tip), or None when none of them is."""
    i = tip_pixel(c, r, c2, r2, _SUBPIXEL)
    return None if i == NO_PIXEL else i


def diamond_pixel_box(cx: float, cy: float, a: float, b: float) -> tuple[int, int, int, int]:
    """``(left, top, right, bottom)`` whole-pixel edges of the pixels more than half covered
    by the diamond ``|x - cx| / a + |y - cy| / b <= 1``, as a sign's pixel labels are drawn
    (its anti-aliased art's alpha above one half).  Along the edges that is the pixels whose
    centres lie inside (as :func:`pixel_box`); at a corner it takes more: a square diamond's
    tip covers half of a pixel on its middle row only when it reaches a quarter pixel past
    the pixel's centre (the wedge covers less than the pixel's half beyond its centre line),
    further on the rows above or below, so the box is on average about half a pixel per
    side inside the sub-pixel diamond's.  A diamond too small for any pixel to be half
    covered at a corner is boxed by the pixel centres it holds."""
    dy = abs(math.floor(cy) + 0.5 - cy)      # the pixel-centre row nearest the middle
    dx = abs(math.floor(cx) + 0.5 - cx)
    ha = a * max(0.0, 1.0 - dy / b)           # the diamond's half-width on that row
    hb = b * max(0.0, 1.0 - dx / a)
    left, right = math.ceil(cx - ha - 0.5), math.floor(cx + ha - 0.5) + 1
    top, bottom = math.ceil(cy - hb - 0.5), math.floor(cy + hb - 0.5) + 1
    if a > 0.5 and b > 0.5:
        tips = (_tip_pixel(cx, a, cy, b), _tip_pixel(cy, b, cx, a),
                _tip_pixel(-cx, a, cy, b), _tip_pixel(-cy, b, cx, a))
        left = left if tips[0] is None else tips[0]
        top = top if tips[1] is None else tips[1]
        right = right if tips[2] is None else -tips[2]
        bottom = bottom if tips[3] is None else -tips[3]
    return left, top, max(right, left + 1), max(bottom, top + 1)


# the (x, y) signs of the diamond's edges in refine_diamond's order: upper left, upper
# right, lower right, lower left
_RHOMBUS_SIGNS = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])
_STRETCH_SIGNS = np.repeat(_RHOMBUS_SIGNS, 2, axis=0)      # two stretches per edge
# the two stretches of each edge, as fractions of its length from its first corner
_STRETCH_FROM = np.array([0.15, 0.55])
_STRETCH_TO = np.array([0.45, 0.85])
# the same per edge (4, 2), and every stretch shown (read-only: each round uses them as
# they are unless an occluder hides some, when :func:`_stretches_above` makes new ones)
_EDGE_FROM = np.tile(_STRETCH_FROM, (4, 1))
_EDGE_TO = np.tile(_STRETCH_TO, (4, 1))
_ALL_SHOWN = np.ones(8, bool)
_EDGE_FROM.flags.writeable = _EDGE_TO.flags.writeable = _ALL_SHOWN.flags.writeable = False


def fit_rhombus(points: np.ndarray, signs: np.ndarray, outlier_px: float = 1.0,
                max_drop: int = 2) -> Optional[tuple[float, float, float, float]]:
    """Least-squares upright diamond ``|x - cx| / a + |y - cy| / b = 1`` through edge points.

    ``points`` (n, 2): points measured on the diamond's edges; ``signs`` (n, 2): the edge
    each lies on, as the signs of ``x - cx`` and ``y - cy`` on it.  The edge equation is
    linear in ``(1/a, 1/b, cx/a, cy/b)``; points further than ``outlier_px`` (or 7 % of the
    smaller half-diagonal) from the outline fitted without them are dropped one at a time,
    worst first (a legend stroke near an edge, a pole across it), at most ``max_drop``,
    while every edge keeps a point.  Returns ``(cx, cy, a, b)`` or None (degenerate, or still
    inconsistent).  Computed by the compiled :func:`~workzone_ros.core.kernels.rhombus_fit`."""
    out = rhombus_fit(np.ascontiguousarray(points, np.float64),
                      np.ascontiguousarray(signs, np.float64), float(outlier_px), int(max_drop))
    return None if math.isnan(out[0]) else tuple(out.tolist())


#: how far (px, along x and y) :func:`refine_shifted` moves a start: half the edge search's
#: width on a large face (offsets -1.5 to 3 px)
START_SHIFT_PX = 2.25


def refine_shifted(starts: Sequence[Sequence[float]],
                   refine: Callable[[tuple], Optional[tuple]],
                   accept: Optional[Callable[[tuple], tuple]] = None,
                   step: float = START_SHIFT_PX) -> Optional[tuple]:
    """``refine`` (e.g. :func:`refine_diamond` on a brightness window) from each of
    ``starts`` ``(cx, cy, a, b)`` moved by ``step`` px in the eight directions: the edges'
    search reaches only a few pixels, so a large face's start a few pixels off (a mask that
    took in a surface of the sign's colour beside it) fails however clear the face.  Of the
    fits ``accept`` keeps (it returns ``(fit or None, verdict)``), the smallest: a start too
    large also fits the sign's outer edge (its margin against the background) or its
    line's, both outside the face's edge (a fit inside it is rarer).  Returns ``(fit,
    verdict)`` (verdict None without ``accept``) or None when no moved start fits."""
    best, best_area = None, math.inf
    for st in starts:
        for ddx, ddy in itertools.product((-1, 0, 1), repeat=2):
            if ddx == 0 and ddy == 0:
                continue                        # (the caller tried it as it is)
            fit = refine((st[0] + ddx * step, st[1] + ddy * step, st[2], st[3]))
            if fit is None or fit[2] * fit[3] >= best_area:
                continue
            got = (fit, None) if accept is None else accept(fit)
            if got[0] is not None:
                best, best_area = (got[0], got[1]), got[0][2] * got[0][3]
    return best


def frame_edges(x: float, y: float, w: float, h: float, width: int, height: int,
                tol: float = 0.0) -> tuple[bool, bool, bool, bool]:
    """Which edges of a ``width`` x ``height`` frame the box ``(x, y, w, h)`` reaches
    (within ``tol`` px): ``(left, top, right, bottom)``."""
    return (x <= tol, y <= tol, x + w >= width - tol, y + h >= height - tol)


def start_shrink(border_rel: float, margin_rel: float) -> float:
    """The factor :func:`refine_diamond` applies to its start's half-diagonals: half-way
    from an outline with the line and margin to the face without them."""
    return 1.0 - 0.5 * (border_rel + margin_rel) * math.sqrt(2)


def refine_diamond(value: np.ndarray, fit: Sequence[float], border_rel: float = 0.0676,
                   margin_rel: float = 0.022, max_change: float = 0.15,
                   min_contrast: float = EDGE_MIN_CONTRAST, iterations: int = 2,
                   aspect: tuple[float, float] = (0.75, 1.2), outlier_px: float = 1.0,
                   max_lost: int = 2, info: Optional[dict] = None,
                   hidden_below: Optional[float] = None, stroke_steps: int = 0,
                   bright_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
                   ) -> Optional[tuple[float, float, float, float]]:
    """Sub-pixel edges of a warning diamond's orange face from the brightness image.

    ``fit = (cx, cy, a, b)``: a first estimate of the face's diamond (continuous
    coordinates, pixel ``i`` spans ``[i, i + 1)``), e.g. :func:`fit_diamond_2d` on the face
    mask.  The colour table cannot place the face's edge: a blend of the orange face and the
    black border line keeps the face's hue and saturation and only gets darker, so the mask
    ends wherever the value gate happens to cut the blend.  The brightness does place it:
    each of the four edges is measured on two stretches (15-45 % and 55-85 % of its length,
    away from the corners), each by the median of its brightness profiles along the edge's
    normal (legend strokes and noise drop out) fitted with the edge model of
    :func:`_profile_bases` (face, border line ``border_rel`` x a wide, outer margin
    ``margin_rel`` x a, background, each with its own level: a headlight's hot spot or a
    bright sky behind one edge does not bias it).  The eight edge points give the diamond by
    least squares (:func:`fit_rhombus`: a point more than ``outlier_px`` off the diamond
    fitted to the others, a legend stroke or a big symbol next to the edge taken for it, is
    dropped; so is a stretch without a face-to-border step, a symbol reaching the edge: at
    most ``max_lost`` points in all); ``iterations`` rounds.
    The defaults are the catalogue's diamond art: the border line's inner edge at 0.888 of
    the half-diagonal, the line 0.06 of the half-diagonal wide (normal to the edge), the
    orange margin outside it.

    ``stroke_steps``: a stretch whose fitted blur is at least this many steps of the edge
    model's blur grid (0.45, 0.65, 0.9, 1.2, 1.6 px) wider than the median of the sign's
    stretches is a legend stroke running into the face's edge there (a lane-shift arrow's
    head, a lane-ends line: the dark stroke beside the border line reads as a wide, soft
    step 0.5-1.5 px inside the edge, often still within ``outlier_px`` of the others);
    it counts as one of the lost points, the widest first, while at most ``max_lost`` are
    lost and each edge keeps a stretch; when the points left then do not agree on a
    diamond, the round is fitted with them kept, and when the refinement fails after
    leaving any out, it is done again without the test (as with 0 = off).

    ``bright_bias``: an edge stretch whose fitted background is brighter than the face is
    taken further out on a small face (:func:`_taper`).

    ``info``, when given, receives ``blur``: the median of the edge stretches' fitted blur
    widths (px) in the last round.

    ``hidden_below``: an occluder (a guardrail, a car's roof) hides the face from this row
    down.  The lower edges are then measured only above it: each lower edge's stretch
    nearest its side corner runs from 10 % of the edge to where its profiles would reach
    the occluder (a pixel above its edge), and a stretch left shorter than 10 % of the
    edge, or any stretch reaching the occluder, is not measured (not one of the points
    the fit may drop: it was never seen).

    Returns ``(cx, cy, a, b)`` or None when a stretch shows no face-to-border step
    (contrast below ``min_contrast`` of the face's brightness: washed out, heavily blurred)
    or lies outside ``value``, the edge points do not agree on a diamond, a half-diagonal
    moves by more than ``max_change`` from the estimate's, or the result is no diamond facing
    the road (``a / b`` outside ``aspect``: turned away by up to ~40 deg, rolled or
    distorted a little).
    """
    used = [False]
    out = _refine_diamond_rounds(value, fit, border_rel, margin_rel, max_change, min_contrast,
                                 iterations, aspect, outlier_px, max_lost, info, hidden_below,
                                 stroke_steps, used, bright_bias)
    if out is None and used[0]:
        out = _refine_diamond_rounds(value, fit, border_rel, margin_rel, max_change,
                                     min_contrast, iterations, aspect, outlier_px, max_lost,
                                     info, hidden_below, 0, used, bright_bias)
    return out


def _refine_diamond_rounds(value: np.ndarray, fit: Sequence[float], border_rel: float,
                           margin_rel: float, max_change: float, min_contrast: float,
                           iterations: int, aspect: tuple[float, float], outlier_px: float,
                           max_lost: int, info: Optional[dict], hidden_below: Optional[float],
                           stroke_steps: int, used: list,
                           bright_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
                           ) -> Optional[tuple[float, float, float, float]]:
    """:func:`refine_diamond`'s rounds; ``used[0]`` is set when a round's fit left out a
    stroke's stretches."""
    cx, cy, a, b = (float(v) for v in fit[:4])
    a_in, b_in = a, b
    if a < 3 or b < 3:
        return None
    # start half-way between the estimate and the face's edge without margin and line
    # (a mask that took in the orange margin): the face's edge is within the search
    # either way
    shrink = start_shrink(border_rel, margin_rel)
    a, b = a * shrink, b * shrink
    img = np.ascontiguousarray(value, dtype=np.float32)
    for _ in range(iterations):
        m = min(a, b)
        border = border_rel * m
        prof = _edge_profile(m, border, margin_rel * m)
        # the four edges (left corner to top, top to right, right to bottom, bottom to
        # left), two stretches on each
        f_from, f_to, shown = _EDGE_FROM, _EDGE_TO, _ALL_SHOWN
        if hidden_below is not None:
            p0, e, nvec = diamond_frame(cx, cy, a, b)
            f_from, f_to, shown = _stretches_above(p0, e, nvec, f_from, f_to, prof[0],
                                                   hidden_below - 1.0)
            if not shown.any():
                return None
        got = _round_edges(img, (cx, cy, a, b), (f_from, f_to, shown), prof, min_contrast,
                           _taper(bright_bias, border), max_lost)
        if got is None:
            return None
        mids, nv, off, blur, lost = got
        seen = np.isfinite(off)
        fit_ = None
        if stroke_steps > 0:
            # without the stretches a stroke runs into, unless the rest then disagree
            drop = _stroke_stretches(blur, seen, max_lost - lost, stroke_steps)
            if drop.any():
                s_seen = seen & ~drop
                fit_ = fit_rhombus(mids[s_seen] + off[s_seen, None] * nv[s_seen],
                                   _STRETCH_SIGNS[s_seen], outlier_px,
                                   max_lost - lost - int(np.count_nonzero(drop)))
                used[0] = used[0] or fit_ is not None
        if fit_ is None:
            q = mids[seen] + off[seen, None] * nv[seen]
            fit_ = fit_rhombus(q, _STRETCH_SIGNS[seen], outlier_px, max_lost - lost)
        if fit_ is None:
            return None
        cx, cy, a, b = fit_
        if not (abs(a / a_in - 1) <= max_change and abs(b / b_in - 1) <= max_change
                and aspect[0] <= a / b <= aspect[1]):
            return None
    if info is not None:
        # the last round's stretches (np.nanmedian's value: the median of the measured
        # ones; at least one is, or the round returned)
        info['blur'] = float(np.median(blur[~np.isnan(blur)]))
    return cx, cy, a, b


def _round_edges(img: np.ndarray, diamond: tuple, stretches: tuple, prof: tuple,
                 min_contrast: float, bright: float, max_lost: int) -> Optional[tuple]:
    """One round of :func:`refine_diamond` from ``diamond = (cx, cy, a, b)`` on the float32
    brightness ``img``: the edge stretches ``stretches = (f_from, f_to, shown)`` measured
    (compiled: :func:`~workzone_ros.core.diamond_kernels.diamond_round`; numpy's path for
    fewer than two stretches).  Returns ``(mids, nv, off, blur, lost)``: the eight
    stretches' middles and inward normals, their offsets and blur widths (NaN: not shown or
    no face-to-border step) and how many shown show no step (a symbol or legend reaching
    the edge: one of the points the fit may drop); None when the round fails (a stretch
    outside ``img``, none with a step, or more than ``max_lost`` without one)."""
    f_from, f_to, shown = stretches
    lost, segs, mids, nv, off, blur = diamond_round(
        img, *diamond, f_from, f_to, shown, prof[0], *_valid_models(prof), prof[3],
        float(min_contrast), _PROFILE_U0, _PROFILE_SIG, float(bright), int(max_lost))
    if lost == -2:
        b_ = np.empty(int(shown.sum()))
        lv = np.empty((b_.size, 2)) if bright > 0 else None
        o_ = _edge_offsets(img, segs[shown], nv[shown], prof, min_contrast, missing=True,
                           blur=b_, levels=lv)
        if o_ is None:
            return None
        if lv is not None:
            # (NaN levels compare False: a stretch without a step stays NaN)
            o_ = o_ - bright * (lv[:, 1] > lv[:, 0])
        off[shown], blur[shown] = o_, b_
        lost = int(np.count_nonzero(shown & ~np.isfinite(off)))
    if lost < 0 or lost > max_lost:
        return None
    return mids, nv, off, blur, lost


def _stroke_stretches(blur: np.ndarray, seen: np.ndarray, spare: int, steps: int
                      ) -> np.ndarray:
    """:func:`refine_diamond`'s ``stroke_steps`` test on one round's eight stretches: the
    mask of those to leave out, the widest-blurred first, at most ``spare`` of them, each
    edge keeping one (``seen``: the stretches measured; ``blur``: their fitted blur)."""
    drop = np.zeros(seen.shape, bool)
    if spare <= 0 or np.count_nonzero(seen) <= 4:
        return drop
    level = np.searchsorted(_PROFILE_SIG, np.where(seen, blur, 0.0) - 1e-6)
    cut = np.median(level[seen]) + steps             # (np.median's value, float64)
    for j in np.argsort(-np.where(seen, level, -1), kind='stable'):
        if spare <= 0 or level[j] < cut:
            break
        if seen[j ^ 1] and not drop[j ^ 1]:    # the edge's other stretch is measured
            drop[j] = True
            spare -= 1
    return drop


def _stretches_above(p0: np.ndarray, e: np.ndarray, nvec: np.ndarray, f_from: np.ndarray,
                     f_to: np.ndarray, u: np.ndarray, limit: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`refine_diamond`'s stretches (fractions ``f_from``, ``f_to`` (4, 2) along its
    edges ``p0 + f e``, profiles sampled at ``u`` along the inward normals ``nvec``) kept
    above row ``limit``: a lower edge's stretch nearest its side corner ends where its
    profiles reach the row (at least 10 % of the edge long, from 10 %), any other stretch
    reaching it is dropped.  Returns the new fractions and which of the 8 stretches show."""
    f_from, f_to = f_from.copy(), f_to.copy()
    # the lowest row a profile at fraction f of edge i samples: the edge point's row plus
    # the normal's reach down (outwards or inwards, whichever goes lower); the outermost
    # 2 px of background may fall on the occluder (another background level at the
    # profile's end: it moves no edge)
    reach = np.maximum((u[0] + 2.0) * nvec[:, 1], u[-1] * nvec[:, 1])    # (4,)
    low = lambda f: p0[:, None, 1] + f * e[:, None, 1] + reach[:, None]   # noqa: E731
    for i in (2, 3):          # right corner to bottom, bottom to left corner
        if e[i, 1] == 0:
            continue
        # the fraction where the profiles reach the limit, and the near-corner stretch
        f_lim = (limit - reach[i] - p0[i, 1]) / e[i, 1]
        if i == 2:              # going down from the right corner: stretch 0 nearest it
            f_from[i, 0], f_to[i, 0] = 0.1, min(_STRETCH_TO[0], f_lim)
        else:                   # going up to the left corner: stretch 1 nearest it
            f_from[i, 1], f_to[i, 1] = max(_STRETCH_FROM[1], f_lim), 0.9
    shown = (np.maximum(low(f_from), low(f_to)) <= limit + 1e-6) & (f_to - f_from >= 0.1)
    return f_from, f_to, shown.reshape(8)
