"""The compiled round of the diamond's edge measurement (workzone_ros.core.diamond_kernels)
against numpy and OpenCV."""
import cv2
import numpy as np
import pytest

from workzone_ros.core import diamond_kernels as dk
from workzone_ros.core import edge_kernels as ek
from workzone_ros.core.detect import diamond as dm
from workzone_ros.core.detect.edges import (
    _PROFILE_SIG,
    _PROFILE_U0,
    _edge_offsets_numpy,
    _edge_profile,
    _unit_steps,
    _valid_models,
)


def _close(a, b):
    """Equal within rounding (bit for bit on this machine; a rounding apart elsewhere)."""
    return np.allclose(a, b, rtol=1e-6, atol=1e-9, equal_nan=True)


def _frame_numpy(cx, cy, a, b):
    """The diamond's edges as refine_diamond computed them in numpy."""
    p0 = np.array([(cx - a, cy), (cx, cy - b), (cx + a, cy), (cx, cy + b)])
    p1 = p0[[1, 2, 3, 0]]
    e = p1 - p0
    dvec = e / np.hypot(e[:, 0], e[:, 1])[:, None]
    nvec = np.stack([-dvec[:, 1], dvec[:, 0]], axis=1)
    inward = (nvec * (np.array([cx, cy]) - 0.5 * (p0 + p1))).sum(axis=1)
    nvec[inward < 0] *= -1.0
    return p0, e, nvec


def _round_numpy(img, diamond, f_from, f_to, shown, prof, min_contrast, bright):
    """A round's stretches and offsets in numpy and OpenCV: (lost or None, segs, mids, nv,
    off, blur)."""
    p0, e, nvec = _frame_numpy(*diamond)
    segs = np.stack([p0[:, None] + f_from[..., None] * e[:, None],
                     p0[:, None] + f_to[..., None] * e[:, None]], axis=2).reshape(8, 2, 2)
    mids = 0.5 * (segs[:, 0] + segs[:, 1])
    nv = np.repeat(nvec, 2, axis=0)
    off, blur = np.full(8, np.nan), np.full(8, np.nan)
    n = int(shown.sum())
    b_, lv = np.empty(n), np.empty((n, 2))
    length = float(np.hypot(*(segs[shown][0, 1] - segs[shown][0, 0])))
    o_ = _edge_offsets_numpy(img, segs[shown], nv[shown], prof, min_contrast,
                             _unit_steps(max(3, int(length) + 1)), True, b_, lv)
    if o_ is None:
        return None, segs, mids, nv, off, blur
    off[shown] = o_ - bright * (lv[:, 1] > lv[:, 0])
    blur[shown] = b_
    return int(np.count_nonzero(shown & ~np.isfinite(off))), segs, mids, nv, off, blur


def _diamond_image(rng, h=120, w=130):
    """A bright diamond face with a dark border line and a margin on a background, blurred,
    with noise; and the diamond (cx, cy, a, b)."""
    cx, cy = rng.uniform(55, 75), rng.uniform(50, 70)
    a, b = rng.uniform(22, 38), rng.uniform(22, 38)
    ys, xs = np.mgrid[:h, :w] + 0.5
    rel = np.abs(xs - cx) / a + np.abs(ys - cy) / b
    img = np.full((h, w), rng.uniform(20, 160), np.float32)
    img[rel <= 1.12] = rng.uniform(180, 250)            # margin
    img[rel <= 1.08] = rng.uniform(0, 40)               # border line
    img[rel <= 1.0] = rng.uniform(150, 230)             # face
    if rng.random() < 0.3:
        img[:, int(cx) - 3:int(cx) + 3] = rng.uniform(0, 255)      # a stroke or a pole
    img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.5, 1.5))
    return (img + rng.normal(0, 6, img.shape)).astype(np.float32), (cx, cy, a, b)


def test_unit_steps_are_linspace():
    for n in range(2, 400):
        assert _close(dk.unit_steps(n), np.linspace(0.0, 1.0, n))


def test_diamond_frame_is_numpys():
    rng = np.random.default_rng(1)
    for _ in range(500):
        d = (*rng.uniform(-50, 300, 2), *rng.uniform(0.5, 120, 2))
        for got, want in zip(dk.diamond_frame(*d), _frame_numpy(*d)):
            assert _close(got, want)


@pytest.mark.parametrize('seed', range(3))
def test_diamond_round_is_the_numpy_round(seed):
    rng = np.random.default_rng(seed)
    found = failed = 0
    for trial in range(80):
        img, (cx, cy, a, b) = _diamond_image(rng)
        # a start a little off (some rounds fail: stretches without a step, or outside)
        d = (cx + rng.normal(0, 2), cy + rng.normal(0, 2), a * rng.uniform(0.85, 1.15),
             b * rng.uniform(0.85, 1.15))
        if trial % 10 == 9:
            d = (d[0] + 60, d[1], d[2], d[3])                   # reaching outside
        m = min(d[2], d[3])
        prof = _edge_profile(m, 0.0676 * m, 0.022 * m)
        f_from, f_to, shown = dm._EDGE_FROM, dm._EDGE_TO, dm._ALL_SHOWN
        if trial % 4 == 3:                                      # some stretches hidden
            shown = rng.random(8) < 0.7
            shown[:2] = True
        mc, bright = rng.choice([0.25, 0.5]), rng.choice([0.0, 0.3])
        max_lost = int(rng.integers(0, 4))
        got = dk.diamond_round(img, *d, f_from, f_to, shown, prof[0], *_valid_models(prof),
                               prof[3], mc, _PROFILE_U0, _PROFILE_SIG, bright, max_lost)
        want = _round_numpy(img, d, f_from, f_to, shown, prof, mc, bright)
        for g, w in zip(got[1:4], want[1:4]):                   # segs, mids, nv
            assert _close(g, w)
        if want[0] is None or want[0] > max_lost:
            assert got[0] == -1
            failed += 1
            continue
        found += 1
        assert got[0] == want[0]
        assert _close(got[4], want[4]) and _close(got[5], want[5])
    assert found > 10 and failed > 10


def test_diamond_round_leaves_one_stretch_to_numpy():
    rng = np.random.default_rng(5)
    img, d = _diamond_image(rng)
    prof = _edge_profile(30.0, 2.0, 0.7)
    shown = np.zeros(8, bool)
    shown[3] = True
    got = dk.diamond_round(img, *d, dm._EDGE_FROM, dm._EDGE_TO, shown, prof[0],
                           *_valid_models(prof), prof[3], 0.25, _PROFILE_U0, _PROFILE_SIG,
                           0.0, 2)
    assert got[0] == -2


def test_edge_fit_stops_after_max_lost():
    rng = np.random.default_rng(9)
    img, (cx, cy, a, b) = _diamond_image(rng)
    img[:, :] = img.mean()                          # no edges anywhere: every stretch lost
    prof = _edge_profile(30.0, 2.0, 0.7)
    p0, e, nvec = dk.diamond_frame(cx, cy, a, b)
    segs = np.stack([p0 + 0.2 * e, p0 + 0.4 * e], axis=1)
    ts = _unit_steps(max(3, int(np.hypot(*(segs[0, 1] - segs[0, 0]))) + 1))
    out = [np.empty(4), np.empty(4, np.int64), np.empty(4), np.empty((4, 2))]
    args = (img, segs, nvec, prof[0], ts, *_valid_models(prof), prof[3], 0.25, _PROFILE_U0,
            _PROFILE_SIG, *out)
    assert ek.edge_fit(*args, 4) == 0
    assert ek.edge_fit(*args, 1) == -3
