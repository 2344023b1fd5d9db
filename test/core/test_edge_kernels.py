"""The compiled edge measurement reproduces OpenCV's and numpy's arithmetic
(workzone_ros.core.edge_kernels)."""
import cv2
import numpy as np
import pytest
from numba import njit

from workzone_ros.core import edge_kernels as ek
from workzone_ros.core.detect import edges
from workzone_ros.core.detect.edges import (
    _PROFILE_SIG,
    _PROFILE_U0,
    _edge_offsets,
    _edge_offsets_numpy,
    _edge_profile,
    _unit_steps,
)
from workzone_ros.core.kernels import profile_medians


def _close(a, b, equal_nan=False):
    """Equal within rounding: bit for bit where OpenCV and OpenBLAS use fused multiply-adds,
    as the kernels do (this machine's AVX2 builds); a rounding apart on other CPUs."""
    return np.allclose(a, b, rtol=1e-6, atol=1e-9, equal_nan=equal_nan)


@njit
def _remap_all(img, mx, my):
    out = np.empty(mx.shape, np.float32)
    for r in range(mx.shape[0]):
        for c in range(mx.shape[1]):
            out[r, c] = ek.bilinear(img, mx[r, c], my[r, c])
    return out


@njit
def _fma32(a, b, c):
    return ek.fma(a, b, c)


def test_fma_rounds_once():
    # 1 + 2^-24 squared is 1 + 2^-23 + 2^-48: a product rounded first loses the 2^-48
    a = np.float32(1.0 + 2.0 ** -23)
    c = np.float32(-(1.0 + 2.0 ** -22))
    assert _fma32(a, a, c) == np.float32(2.0 ** -46)
    assert np.float32(a * a) + c == 0.0


def test_bilinear_is_cv2_remap():
    rng = np.random.default_rng(3)
    for h, w in ((7, 9), (40, 53), (2, 2)):
        for img in ((rng.random((h, w)) * 255).astype(np.float32),
                    rng.integers(0, 256, (h, w)).astype(np.float32)):
            mx = (rng.random((60, 37)) * (w - 1)).astype(np.float32)
            my = (rng.random((60, 37)) * (h - 1)).astype(np.float32)
            # the last column and row exactly, whole and half pixels
            mx[0], my[1] = w - 1, h - 1
            mx[2], my[2] = np.round(mx[2]), np.round(my[2] * 2) / 2
            want = cv2.remap(img, mx, my, cv2.INTER_LINEAR)
            assert _close(_remap_all(img, mx, my), want)


@pytest.mark.parametrize('n', [1, 2, 3, 5, 8, 13, 31, 32, 33, 48, 70])
def test_sort_columns_is_numpys_sort(n):
    rng = np.random.default_rng(n)
    for x in (rng.normal(100, 40, (n, 21)).astype(np.float32),
              rng.integers(0, 3, (n, 32)).astype(np.float32)):       # many ties
        want = np.sort(x, axis=0)
        ek.sort_columns(x)
        assert np.array_equal(x, want)


@pytest.mark.parametrize('nt', range(1, 49))
def test_column_medians_are_numpys(nt):
    rng = np.random.default_rng(nt)
    for x in (rng.normal(100, 40, (nt, 37)).astype(np.float32),
              rng.integers(0, 4, (nt, 16)).astype(np.float32)):      # many ties
        want = np.median(x, axis=0)
        out = np.empty(x.shape[1])
        ek.column_medians(x, out)
        assert np.array_equal(out, want)


def _points(rng, img, n, u):
    """``n`` random stretches inside ``img`` with unit normals and their sample steps."""
    h, w = img.shape
    length = rng.uniform(3, 45)
    ang = rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.cos(ang), np.sin(ang)], 1)
    nv = np.stack([-d[:, 1], d[:, 0]], 1)
    reach = length + abs(u).max() + 2
    s0 = np.stack([rng.uniform(reach, w - reach, n), rng.uniform(reach, h - reach, n)], 1)
    segs = np.stack([s0, s0 + length * d], 1)
    return segs, nv, _unit_steps(max(3, int(length) + 1))


def _first_bad_point(img, segs, nv, u, ts):
    """The code of the first sample point (stretch by stretch, along, then across) that is
    not a number (-2) or outside ``img`` (-1), from every point computed as numpy does."""
    h, w = img.shape
    with np.errstate(invalid='ignore', over='ignore'):
        along = segs[:, None, 0, :] + ts[None, :, None] * (segs[:, 1] - segs[:, 0])[:, None]
        across = u[None, :, None] * nv[:, None, :]
        pts = (along[:, :, None] + across[:, None] - 0.5).astype(np.float32)
    for p in pts.reshape(len(segs), -1, 2):
        nan = np.isnan(p).any(axis=1)
        with np.errstate(invalid='ignore'):
            out = (p < 0).any(axis=1) | (p[:, 0] > w - 1) | (p[:, 1] > h - 1)
        bad = np.flatnonzero(nan | out)
        if bad.size:
            return -2 if nan[bad[0]] else -1
    return 0


def test_points_code_is_the_point_by_point_check():
    rng = np.random.default_rng(9)
    img = np.zeros((60, 70), np.float32)
    u = _edge_profile(20.0, 1.0, 0.4)[0]
    codes = set()
    for trial in range(600):
        n = int(rng.integers(1, 9))
        length = rng.uniform(3, 30)
        ang = rng.uniform(0, 2 * np.pi, n)
        d = np.stack([np.cos(ang), np.sin(ang)], 1)
        nv = np.stack([-d[:, 1], d[:, 0]], 1)
        s0 = np.stack([rng.uniform(-5, 75, n), rng.uniform(-5, 65, n)], 1)
        segs = np.stack([s0, s0 + length * d], 1)
        ts = _unit_steps(max(3, int(length) + 1))
        if trial % 3 == 1:
            # a stretch moved so that its extreme point lands on the image's edge (within
            # rounding: either side)
            k = int(rng.integers(n))
            along = segs[k, 0] + ts[:, None] * (segs[k, 1] - segs[k, 0])
            pts = (along[:, None] + u[None, :, None] * nv[k] - 0.5).astype(np.float32)
            axis = int(rng.integers(2))
            edge = (0.0, (70.0, 60.0)[axis] - 1)[int(rng.integers(2))]
            far = pts[..., axis].min() if edge == 0.0 else pts[..., axis].max()
            segs[k, :, axis] += edge - float(far) + rng.choice([0.0, 1e-7, -1e-7, 1e-12])
        if trial % 7 == 2:
            segs[int(rng.integers(n)), int(rng.integers(2)), int(rng.integers(2))] = \
                rng.choice([np.nan, np.inf, -np.inf])
        if trial % 11 == 3:
            nv[int(rng.integers(n)), int(rng.integers(2))] = np.nan
        want = _first_bad_point(img, segs, nv, u, ts)
        codes.add(want)
        assert ek.points_code(img.shape, segs, nv, u, ts) == want
        mx, my, code = ek.sample_points(img, segs, nv, u, ts)
        assert code == want
    assert codes == {0, -1, -2}


def test_edge_profiles_are_remap_and_numpys_medians():
    rng = np.random.default_rng(5)
    img = (rng.random((140, 150)) * 255).astype(np.float32)
    for n in (1, 2, 6, 8):
        u = _edge_profile(rng.uniform(5, 40), rng.uniform(0.3, 2.5), rng.uniform(0.1, 1))[0]
        for _ in range(20):
            segs, nv, ts = _points(rng, img, n, u)
            along = segs[:, None, 0, :] + ts[None, :, None] * (segs[:, 1] - segs[:, 0])[:, None]
            across = u[None, :, None] * nv[:, None, :]
            mx = (along[:, :, None, 0] + across[:, None, :, 0] - 0.5).astype(np.float32)
            my = (along[:, :, None, 1] + across[:, None, :, 1] - 0.5).astype(np.float32)
            nt = ts.size
            samples = cv2.remap(img, mx.reshape(n * nt, -1), my.reshape(n * nt, -1),
                                cv2.INTER_LINEAR)
            want = profile_medians(samples, n, nt)
            assert _close(ek.edge_profiles(img, segs, nv, u, ts), want)
    # a stretch reaching outside the image, and one not a number
    segs[0, 1] = (-5.0, 3.0)
    assert ek.edge_profiles(img, segs, nv, u, ts).shape == (0, u.size)
    segs[0, 1] = (np.nan, 3.0)
    assert ek.edge_profiles(img, segs, nv, u, ts).shape == (0, 0)


def test_model_fits_are_numpys_products():
    rng = np.random.default_rng(7)
    for _ in range(30):
        u, bases_t, ata_inv, valid = _edge_profile(rng.uniform(5, 40), rng.uniform(0.3, 2.5),
                                                   rng.uniform(0.1, 1))[:4]
        n = int(rng.integers(2, 9))       # (one stretch: numpy's matrix-vector products)
        prof = rng.uniform(0, 255, (n, u.size))
        vt, inv, models = ek.valid_models(bases_t, ata_inv, valid)
        atb, coef = ek.model_fits(prof, vt, inv)
        want_atb = (bases_t @ prof.T).reshape(-1, 3, n)
        want_coef = ata_inv @ want_atb
        assert _close(atb.reshape(n, -1, 3).transpose(1, 2, 0), want_atb[models])
        assert _close(coef.reshape(n, -1, 3).transpose(1, 2, 0), want_coef[models])


def _step_image(rng, h=120, w=130):
    """A dark-lined bright square on a background, blurred, with noise (edges to find)."""
    img = np.full((h, w), rng.uniform(20, 120), np.float32)
    x0, y0, x1, y1 = 30, 25, 100, 95
    img[y0 - 3:y1 + 3, x0 - 3:x1 + 3] = rng.uniform(180, 250)      # margin
    img[y0 - 2:y1 + 2, x0 - 2:x1 + 2] = rng.uniform(0, 40)         # border line
    img[y0:y1, x0:x1] = rng.uniform(150, 230)                      # face
    img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.5, 1.5))
    return (img + rng.normal(0, 6, img.shape)).astype(np.float32)


def test_edge_offsets_compiled_is_the_numpy_path():
    rng = np.random.default_rng(11)
    found = 0
    for trial in range(60):
        img = _step_image(rng)
        prof = _edge_profile(35.0, rng.uniform(1.0, 2.5), rng.uniform(0.3, 1.0))
        # the square's four sides (two stretches each), moved a little
        jit = rng.uniform(-1.5, 1.5, 8)
        xs = [(30, 40), (30, 65), (100, 40), (100, 65)]      # (side x, stretch start y)
        ys = [(40, 25), (65, 25), (40, 95), (65, 95)]        # (stretch start x, side y)
        segs = np.array([((x + j, y0), (x + j, y0 + 20)) for (x, y0), j in zip(xs, jit[:4])]
                        + [((x0, y + j), (x0 + 20, y + j)) for (x0, y), j in zip(ys, jit[4:])])
        nv = np.array([(1.0, 0.0)] * 2 + [(-1.0, 0.0)] * 2 + [(0.0, 1.0)] * 2 + [(0.0, -1.0)] * 2)
        if trial % 3 == 0:
            img[:, 60:75] = rng.uniform(0, 255)              # a stroke across two stretches
        mc = rng.choice([0.25, 0.5])
        ts = _unit_steps(max(3, int(float(np.hypot(*(segs[0, 1] - segs[0, 0])))) + 1))
        for missing in (False, True):
            b1, b2 = np.empty(8), np.empty(8)
            l1, l2 = np.empty((8, 2)), np.empty((8, 2))
            got = _edge_offsets(img, segs, nv, prof, mc, missing, b1, l1)
            want = _edge_offsets_numpy(img, segs, nv, prof, mc, ts, missing, b2, l2)
            assert (got is None) == (want is None)
            if want is not None:
                found += 1
                assert _close(got, want, equal_nan=True)
                assert _close(b1, b2, equal_nan=True)
                assert _close(l1, l2, equal_nan=True)
    assert found > 30


def test_edge_offsets_outside_and_other_types():
    rng = np.random.default_rng(2)
    img = _step_image(rng)
    prof = _edge_profile(35.0, 1.5, 0.5)
    segs = np.array([((30.0, 40.0), (30.0, 60.0)), ((-4.0, 40.0), (-4.0, 60.0))])
    nv = np.array([(1.0, 0.0), (1.0, 0.0)])
    assert _edge_offsets(img, segs, nv, prof, 0.25) is None
    # a float64 image takes the numpy path, with the same offsets as float32
    segs = segs[:1]
    a = _edge_offsets(img, segs, nv[:1], prof, 0.25)
    b = _edge_offsets(img.astype(np.float64), segs, nv[:1], prof, 0.25)
    assert a is not None and b is not None and _close(a, b)


def test_valid_models_cache_keeps_its_bases():
    prof = _edge_profile(20.0, 1.0, 0.4)
    a = edges._valid_models(prof)
    assert edges._valid_models(prof) is a
    assert a[2].tolist() == np.flatnonzero(prof[3]).tolist()
    assert _PROFILE_U0.size * _PROFILE_SIG.size == prof[3].size


def test_one_stretch_takes_the_numpy_path():
    rng = np.random.default_rng(4)
    img = _step_image(rng)
    prof = _edge_profile(35.0, 1.5, 0.5)
    segs = np.array([((30.3, 40.0), (30.3, 60.0))])
    nv = np.array([(1.0, 0.0)])
    ts = _unit_steps(21)
    got = _edge_offsets(img, segs, nv, prof, 0.25)
    want = _edge_offsets_numpy(img, segs, nv, prof, 0.25, ts, False, None, None)
    assert got is not None and _close(got, want)
