"""The compiled blob helpers (workzone_ros.core.blob_kernels) against OpenCV and numpy."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from workzone_ros.core.blob_kernels import (
    blur_rings,
    chessboard_distance,
    clipped_outside,
    gated_likelihood,
    hull_points,
    masked_median_u8,
    mean32,
    pairwise_sum32,
    surround_ring,
)


def _masks(n: int, seed: int = 0):
    """Random masks: noise, filled polygons with holes, ellipses, diamonds with cut rows."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        h, w = (int(v) for v in rng.integers(1, 60, 2))
        m = np.zeros((h, w), np.uint8)
        kind = i % 4
        if kind == 0:
            m[:] = rng.random((h, w)) < rng.random()
        elif kind == 1:
            pts = rng.integers(0, [w, h], (int(rng.integers(3, 8)), 2)).astype(np.int32)
            cv2.fillConvexPoly(m, cv2.convexHull(pts), 1)
            m &= (rng.random((h, w)) < 0.9).astype(np.uint8)
        elif kind == 2:
            cv2.ellipse(m, (w // 2, h // 2), (w // 3 + 1, h // 3 + 1),
                        float(rng.integers(0, 90)), 0, 360, 1, -1)
        else:
            ys, xs = np.mgrid[:h, :w]
            m[:] = np.abs(xs + 0.5 - w / 2) / (w / 2.2) + np.abs(ys + 0.5 - h / 2) / (h / 2.2) <= 1
            m[rng.integers(0, h, 3)] = 0
        yield m


def test_hull_points_give_the_hull_of_all_pixels():
    n = 0
    for m in _masks(3000):
        if not m.any():
            assert hull_points(m).shape == (0, 1, 2)
            continue
        pts = hull_points(m)
        assert pts.dtype == np.int32 and pts.ndim == 3 and pts.shape[1:] == (1, 2)
        # a subset of the pixels, in findNonZero's order
        assert m[pts[:, 0, 1], pts[:, 0, 0]].all()
        order = pts[:, 0, 1].astype(np.int64) * m.shape[1] + pts[:, 0, 0]
        assert (np.diff(order) > 0).all()
        want = cv2.convexHull(cv2.findNonZero(m))
        got = cv2.convexHull(pts)
        assert got.shape == want.shape and (got == want).all()       # integer points
        # a bool mask and a slice of a larger mask give the same points
        assert (hull_points(m > 0) == pts).all()
        big = np.zeros((m.shape[0] + 2, m.shape[1] + 3), np.uint8)
        big[1:-1, 2:-1] = m
        assert (hull_points(big[1:-1, 2:-1]) == pts).all()
        n += 1
    assert n > 2500


@pytest.mark.parametrize('seed', range(3))
def test_masked_median_u8_is_np_median(seed):
    rng = np.random.default_rng(seed)
    for _ in range(500):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        hsv = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        lo, hi = sorted(int(v) for v in rng.integers(0, 256, 2))
        hsv[..., 2] = np.clip(hsv[..., 2], lo, hi)
        mask = rng.random((h, w)) < rng.random()
        if not mask.any():
            assert np.isnan(masked_median_u8(hsv[..., 2], mask))
            continue
        want = float(np.median(hsv[..., 2][mask]))
        for m in (mask, mask.astype(np.uint8)):
            assert np.allclose(masked_median_u8(hsv[..., 2], m), want, rtol=1e-6, atol=1e-9)


def test_gated_likelihood_is_the_table_lookup():
    rng = np.random.default_rng(4)
    for table in (rng.random((180, 256)).astype(np.float32),
                  rng.integers(0, 255, (180, 256)).astype(np.uint8)):
        for _ in range(50):
            h, w = (int(v) for v in rng.integers(1, 50, 2))
            bgr = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
            hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
            sat_tab = np.minimum(255, np.round(np.arange(256) * rng.uniform(1, 3))).astype(
                np.uint8)
            v_min = int(rng.integers(0, 120))
            want = table[hsv[..., 0], cv2.LUT(hsv[..., 1], sat_tab)]
            want[hsv[..., 2] < v_min] = 0
            got = gated_likelihood(table, hsv, sat_tab, v_min)
            assert got.dtype == table.dtype
            assert np.allclose(got, want, rtol=1e-6, atol=1e-9)
    with pytest.raises(IndexError):
        gated_likelihood(np.zeros((10, 256), np.float32), hsv, sat_tab, 0)


def test_clipped_outside_is_numpys_test():
    rng = np.random.default_rng(6)
    hits = 0
    for _ in range(400):
        h, w = (int(v) for v in rng.integers(1, 30, 2))
        frame = rng.integers(200, 256, (h + 2, w + 2, 3), dtype=np.uint8)
        bgr = frame[1:-1, 1:-1]                 # a window of the frame
        weak = (rng.random((h, w)) < 0.5).astype(np.uint8)
        near = (rng.random((h, w)) < rng.random()).astype(np.uint8)
        want = bool(((weak > 0) & (bgr[..., 2] >= 250) & (bgr[..., 1] < bgr[..., 2])
                     & (near == 0)).any())
        assert clipped_outside(bgr, weak, near) == want
        hits += want
    assert 50 < hits < 350


def test_mean32_is_np_mean_of_float32():
    rng = np.random.default_rng(8)
    for i in range(600):
        n = int(rng.integers(1, 40000)) if i % 4 == 0 else int(rng.integers(1, 300))
        a = (rng.random(n + 5) * rng.uniform(1e-3, 300)).astype(np.float32)
        got = mean32(a, 3, n)
        assert np.allclose(got, a[3:3 + n].mean(), rtol=1e-6, atol=1e-9)
        assert np.allclose(pairwise_sum32(a, 3, n), np.add.reduce(a[3:3 + n]), rtol=1e-6,
                           atol=1e-9)


def test_chessboard_distance_and_blur_rings_are_dilations():
    rng = np.random.default_rng(10)
    k3 = np.ones((3, 3), np.uint8)
    counts = set()
    for m in _masks(600, seed=2):
        like = rng.random(m.shape).astype(np.float32) * rng.uniform(0.2, 1.0)
        like[m > 0] = 1.0
        cap = int(rng.integers(1, 12))
        d = chessboard_distance(m, cap)
        # the rings of repeated dilations (numpy's loop) and the distances
        prev, blur, level = m, None, float(rng.uniform(0.05, 0.5))
        for k in range(1, cap + 1):
            nxt = cv2.dilate(prev, k3)
            ring = (nxt > 0) & (prev == 0)
            assert (ring == (d == k)).all()
            if blur is None and (not ring.any() or float(like[ring].mean()) < level):
                blur = k - 1
            prev = nxt
        assert ((d > cap) == (prev == 0)).all() and (d <= cap + 1).all()
        blur = cap if blur is None else blur
        assert blur_rings(m, like, level, cap) == blur
        counts.add(blur)
    assert len(counts) > 4


def _ring_numpy(mask, like, r1, r2, level):
    """The surround ring's (mean, share at ``level``) by two square dilations."""
    d1 = cv2.dilate(mask, np.ones((2 * r1 + 1, 2 * r1 + 1), np.uint8))
    d2 = cv2.dilate(mask, np.ones((2 * r2 + 1, 2 * r2 + 1), np.uint8))
    ring = (d2 > 0) & (d1 == 0)
    if not ring.any():
        return 0.0, 0.0
    lr = like[ring]
    return float(lr.mean()), float(np.count_nonzero(lr >= level) / lr.size)


def test_surround_ring_is_the_ring_between_two_dilations():
    rng = np.random.default_rng(11)
    for m in _masks(200, seed=4):
        like = rng.random(m.shape).astype(np.float32)
        r1 = int(rng.integers(1, 6))
        r2 = r1 + int(rng.integers(1, 8))
        level = float(rng.random())
        got = surround_ring(m, like, r1, r2, level)
        want = _ring_numpy(m, like, r1, r2, level)
        assert np.allclose(got, want, rtol=1e-6, atol=1e-9)
    # a level between a value and its float32 neighbour: compared in float32 as numpy does
    m = np.zeros((9, 9), np.uint8)
    m[4, 4] = 1
    like = np.full((9, 9), np.float32(0.1))
    level = float(np.float32(0.1)) + 1e-9
    assert surround_ring(m, like, 1, 2, level) == _ring_numpy(m, like, 1, 2, level)
