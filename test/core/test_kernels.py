"""The compiled kernels reproduce numpy's arithmetic (workzone_ros.core.kernels)."""
import cv2
import numpy as np
import pytest

from workzone_ros.core import kernels as k
from workzone_ros.core.detect.common import _lookup
from workzone_ros.core.detect.diamond import (
    _RHOMBUS_SIGNS,
    _STRETCH_SIGNS,
    _SUBPIXEL,
    _tip_pixel,
    fit_diamond,
    fit_rhombus,
)
from workzone_ros.core.detect.edges import _PROFILE_SIG, _PROFILE_U0, _edge_profile


@pytest.mark.parametrize('n', [0, 1, 5, 7, 8, 9, 15, 16, 17, 24, 31, 64, 127, 128, 129, 200,
                               257, 1000])
def test_pairwise_sum_is_numpys_sum_bit_for_bit(n):
    rng = np.random.default_rng(n)
    for scale in (1e-3, 1.0, 1e6):
        a = rng.normal(0, scale, n) + rng.uniform(-1, 1) * scale * 1e3
        assert k.pairwise_sum(a) == np.add.reduce(a)
        # and along the last axis of a 2-d array (fit_diamond's row sums)
        rows = rng.normal(0, scale, (3, n))
        assert [k.pairwise_sum(r) for r in rows] == rows.sum(axis=1).tolist()


def test_float_range_is_numpys_arange():
    rng = np.random.default_rng(1)
    for _ in range(2000):
        start = rng.uniform(-50, 300)
        step = rng.choice([0.25, 0.5, rng.uniform(0.5, 15.0)])
        stop = start + rng.uniform(-1, 60) + rng.choice([0.0, 0.01, 0.26])
        assert np.array_equal(k.float_range(start, stop, step), np.arange(start, stop, step))


@pytest.mark.parametrize('n', [1, 2, 3, 4, 5, 24, 25, 47, 48, 100])
def test_median_inplace_is_numpys_median(n):
    rng = np.random.default_rng(n)
    for _ in range(300):
        v = rng.normal(0, 10, n)
        if rng.random() < 0.5:
            v = np.round(v)             # ties
        want = np.median(v)
        assert k.median_inplace(v.copy(), n) == want
        # only the first n values count
        assert k.median_inplace(np.concatenate([v, [1e9, -1e9]]), n) == want


def test_inverse4_and_singular():
    rng = np.random.default_rng(2)
    for _ in range(200):
        a = rng.normal(size=(8, 4))
        m = a.T @ a
        np.testing.assert_allclose(k._inverse4(m) @ m, np.eye(4), atol=1e-9)
    assert k._inverse4(np.ones((4, 4))).size == 0


def _rhombus_points(cx, cy, a, b, ts):
    signs = _STRETCH_SIGNS
    pts = np.array([(cx + s[0] * a * t, cy + s[1] * b * (1 - t)) for s, t in zip(signs, ts)])
    return pts, signs


def _fit_rhombus_numpy(points, signs, outlier_px, max_drop):
    """fit_rhombus as numpy computed it before the kernel (the reference)."""
    keep = np.ones(len(points), bool)
    for _ in range(max_drop + 1):
        p, sg = points[keep], signs[keep]
        if len({tuple(e) for e in sg.tolist()}) < 4:
            return None
        mat = np.concatenate([sg * p, -sg], axis=1)
        inv = np.linalg.inv(mat.T @ mat)
        u, v, pu, rv = inv @ mat.sum(axis=0)
        if u <= 1e-6 or v <= 1e-6:
            return None
        a, b = 1.0 / u, 1.0 / v
        cx, cy = pu * a, rv * b
        lev = np.minimum(np.einsum('ij,jk,ik->i', mat, inv, mat), 0.95)
        dist = np.abs(sg[:, 0] * (p[:, 0] - cx) / a + sg[:, 1] * (p[:, 1] - cy) / b - 1.0) \
            * a * b / np.hypot(a, b) / (1.0 - lev)
        worst = np.full(len(points), -1.0)
        worst[keep] = dist
        k_ = int(np.argmax(worst))
        if worst[k_] <= max(outlier_px, 0.07 * min(a, b)):
            return cx, cy, a, b
        keep[k_] = False
    return None


def test_rhombus_fit_is_the_numpy_fit():
    """Exact and noisy edge points, with and without a point off its edge, every drop
    budget: the same points dropped and the same diamond (to rounding)."""
    rng = np.random.default_rng(3)
    n_none = 0
    for t in range(3000):
        cx, cy = rng.uniform(10, 600, 2)
        a = rng.uniform(6, 60)
        b = a * rng.uniform(0.7, 1.4)
        pts, signs = _rhombus_points(cx, cy, a, b, rng.uniform(0.15, 0.85, 8))
        pts = pts + rng.normal(0, [0.0, 0.1, 0.5, 1.5][t % 4], pts.shape)
        if t % 3:
            i = int(rng.integers(8))
            pts[i] += rng.uniform(1, 8) * rng.choice([-1, 1]) * signs[i]
        for max_drop in (0, 1, 2, 3):
            want = _fit_rhombus_numpy(pts, signs, 1.0, max_drop)
            got = fit_rhombus(pts, signs, 1.0, max_drop)
            assert (got is None) == (want is None)
            if want is not None:
                np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-8)
            n_none += want is None
    assert 0 < n_none < 12000 - 1000     # both outcomes tested


def test_rhombus_fit_matches_numpy_least_squares():
    """Without outliers the fit is the least-squares solution of the edge equations."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        pts, signs = _rhombus_points(*rng.uniform(20, 300, 2), *rng.uniform(8, 40, 2),
                                     rng.uniform(0.2, 0.8, 8))
        pts = pts + rng.normal(0, 0.05, pts.shape)
        mat = np.concatenate([signs * pts, -signs], axis=1)
        u, v, pu, rv = np.linalg.lstsq(mat, np.ones(8), rcond=None)[0]
        got = fit_rhombus(pts, signs, 5.0, 0)
        np.testing.assert_allclose(got, (pu / u, rv / v, 1 / u, 1 / v), rtol=1e-9)


def test_rhombus_fit_needs_every_edge():
    pts, signs = _rhombus_points(50, 50, 20, 20, np.full(8, 0.5))
    keep = np.any(signs != _RHOMBUS_SIGNS[2], axis=1)       # no lower-right point
    assert fit_rhombus(pts[keep], signs[keep], 1.0, 2) is None


@pytest.mark.parametrize('kind', ['uint8', 'uint8_255', 'bool', 'transposed', 'int32'])
def test_fit_diamond_takes_any_mask_layout(kind):
    yy, xx = np.mgrid[:41, :37]
    inside = np.abs(xx + 0.5 - 18.3) / 15.2 + np.abs(yy + 0.5 - 20.1) / 17.4 <= 1
    mask = inside.astype(np.uint8)
    want = fit_diamond(mask)
    assert want is not None
    if kind == 'uint8_255':
        m = mask * 255
    elif kind == 'bool':
        m = inside
    elif kind == 'transposed':
        m = np.ascontiguousarray(mask.T).T          # a non-contiguous view, same pixels
    else:
        m = mask.astype(np.int32)
    assert fit_diamond(m) == want


def test_tip_pixel_is_the_first_half_covered_pixel():
    """Against the coverage counted on the full 8 x 8 sub-pixel grid of every pixel."""
    rng = np.random.default_rng(5)
    sub = _SUBPIXEL
    for _ in range(300):
        c, c2 = rng.uniform(-20, 20, 2)
        r, r2 = rng.uniform(0.6, 12, 2)
        got = _tip_pixel(c, r, c2, r2)
        i0 = int(np.floor(c - r))
        cols = np.arange(i0, min(i0 + 4 + int(np.ceil(2.0 * r / r2)), int(np.floor(c)) + 1))
        rows = np.arange(int(np.floor(c2)) - 1, int(np.floor(c2)) + 2)
        x = cols[:, None, None, None] + sub[None, None, :, None]
        y = rows[None, :, None, None] + sub[None, None, None, :]
        cover = (np.abs(x - c) / r + np.abs(y - c2) / r2 <= 1.0).sum(axis=(2, 3)).max(axis=1)
        hit = np.flatnonzero(2 * cover > sub.size ** 2)
        assert got == (int(cols[hit[0]]) if hit.size else None)


def _low_chroma_numpy(small, lo=0.6, hi=1.6, share=0.2, iters=2):
    """low_chroma_gains' rounds as numpy computed them before the kernel (the reference)."""
    px = small.reshape(-1, 3).astype(np.float32)
    mx0 = px.max(axis=1)
    keep = (mx0 > 30) & (mx0 < 245)
    px, mx0 = px[keep], mx0[keep]
    if len(px) < 50:
        return (1.0, 1.0, 1.0)
    g = np.ones(3, np.float32)
    for i in range(max(1, iters)):
        x = px * g if i else px
        mx = x.max(axis=1) if i else mx0
        c = (mx - x.min(axis=1)) / np.maximum(mx, 1.0)
        m = x[c <= np.quantile(c, share)].mean(axis=0)
        g = np.minimum(np.maximum(g * m.mean() / np.maximum(m, 1.0), lo), hi)
    return tuple(float(v) for v in g)


def test_low_chroma_gains_are_the_numpy_gains_bit_for_bit():
    """Drawn scenes (grey ground, a tint, a sign, noise, dark and clipped parts) and noise."""
    from workzone_ros.core.color_model import low_chroma_gains
    rng = np.random.default_rng(6)
    n_ones = 0
    for t in range(300):
        h, w = rng.integers(40, 300, 2)
        img = np.empty((h, w, 3), np.uint8)
        img[: h // 2] = rng.integers(0, 256, 3)                          # sky
        img[h // 2:] = np.clip(rng.normal(110, 40) * rng.uniform(0.7, 1.3, 3), 0, 255)
        y, x = rng.integers(0, h - 10), rng.integers(0, w - 10)
        img[y:y + 10, x:x + 10] = (0, 110, 245)                              # a sign
        img = np.clip(img + rng.normal(0, rng.uniform(1, 30), img.shape), 0, 255).astype(np.uint8)
        if t % 5 == 0:
            img //= 8                                                      # mostly too dark
        kw = {} if t % 2 else {'share': float(rng.uniform(0.05, 0.9)),
                               'iters': int(rng.integers(1, 4))}
        top = 0.5
        part = img[int(h * top):]
        ph, pw = part.shape[:2]
        small = part if min(ph, pw) < 64 else cv2.resize(part, (pw // 4, ph // 4),
                                                         interpolation=cv2.INTER_AREA)
        want = _low_chroma_numpy(small, **kw)
        assert low_chroma_gains(img, **kw) == want
        n_ones += want == (1.0, 1.0, 1.0)
    assert 0 < n_ones < 150


@pytest.mark.parametrize('nt', [3, 4, 9, 10, 31, 64, 65, 80])
def test_profile_medians_are_numpys_medians(nt):
    rng = np.random.default_rng(nt)
    for n in (1, 3, 8):
        s = rng.uniform(0, 255, (n * nt, 35)).astype(np.float32)
        s[rng.random(s.shape) < 0.3] = 100.0                    # ties
        want = np.median(s.reshape(n, nt, 35), axis=1).astype(np.float64)
        assert np.array_equal(k.profile_medians(s, n, nt), want)


def _edge_choice_numpy(prof_v, atb, coef, valid, min_contrast, u0, ns):
    """_edge_offsets' choice of model and offset as numpy computed it (the reference)."""
    n = prof_v.shape[0]
    sse = (prof_v * prof_v).sum(axis=1)[None, :] - (
        atb[:, 0] * coef[:, 0] + atb[:, 1] * coef[:, 1] + atb[:, 2] * coef[:, 2])
    hi, lo = coef[:, 0, :], coef[:, 1, :]
    ok = valid[:, None] & (hi > 0) & (hi - lo >= min_contrast * hi)
    seen = ok.any(axis=0)
    sse = np.where(ok, sse, np.inf)
    off, best = np.full(n, np.nan), np.full(n, -1)
    for c, kk in enumerate(np.argmin(sse, axis=0).tolist()):
        if not seen[c]:
            continue
        i0 = kk // ns
        o = float(u0[i0])
        if 0 < i0 < u0.size - 1:
            s_m, s_0, s_p = float(sse[kk - ns, c]), float(sse[kk, c]), float(sse[kk + ns, c])
            den = s_m - 2 * s_0 + s_p
            if np.isfinite(den) and den > 0:
                o += 0.05 * (s_m - s_p) / den
        off[c], best[c] = o, kk
    return off, best


def test_edge_choice_is_the_numpy_choice():
    """Profiles of blurred face-line-background edges and of plain noise, through the real
    edge models: the same model, offset and stretches without a step."""
    rng = np.random.default_rng(7)
    u, bases_t, ata_inv, valid = _edge_profile(16.0, 1.1, 0.35)[:4]
    u0, ns = _PROFILE_U0, _PROFILE_SIG.size
    n_lost = 0
    for t in range(200):
        n = 8
        face, line, bg = rng.uniform(60, 250), rng.uniform(0, 80), rng.uniform(0, 255, n)
        edge = rng.uniform(-2, 2, n)[:, None]
        outside = np.where(u[None, :] > edge - 1.1, line, bg[:, None])
        prof = np.where(u[None, :] > edge, face, outside)
        prof = prof + rng.normal(0, rng.uniform(0, 25), prof.shape)
        if t % 4 == 0:
            prof[: t % 8] = rng.uniform(0, 255, (t % 8, u.size))          # no edge there
        atb = (bases_t @ prof.T).reshape(-1, 3, n)
        coef = ata_inv @ atb
        mc = float(rng.choice([0.05, 0.25, 0.6]))
        off, best = np.empty(n), np.empty(n, np.int64)
        seen = k.edge_choice(prof, atb, coef, valid, mc, u0, ns, off, best)
        want_off, want_best = _edge_choice_numpy(prof, atb, coef, valid, mc, u0, ns)
        assert np.array_equal(off, want_off, equal_nan=True)
        assert best.tolist() == want_best.tolist()
        assert seen == int(np.count_nonzero(want_best >= 0))
        n_lost += n - seen
    assert 0 < n_lost < 800        # stretches with and without a step


def test_label_at_first_pixel():
    rng = np.random.default_rng(8)
    for _ in range(100):
        hi = (rng.random((40, 60)) < 0.08).astype(np.uint8)
        lo = cv2.dilate(hi, np.ones((3, 3), np.uint8)) | (rng.random((40, 60)) < 0.2)
        n, lab_hi, stats, _ = cv2.connectedComponentsWithStats(hi, connectivity=8)
        _, lab_lo = cv2.connectedComponents(lo.astype(np.uint8), connectivity=8)
        got = k.label_at_first_pixel(lab_hi, n, lab_lo)
        assert got[0] == -1                                       # the background
        for i in range(1, n):
            first = int(np.argmax(lab_hi.ravel() == i))          # row-major
            assert got[i] == lab_lo.flat[first]
            assert got[i] > 0                                     # lo holds hi


def test_table_lookups_are_numpys():
    rng = np.random.default_rng(9)
    for dtype in (np.uint8, np.float32):
        table = (rng.random((180, 256)) * 255).astype(dtype)
        hsv = np.dstack([rng.integers(0, 180, (30, 40)), rng.integers(0, 256, (30, 40)),
                         rng.integers(0, 256, (30, 40))]).astype(np.uint8)
        hue, sat = hsv[..., 0], hsv[..., 1]                     # strided channel views
        assert np.array_equal(_lookup(table, hue, sat), table[hue, sat])
        idx = cv2.merge([sat, hue]).view(np.uint16)[..., 0]     # hue * 256 + sat
        assert np.array_equal(k.flat_take(table.reshape(-1), idx), np.take(table, idx))
    # a hue past the table: numpy's error, not memory past the table
    with pytest.raises(IndexError):
        k.hue_sat_take(table, np.full((2, 2), 200, np.uint8), np.zeros((2, 2), np.uint8))
    with pytest.raises(IndexError):
        k.flat_take(table.reshape(-1), np.full((2, 2), 60000, np.uint16))


_FIRST_FRAME = """
import cv2, numpy as np
from workzone_ros.core import color_model as cm, detect as dt, kernels as k
from workzone_ros.resources import config_path
k.warm()
kernels = {n: getattr(k, n) for n in dir(k) if hasattr(getattr(k, n), 'signatures')}
before = {n: set(f.signatures) for n, f in kernels.items()}
img = np.full((480, 640, 3), (110, 112, 108), np.uint8)
pts = np.array([[420, 100], [470, 150], [420, 200], [370, 150]], np.int32)
cv2.fillConvexPoly(img, pts, (0, 110, 245))
cv2.polylines(img, [pts], True, (20, 20, 20), 3)
cv2.putText(img, 'RW', (398, 160), cv2.FONT_HERSHEY_DUPLEX, 0.8, (20, 20, 20), 2)
det = dt.ColorDetector(cm.load_model(config_path('models/color_orange.npz')),
                       dt.DetectorConfig())
assert det.detect(img), 'no detection'
print(sorted(n for n, f in kernels.items() if set(f.signatures) - before[n]))
"""


def test_warm_compiles_every_kernel_the_detector_calls():
    """After :func:`kernels.warm` (what a node runs before its first image) the detector's
    first frame compiles nothing: every kernel is called with types warm() prepared (a new
    type, e.g. a read-only array, loads or compiles a specialisation inside the first
    image's callback, and the frames behind it wait).  In a fresh process: this one's
    kernels have seen every type already."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, '-c', _FIRST_FRAME], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == '[]'


@pytest.mark.parametrize('connectivity', [4, 8])
def test_components_with_stats_are_opencvs(connectivity):
    """The labels and statistics of ``components_with_stats`` are OpenCV's
    (``connectedComponentsWithStats``) on masks of every density, shape and value, views
    included; a label without pixels (the background of a full mask) has zeros."""
    rng = np.random.default_rng(connectivity)
    for _ in range(300):
        h, w = (int(v) for v in rng.integers(1, 90, 2))
        mask = ((rng.random((h, w)) < rng.choice([0.0, 0.02, 0.2, 0.6, 1.0]))
                * int(rng.integers(1, 256))).astype(np.uint8)
        if rng.random() < 0.5:
            mask = cv2.dilate(mask, np.ones((3, 3), np.uint8))
        if rng.random() < 0.3:
            mask = mask[:, ::2]
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
        n2, labels2, stats2 = k.components_with_stats(mask, connectivity)
        assert n2 == n and np.array_equal(labels2, labels)
        assert np.array_equal(stats2[1:], stats[1:])
        if np.count_nonzero(mask) < mask.size:
            assert np.array_equal(stats2[0], stats[0])
        else:
            assert not stats2[0].any()
