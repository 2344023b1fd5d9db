"""The band tests' compiled row profiles against their numpy forms on random masks."""
from __future__ import annotations

import numpy as np
import pytest

from workzone_ros.core.profile_kernels import banded_kernel, row_share_at_least, taper_kernel


def _banded_numpy(orange, white, dark, top, bottom, min_run, gap, max_band, min_beyond=3,
                  min_white=0.5, min_orange=0.2, line=0.9):
    """The band search in numpy and Python (row sums, then a walk over the rows)."""
    n = orange.shape[0]
    w = float(orange.shape[1])
    is_w = white.sum(axis=1) / w >= min_white
    is_o = (orange.sum(axis=1) / w >= min_orange) & ~is_w
    is_d = dark.sum(axis=1) / w >= line
    is_w, is_o, is_d = is_w.tolist(), is_o.tolist(), is_d.tolist()
    for start, step in ((top - 1, -1), (bottom, 1)):
        i, n_white, first = start, 0, None
        while 0 <= i < n and not is_d[i]:
            if is_w[i]:
                n_white += 1
                first = i if first is None else first
            elif is_o[i]:
                k = i
                while 0 <= k < n and is_o[k]:
                    k += step
                if first is not None and n_white >= min_run and abs(k - i) >= min_beyond:
                    return True
                if first is None and abs(i - start) >= gap:
                    break
                if first is not None:
                    i = k
                    continue
            if first is None and abs(i - start) >= gap + 1:
                break
            if first is not None and abs(i - first) >= max_band:
                break
            i += step
    i = top
    while i < min(bottom, n):
        if is_o[i] or not (is_w[i] or not is_d[i]) or i == top:
            i += 1
            continue
        j = i
        while j < min(bottom, n) and not is_o[j] and not is_d[j]:
            j += 1
        if j < min(bottom, n) and is_o[j] and is_o[i - 1] and sum(is_w[i:j]) >= min_run:
            return True
        i = j + 1
    return False


def _taper_numpy(mask):
    """Mean width of the upper rows (15-40 %) over the lower rows' (60-85 %), in numpy."""
    m = mask > 0
    rows = np.nonzero(m.any(axis=1))[0]
    if rows.size < 5:
        return 1.0
    sub = m[rows]
    left = np.argmax(sub, axis=1).astype(float)
    right = (m.shape[1] - np.argmax(sub[:, ::-1], axis=1)).astype(float)
    yc = rows + 0.5
    y0 = yc[0] - 0.5
    t = (yc - y0) / (yc[-1] + 0.5 - y0)
    w = right - left
    up, lo = (t >= 0.15) & (t <= 0.4), (t >= 0.6) & (t <= 0.85)
    if not (up.any() and lo.any()):
        return 1.0
    return float(w[up].mean() / max(w[lo].mean(), 1e-6))


def _striped(rng, h, w):
    """Random strips of whole-row stripes (orange, white, dark) with some noise."""
    kind = rng.integers(0, 4, size=h)
    kind = np.repeat(kind[::3], 3)[:h]
    noise = rng.random((h, w))
    orange = (kind[:, None] == 0) & (noise > 0.2)
    white = (kind[:, None] == 1) & (noise > 0.3)
    dark = (kind[:, None] == 2) & (noise > 0.05)
    return orange, white, dark


def test_banded_kernel_matches_the_numpy_search():
    rng = np.random.default_rng(5)
    hits = 0
    for _ in range(600):
        h, w = int(rng.integers(4, 60)), int(rng.integers(1, 12))
        orange, white, dark = _striped(rng, h, w)
        top = int(rng.integers(0, h))
        bottom = int(rng.integers(top + 1, h + 1))
        run, gap, beyond = int(rng.integers(1, 4)), int(rng.integers(2, 5)), 3
        args = (orange, white, dark, top, bottom, run, gap, bottom - top + gap, beyond)
        want = _banded_numpy(*args)
        hits += want
        assert bool(banded_kernel(*args, 0.5, 0.2, 0.9)) == want
    assert 0 < hits < 600


@pytest.mark.parametrize('dtype', [np.bool_, np.uint8])
def test_taper_kernel_matches_numpy(dtype):
    rng = np.random.default_rng(6)
    for _ in range(300):
        h, w = int(rng.integers(1, 40)), int(rng.integers(1, 30))
        mask = (rng.random((h, w)) > rng.uniform(0.2, 0.95)).astype(dtype)
        if rng.random() < 0.5:
            mask = mask[1:, 1:]                          # a window: not contiguous
        if mask.size == 0:
            continue
        assert np.allclose(taper_kernel(mask), _taper_numpy(mask), rtol=1e-6, atol=1e-9)


def test_row_share_matches_numpy():
    rng = np.random.default_rng(7)
    for _ in range(200):
        m = rng.random((int(rng.integers(1, 30)), int(rng.integers(1, 20)))) > 0.5
        share = float(rng.uniform(0.1, 0.9))
        want = np.count_nonzero(m, axis=1) / m.shape[1] >= share
        assert np.array_equal(row_share_at_least(m, share), want)
        assert np.array_equal(row_share_at_least(m[:, 1:], share),
                              np.count_nonzero(m[:, 1:], axis=1) / max(m.shape[1] - 1, 1)
                              >= share) or m.shape[1] == 1
    assert not row_share_at_least(np.ones((3, 0), bool), 0.5).any()
