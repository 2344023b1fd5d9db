"""Compiled inner loops of the colour detector (numba), with numpy's own arithmetic.

A warning sign's measurement (:mod:`workzone_ros.core.detect`) runs fits on arrays of a few
dozen values.  In numpy each step is a call costing microseconds of dispatch, more than its
arithmetic: a frame with a sign made some 2300 numpy calls, and a sign cost 2.3-2.7 ms.  The
loops here (the diamond's row tent, its tip pixels, the edge model's choice per stretch, the
rhombus through the edge points, the frame's white balance, the hysteresis' blob lookup, the
colour tables' lookup, the connected components' statistics) do the same arithmetic
compiled and in the same order, so they return
what the numpy code returned, bit for bit: sums are numpy's pairwise sums
(:func:`pairwise_sum`), float ranges are filled as ``np.arange`` fills them
(:func:`float_range`), a median is np.median's middle value or the mean of the middle two
(:func:`median_inplace`), float32 stays float32.  The one exception is :func:`rhombus_fit`,
whose 4 x 4 normal equations are summed and inverted here rather than by BLAS and LAPACK
(equal to rounding: 1.7e-8 px at worst on 72,000 perturbed point sets, the same points
dropped).
``test/core/test_kernels.py`` checks each against numpy.

Compiled on first use and cached beside this file (``cache=True``): 10-15 s once per install
(``python -m workzone_ros.core.kernels``, which ``make install`` runs), then about 0.5 s per
process to load them all.
"""
from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

__all__ = ['pairwise_sum', 'float_range', 'select_kth', 'median_inplace', 'diamond_tent',
           'rhombus_fit', 'tip_pixel', 'low_chroma_rounds', 'profile_medians', 'edge_choice',
           'label_at_first_pixel', 'flat_take', 'hue_sat_take', 'NO_PIXEL', 'label_stats',
           'components_with_stats']

#: :func:`tip_pixel`'s "no pixel" (an index no image has)
NO_PIXEL = -(1 << 62)


@njit(cache=True)
def pairwise_sum(a: np.ndarray) -> float:
    """``np.add.reduce`` of a 1-d float64 array: numpy's pairwise summation (fewer than 8
    values in turn; up to 128 in eight interleaved partial sums combined as a tree, the
    remainder after them in turn; more: the two halves, split at a multiple of 8)."""
    n = a.size
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[0], a[1], a[2], a[3]
        r4, r5, r6, r7 = a[4], a[5], a[6], a[7]
        i = 8
        while i < n - (n % 8):
            r0 += a[i]
            r1 += a[i + 1]
            r2 += a[i + 2]
            r3 += a[i + 3]
            r4 += a[i + 4]
            r5 += a[i + 5]
            r6 += a[i + 6]
            r7 += a[i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return pairwise_sum(a[:n2]) + pairwise_sum(a[n2:])


@njit(cache=True)
def float_range(start: float, stop: float, step: float) -> np.ndarray:
    """``np.arange(start, stop, step)`` of floats as numpy fills it: ``ceil((stop - start) /
    step)`` values, ``start``, ``start + step``, then ``start + i * delta`` with ``delta``
    the difference of those two."""
    n = max(int(math.ceil((stop - start) / step)), 0)
    out = np.empty(n)
    if n > 0:
        out[0] = start
    if n > 1:
        nxt = start + step
        delta = nxt - start
        out[1] = nxt
        for i in range(2, n):
            out[i] = start + i * delta
    return out


@njit(cache=True)
def select_kth(v: np.ndarray, n: int, k: int):
    """The k-th smallest of ``v[:n]`` (NaN-free), by Hoare selection; reorders ``v[:n]`` so
    that nothing before ``v[k]`` is larger and nothing after it smaller."""
    lo, hi = 0, n - 1
    while lo < hi:
        pivot = v[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while v[i] < pivot:
                i += 1
            while v[j] > pivot:
                j -= 1
            if i <= j:
                v[i], v[j] = v[j], v[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return v[k]


@njit(cache=True)
def median_inplace(v: np.ndarray, n: int) -> float:
    """np.median of ``v[:n]`` (NaN-free): the middle value, or the mean of the middle two
    (their sum in the array's type, halved: exact, so float32 data gives numpy's float32
    median); reorders ``v[:n]``."""
    k = n // 2
    mid = select_kth(v, n, k)
    if n % 2:
        return mid
    below = v[0]                        # everything before k is at most v[k]
    for q in range(1, k):
        if v[q] > below:
            below = v[q]
    return (below + mid) / 2


@njit(cache=True)
def _row_spans(mask: np.ndarray):
    """Every non-empty row of ``mask``, in order: ``(yc, half, mid, n)``, its centre height
    (row + 0.5), half width and middle column (from its first pixel to one past its last);
    only the first ``n`` entries are filled."""
    H, W = mask.shape
    yc = np.empty(H)
    half = np.empty(H)
    mid = np.empty(H)
    n = 0
    for r in range(H):
        left = -1
        for c in range(W):
            if mask[r, c] != 0:
                left = c
                break
        if left < 0:
            continue
        right = W - 1
        while mask[r, right] == 0:
            right -= 1
        right += 1
        yc[n] = r + 0.5
        half[n] = 0.5 * (float(right) - float(left))
        mid[n] = 0.5 * (float(right) + float(left))
        n += 1
    return yc, half, mid, n


@njit(cache=True)
def _tent_consensus(yc: np.ndarray, half: np.ndarray, n: int, slopes: np.ndarray):
    """The tent's consensus: the median peak of every (apex row, slope) over a subsample of
    the ``n`` rows, scored by the rows within max(1, 10 %) of it.  Returns ``(cys, step, ic,
    js, a0)``: the apex rows tried, their spacing, the best's apex row and slope indices and
    its peak half width (the first of the best, as np.argmax)."""
    stride = max(1, n // 24)
    nsub = (n + stride - 1) // stride
    step = max(0.5, (yc[n - 1] - yc[0]) / 20.0)
    cys = float_range(yc[0], yc[n - 1] + 0.01, step)
    hs = np.empty(nsub)
    dq = np.empty(nsub)
    col = np.empty(nsub)
    buf = np.empty(nsub)
    low = np.empty(nsub)
    for q in range(nsub):
        hs[q] = half[q * stride]
    best = -np.inf
    ic, js, a0 = 0, 0, 0.0
    for i in range(cys.size):
        for q in range(nsub):
            dq[q] = abs(yc[q * stride] - cys[i])
        for j in range(slopes.size):
            sj = slopes[j]
            for q in range(nsub):
                col[q] = hs[q] + sj * dq[q]
                buf[q] = col[q]
            a = median_inplace(buf, nsub)
            tol = max(1.0, 0.1 * a)
            count = 0
            for q in range(nsub):
                res = abs(col[q] - a)
                if res <= tol:
                    count += 1
                low[q] = min(res, tol)
            score = count - 1e-3 * pairwise_sum(low)
            if score > best:                # the first of the best, as np.argmax
                best, ic, js, a0 = score, i, j, a
    return cys, step, ic, js, a0


@njit(cache=True)
def _tent_rows(yc: np.ndarray, half: np.ndarray, mid: np.ndarray, n: int, cy0: float,
               s0: float, a0: float):
    """The rows that agree with the consensus tent (apex row ``cy0``, slope ``s0``, peak
    ``a0``) to ``max(1, a0 / 10)``: ``(hk, yk, mk, n_keep)``, their half widths, centre
    heights and middle columns (the first ``n_keep`` entries)."""
    lim = max(1.0, 0.1 * a0)
    hk = np.empty(n)
    yk = np.empty(n)
    mk = np.empty(n)
    n_keep = 0
    for q in range(n):
        if abs(half[q] + s0 * abs(yc[q] - cy0) - a0) <= lim:
            hk[n_keep], yk[n_keep], mk[n_keep] = half[q], yc[q], mid[q]
            n_keep += 1
    return hk, yk, mk, n_keep


@njit(cache=True)
def _tent_least_squares(hk: np.ndarray, yk: np.ndarray, cy0: float, step: float, a0: float,
                        s0: float, s_lo: float, s_hi: float):
    """Least squares of the half widths ``hk`` over the heights ``yk`` (the consensus rows)
    as a tent, its apex row on a quarter-pixel grid around the consensus apex ``cy0``: the
    apex row, peak and slope of least squared error among those with a slope in ``[0.8
    s_lo, 1.25 s_hi]`` (the consensus ``cy0``, ``a0``, ``s0`` when none)."""
    n_keep = hk.size
    cyr = float_range(cy0 - step - 0.25, cy0 + step + 0.26, 0.25)
    hm = pairwise_sum(hk) / n_keep
    dd = np.empty(n_keep)
    d2 = np.empty(n_keep)
    dh = np.empty(n_keep)
    e2 = np.empty(n_keep)
    found = False
    best_sse, cy, aa, slope = 0.0, cy0, a0, s0
    for i in range(cyr.size):
        for q in range(n_keep):
            dd[q] = abs(yk[q] - cyr[i])
            d2[q] = dd[q] * dd[q]
            dh[q] = dd[q] * hk[q]
        dm = pairwise_sum(dd) / n_keep
        var = pairwise_sum(d2) / n_keep - dm * dm
        cov = pairwise_sum(dh) / n_keep - dm * hm
        slope_r = -cov / max(var, 1e-9)
        a_r = hm + slope_r * dm
        for q in range(n_keep):
            e = hk[q] - (a_r - slope_r * dd[q])
            e2[q] = e * e
        sse = pairwise_sum(e2)
        if var > 1e-9 and s_lo * 0.8 <= slope_r <= s_hi * 1.25 and (
                not found or sse < best_sse):
            found = True
            best_sse, cy, aa, slope = sse, cyr[i], a_r, slope_r
    return cy, aa, slope


@njit(cache=True)
def diamond_tent(mask: np.ndarray, min_rows: int, slopes: np.ndarray, s_lo: float,
                 s_hi: float) -> np.ndarray:
    """:func:`workzone_ros.core.detect.diamond.fit_diamond` on a C-contiguous uint8 mask (non-zero:
    the blob) with the tent slopes ``slopes`` (``s_lo``, ``s_hi``: their range): ``(cx, cy,
    a, b, inliers)``, all NaN for no fit.  The steps and their arithmetic are fit_diamond's
    (see there): the rows' spans (:func:`_row_spans`), the consensus tent
    (:func:`_tent_consensus`), the rows agreeing with it (:func:`_tent_rows`) and the least
    squares on them (:func:`_tent_least_squares`)."""
    out = np.full(5, np.nan)
    yc, half, mid, n = _row_spans(mask)
    if n < min_rows:
        return out
    cys, step, ic, js, a0 = _tent_consensus(yc, half, n, slopes)
    s0 = slopes[js]
    hk, yk, mk, n_keep = _tent_rows(yc, half, mid, n, cys[ic], s0, a0)
    if n_keep < min_rows:
        return out
    cy, aa, slope = _tent_least_squares(hk[:n_keep], yk[:n_keep], cys[ic], step, a0, s0,
                                        s_lo, s_hi)
    if aa <= 0:
        return out
    out[0] = median_inplace(mk, n_keep)
    out[1] = cy
    out[2] = aa
    out[3] = aa / slope
    out[4] = n_keep / n
    return out


@njit(cache=True)
def tip_pixel(c: float, r: float, c2: float, r2: float, sub: np.ndarray) -> int:
    """:func:`workzone_ros.core.detect.diamond._tip_pixel` (``sub``: the sub-pixel sample offsets);
    :data:`NO_PIXEL` for none."""
    i0 = math.floor(c - r)
    i1 = min(i0 + 4 + math.ceil(2.0 * r / r2), math.floor(c) + 1)
    j0 = math.floor(c2)
    ns = sub.size
    for col in range(i0, i1):
        cover = 0
        for row in range(j0 - 1, j0 + 2):
            inside = 0
            for p in range(ns):
                dx = abs((col + sub[p]) - c) / r
                for q in range(ns):
                    if dx + abs((row + sub[q]) - c2) / r2 <= 1.0:
                        inside += 1
            cover = max(cover, inside)
        if 2 * cover > ns * ns:
            return col
    return NO_PIXEL


@njit(cache=True)
def _inverse4(m: np.ndarray) -> np.ndarray:
    """The inverse of a 4 x 4 matrix by Gauss-Jordan elimination with partial pivoting (an
    empty array when it is singular)."""
    a = m.copy()
    inv = np.eye(4)
    for c in range(4):
        p = c
        for r in range(c + 1, 4):
            if abs(a[r, c]) > abs(a[p, c]):
                p = r
        if a[p, c] == 0.0:
            return np.empty((0, 0))
        if p != c:
            for k in range(4):
                a[c, k], a[p, k] = a[p, k], a[c, k]
                inv[c, k], inv[p, k] = inv[p, k], inv[c, k]
        d = a[c, c]
        for k in range(4):
            a[c, k] /= d
            inv[c, k] /= d
        for r in range(4):
            if r != c and a[r, c] != 0.0:
                f = a[r, c]
                for k in range(4):
                    a[r, k] -= f * a[c, k]
                    inv[r, k] -= f * inv[c, k]
    return inv


@njit(cache=True)
def _rhombus_rows(points: np.ndarray, signs: np.ndarray):
    """The least squares' rows ``(sx x, sy y, -sx, -sy)`` of the edge points and each
    point's edge (0-3, by its signs)."""
    n = points.shape[0]
    rows = np.empty((n, 4))
    edge = np.empty(n, np.int64)
    for i in range(n):
        sx, sy = signs[i, 0], signs[i, 1]
        rows[i, 0] = sx * points[i, 0]
        rows[i, 1] = sy * points[i, 1]
        rows[i, 2] = -sx
        rows[i, 3] = -sy
        edge[i] = (1 if sx > 0 else 0) + (2 if sy > 0 else 0)
    return rows, edge


@njit(cache=True)
def _every_edge(keep: np.ndarray, edge: np.ndarray) -> bool:
    """Each of the four edges keeps a point."""
    has = np.zeros(4, np.bool_)
    for i in range(keep.size):
        if keep[i]:
            has[edge[i]] = True
    return has[0] and has[1] and has[2] and has[3]


@njit(cache=True)
def _rhombus_solve(rows: np.ndarray, keep: np.ndarray):
    """The kept rows' normal equations, summed and solved: ``(inverse, solution)``, the
    inverse empty when they are singular."""
    mtm = np.zeros((4, 4))
    rhs = np.zeros(4)
    for i in range(rows.shape[0]):
        if keep[i]:
            for j in range(4):
                rhs[j] += rows[i, j]
                for k in range(4):
                    mtm[j, k] += rows[i, j] * rows[i, k]
    inv = _inverse4(mtm)
    sol = np.zeros(4)
    if inv.size == 0:
        return inv, sol
    for j in range(4):
        for k in range(4):
            sol[j] += inv[j, k] * rhs[k]
    return inv, sol


@njit(cache=True)
def _worst_point(points: np.ndarray, signs: np.ndarray, rows: np.ndarray, keep: np.ndarray,
                 inv: np.ndarray, cx: float, cy: float, a: float, b: float):
    """The leave-one-out outlier test: ``(wi, worst, nan_seen)``, the kept point farthest
    from the rhombus ``(cx, cy, a, b)`` by its distance over one minus its leverage, that
    distance, and whether a distance was NaN (then ``wi`` is the first such point, as
    np.argmax)."""
    scale = a * b / math.hypot(a, b)
    worst, wi, nan_seen = -1.0, -1, False
    for i in range(points.shape[0]):
        if not keep[i]:
            continue
        lev = 0.0
        for j in range(4):
            t = 0.0
            for k in range(4):
                t += inv[j, k] * rows[i, k]
            lev += rows[i, j] * t
        lev = min(lev, 0.95)
        d = abs(signs[i, 0] * (points[i, 0] - cx) / a
                + signs[i, 1] * (points[i, 1] - cy) / b - 1.0) * scale / (1.0 - lev)
        if math.isnan(d):
            if not nan_seen:        # np.argmax: the first NaN is the worst
                wi, nan_seen = i, True
        elif not nan_seen and d > worst:
            worst, wi = d, i
    return wi, worst, nan_seen


@njit(cache=True)
def rhombus_fit(points: np.ndarray, signs: np.ndarray, outlier_px: float,
                max_drop: int) -> np.ndarray:
    """:func:`workzone_ros.core.detect.diamond.fit_rhombus`: ``(cx, cy, a, b)``, all NaN for no
    fit.  The same least squares and leave-one-out outlier test (see there); the 4 x 4
    normal equations are summed and inverted here (to rounding, not bit for bit, numpy's
    matrix product and LAPACK's inverse)."""
    n = points.shape[0]
    out = np.full(4, np.nan)
    rows, edge = _rhombus_rows(points, signs)
    keep = np.ones(n, np.bool_)
    for _ in range(max_drop + 1):
        if not _every_edge(keep, edge):
            return out                  # an edge without a point
        inv, sol = _rhombus_solve(rows, keep)
        if inv.size == 0:
            return out
        u, v = sol[0], sol[1]
        if u <= 1e-6 or v <= 1e-6:
            return out
        a, b = 1.0 / u, 1.0 / v
        cx, cy = sol[2] * a, sol[3] * b
        wi, worst, nan_seen = _worst_point(points, signs, rows, keep, inv, cx, cy, a, b)
        if not nan_seen and worst <= max(outlier_px, 0.07 * min(a, b)):
            out[0], out[1], out[2], out[3] = cx, cy, a, b
            return out
        keep[wi] = False
    return out


@njit(cache=True)
def low_chroma_rounds(small: np.ndarray, lo: float, hi: float, share: float,
                      iters: int) -> np.ndarray:
    """:func:`workzone_ros.core.color_model.low_chroma_gains` after its downscaling: the
    (b, g, r) gains from an (h, w, 3) uint8 image, or an empty array for fewer than 50
    well-exposed pixels.  float32 throughout, as numpy computes it there: the chroma
    quantile interpolated as ``np.quantile`` does (in float32), the mean of the least
    chromatic pixels summed row by row (numpy's order for a mean over the first axis of (n,
    3) pixels)."""
    f1 = np.float32(1.0)
    flat = small.reshape(-1, 3)
    n_all = flat.shape[0]
    px = np.empty((n_all, 3), np.float32)
    n = 0
    for i in range(n_all):
        b, g_, r = np.float32(flat[i, 0]), np.float32(flat[i, 1]), np.float32(flat[i, 2])
        mx = max(max(b, g_), r)
        if mx > 30 and mx < 245:
            px[n, 0], px[n, 1], px[n, 2] = b, g_, r
            n += 1
    if n < 50:
        return np.empty(0, np.float32)
    px = px[:n]
    gain = np.ones(3, np.float32)
    x = np.empty((n, 3), np.float32)
    c = np.empty(n, np.float32)
    buf = np.empty(n, np.float32)
    lo32, hi32 = np.float32(lo), np.float32(hi)
    for it in range(max(1, iters)):
        for i in range(n):
            for ch in range(3):
                x[i, ch] = px[i, ch] * gain[ch] if it else px[i, ch]
            mx = max(max(x[i, 0], x[i, 1]), x[i, 2])
            mn = min(min(x[i, 0], x[i, 1]), x[i, 2])
            c[i] = (mx - mn) / max(mx, f1)
        # np.quantile(c, share), numpy's linear method and lerp
        vi = (n - 1) * share
        i0 = math.floor(vi)
        j0 = min(i0 + 1, n - 1)
        buf[:] = c
        a = select_kth(buf, n, i0)
        bnext = a
        if j0 != i0:
            # the next order statistic: the smallest of what lies above position i0
            bnext = buf[i0 + 1]
            for q in range(i0 + 2, n):
                if buf[q] < bnext:
                    bnext = buf[q]
        t = vi - i0
        diff = bnext - a
        if t < 0.5:
            qv = a + diff * np.float32(t)
        else:
            qv = bnext - diff * np.float32(1 - t)
        s0, s1, s2 = np.float32(0.0), np.float32(0.0), np.float32(0.0)
        cnt = 0
        for i in range(n):
            if c[i] <= qv:
                s0 += x[i, 0]
                s1 += x[i, 1]
                s2 += x[i, 2]
                cnt += 1
        fc = np.float32(cnt)
        m0, m1, m2 = s0 / fc, s1 / fc, s2 / fc
        mm = ((np.float32(0.0) + m0) + m1 + m2) / np.float32(3)
        gain[0] = min(max(gain[0] * mm / max(m0, f1), lo32), hi32)
        gain[1] = min(max(gain[1] * mm / max(m1, f1), lo32), hi32)
        gain[2] = min(max(gain[2] * mm / max(m2, f1), lo32), hi32)
    return gain


@njit(cache=True)
def profile_medians(samples: np.ndarray, n: int, nt: int) -> np.ndarray:
    """The median over each stretch's ``nt`` profiles of float32 ``samples`` (n * nt, nu):
    (n, nu) float64, np.median's values (the mean of the middle two in float32)."""
    nu = samples.shape[1]
    out = np.empty((n, nu))
    buf = np.empty(nt, np.float32)
    for s in range(n):
        for u in range(nu):
            for t in range(nt):
                buf[t] = samples[s * nt + t, u]
            out[s, u] = median_inplace(buf, nt)
    return out


@njit(cache=True)
def edge_choice(prof_v: np.ndarray, atb: np.ndarray, coef: np.ndarray, valid: np.ndarray,
                min_contrast: float, u0: np.ndarray, ns: int, off: np.ndarray,
                best: np.ndarray) -> int:
    """:func:`workzone_ros.core.detect.edges._edge_offsets` after its least squares: per
    stretch (``prof_v`` (n, u): its median profile; ``atb``, ``coef`` (k, 3, n): the edge
    models' ``A^T p`` and coefficients; ``valid`` (k,)) the model of least residual among
    those showing a face-to-border step (``coef`` hi > 0, hi - lo >= ``min_contrast`` hi),
    its offset moved by the parabola through its neighbours' residuals (``u0``: the
    offsets, ``ns`` blur widths per offset).  Writes ``off`` (NaN: no step) and ``best``
    (the model, -1: none); returns how many stretches show a step."""
    n = prof_v.shape[0]
    nk = atb.shape[0]
    nu0 = u0.size
    pp = np.empty(n)
    for c in range(n):
        pp[c] = pairwise_sum(prof_v[c] * prof_v[c])
    sse = np.empty(nk)
    seen = 0
    for c in range(n):
        kb = -1
        for k in range(nk):
            hi, lo = coef[k, 0, c], coef[k, 1, c]
            if valid[k] and hi > 0 and hi - lo >= min_contrast * hi:
                sse[k] = pp[c] - (atb[k, 0, c] * coef[k, 0, c] + atb[k, 1, c] * coef[k, 1, c]
                                  + atb[k, 2, c] * coef[k, 2, c])
                if kb < 0 or sse[k] < sse[kb]:
                    kb = k
            else:
                sse[k] = np.inf
        best[c] = kb
        if kb < 0:
            off[c] = np.nan
            continue
        seen += 1
        i0 = kb // ns
        o = float(u0[i0])
        if 0 < i0 < nu0 - 1:
            s_m, s_0, s_p = sse[kb - ns], sse[kb], sse[kb + ns]
            den = s_m - 2 * s_0 + s_p
            if math.isfinite(den) and den > 0:
                o += 0.05 * (s_m - s_p) / den
        off[c] = o
    return seen


@njit(cache=True)
def label_at_first_pixel(labels: np.ndarray, n: int, other: np.ndarray) -> np.ndarray:
    """For each of the ``n`` labels of ``labels``, ``other``'s label at its first pixel in
    row-major order (-1 for the background, 0, and for a label without pixels)."""
    out = np.full(n, -1, np.int64)
    left = n - 1
    H, W = labels.shape
    for r in range(H):
        for c in range(W):
            k = labels[r, c]
            if k > 0 and out[k] < 0:
                out[k] = other[r, c]
                left -= 1
                if left == 0:
                    return out
    return out


@njit(cache=True)
def flat_take(table: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``np.take(table, idx)`` of a C-contiguous table (read flat) at a 2-d array of indices
    (uint16 here: a hue and a saturation merged), without numpy's conversion of every
    index to intp first."""
    flat = table.reshape(-1)
    H, W = idx.shape
    out = np.empty((H, W), table.dtype)
    n = flat.size
    for r in range(H):
        for c in range(W):
            i = idx[r, c]
            if i >= n:
                raise IndexError('flat_take: an index past the table')
            out[r, c] = flat[i]
    return out


@njit(cache=True)
def hue_sat_take(table: np.ndarray, hue: np.ndarray, sat: np.ndarray) -> np.ndarray:
    """``table[hue, sat]`` for 2-d hue and saturation arrays of the same shape."""
    H, W = hue.shape
    out = np.empty((H, W), table.dtype)
    nh, ns = table.shape
    for r in range(H):
        for c in range(W):
            h, s = hue[r, c], sat[r, c]
            if h >= nh or s >= ns:
                raise IndexError('hue_sat_take: a hue or saturation past the table')
            out[r, c] = table[h, s]
    return out


@njit(cache=True)
def label_stats(labels: np.ndarray, n: int, mask: np.ndarray) -> np.ndarray:
    """Per label of ``labels`` (``n`` labels of the nonzero pixels of ``mask``, 0 the
    zeros): x, y, width, height and area (int32), as ``cv2.connectedComponentsWithStats``
    gives them; a label without pixels: zeros.  The zeros (most of a sparse mask) are read
    from ``mask`` a byte each, the labels only where it is set."""
    h, w = labels.shape
    x0 = np.full(n, w, np.int64)
    y0 = np.full(n, h, np.int64)
    x1 = np.full(n, -1, np.int64)
    y1 = np.full(n, -1, np.int64)
    area = np.zeros(n, np.int64)
    for r in range(h):
        first, last, zeros = -1, -1, 0
        for c in range(w):
            if mask[r, c] == 0:
                if first < 0:
                    first = c
                last = c
                zeros += 1
                continue
            lab = labels[r, c]
            area[lab] += 1
            if c < x0[lab]:
                x0[lab] = c
            if c > x1[lab]:
                x1[lab] = c
            if r < y0[lab]:
                y0[lab] = r
            y1[lab] = r
        if zeros:
            area[0] += zeros
            x0[0] = min(x0[0], first)
            x1[0] = max(x1[0], last)
            y0[0] = min(y0[0], r)
            y1[0] = r
    out = np.zeros((n, 5), np.int32)
    for lab in range(n):
        if area[lab] > 0:
            out[lab, 0] = x0[lab]
            out[lab, 1] = y0[lab]
            out[lab, 2] = x1[lab] - x0[lab] + 1
            out[lab, 3] = y1[lab] - y0[lab] + 1
            out[lab, 4] = area[lab]
    return out


def components_with_stats(mask: np.ndarray, connectivity: int = 8
                          ) -> tuple[int, np.ndarray, np.ndarray]:
    """``cv2.connectedComponentsWithStats(mask, connectivity)`` without the centroids:
    ``(n, labels, stats)``, the same labels and statistics (a label without pixels, the
    background of a full mask, has zeros).  OpenCV's statistics pass cost about 0.35 ms
    on the detector's 361 x 203 mask on one thread, five times its labelling; here the
    labelling is OpenCV's and the statistics one compiled pass."""
    n, labels = cv2.connectedComponents(mask, connectivity=connectivity, ltype=cv2.CV_32S)
    return n, labels, label_stats(labels, n, mask)


def warm() -> None:
    """Compile (or load from the cache) every kernel for the types the detector passes:
    ``python -m workzone_ros.core.kernels`` after an install, so that no node's first frame
    waits for the compiler."""
    # (the chroma fit's solver, the edge measurement, the blob helpers, the diamond's
    # rounds, the band tests' row profiles and the proposals' sums: their own modules)
    from workzone_ros.core import (
        blob_kernels,
        chroma_fit,
        diamond_kernels,
        edge_kernels,
        profile_kernels,
        proposal_kernels,
    )
    chroma_fit.warm()
    proposal_kernels.warm()
    profile_kernels.warm()
    edge_kernels.warm()
    blob_kernels.warm()
    diamond_kernels.warm()
    mask = np.zeros((12, 12), np.uint8)
    mask[2:10, 3:9] = 1
    ratios = np.linspace(0.7, 1.4, 6)
    diamond_tent(mask, 5, ratios, 0.7, 1.4)
    ratios.flags.writeable = False                  # fit_diamond's ratios are a constant
    diamond_tent(mask, 5, ratios, 0.7, 1.4)
    pts = np.array([(0.0, 5.0), (5.0, 0.0), (10.0, 5.0), (5.0, 10.0)] * 2)
    signs = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] * 2)
    rhombus_fit(pts, signs, 1.0, 2)
    tip_pixel(5.0, 4.0, 5.0, 4.0, (np.arange(8) + 0.5) / 8)
    low_chroma_rounds(np.full((10, 10, 3), 100, np.uint8), 0.6, 1.6, 0.2, 2)
    medians = profile_medians(np.zeros((6, 5), np.float32), 2, 3)
    atb = np.zeros((4, 3, 2))
    edge_choice(medians, atb, atb, np.ones(4, np.bool_), 0.25,
                np.arange(4, dtype=np.float32), 2, np.empty(2), np.empty(2, np.int64))
    labels = np.zeros((4, 4), np.int32)
    label_at_first_pixel(labels, 1, labels)
    label_stats(labels, 1, np.zeros((4, 4), np.uint8))
    label_stats(labels, 1, np.zeros((4, 5), np.uint8)[:, 1:])      # (a mask's window)
    flat_take(np.zeros(180 * 256, np.uint8), np.zeros((4, 4), np.uint16))
    hsv = np.zeros((4, 4, 3), np.uint8)
    for table in (np.zeros((180, 256), np.float32), np.zeros((180, 256), np.uint8)):
        hue_sat_take(table, hsv[..., 0], hsv[..., 1])       # channel views (strided)
        hue_sat_take(table, hsv[..., 0], np.zeros((4, 4), np.uint8))
        hue_sat_take(table, np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint8))


if __name__ == '__main__':
    import time
    t0 = time.perf_counter()
    warm()
    print(f'workzone_ros kernels ready in {time.perf_counter() - t0:.1f} s')
