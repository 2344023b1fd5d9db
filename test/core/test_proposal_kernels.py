"""The proposals' compiled component sums give numpy's figures to the bit."""
from __future__ import annotations

import cv2
import numpy as np

from workzone_ros.core.kernels import components_with_stats
from workzone_ros.core.proposal_kernels import component_sums


def _numpy_sums(labels, n, prob, sat, val):
    lab = labels.ravel()
    out = np.zeros((n, 4))
    v = val.ravel()
    for k, w in enumerate((prob.ravel(), sat.ravel(), v,
                           np.square(v, dtype=np.float32))):
        out[:, k] = np.bincount(lab, weights=w, minlength=n)
    return out


def test_component_sums_match_numpy_on_the_kept_labels_and_skip_the_rest():
    rng = np.random.default_rng(3)
    mask = (cv2.blur(rng.random((120, 160)).astype(np.float32), (5, 5)) > 0.52
            ).astype(np.uint8)
    n, labels, _ = components_with_stats(mask, 4)
    assert n > 20
    prob = rng.random((120, 160)).astype(np.float32)
    hsv = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)    # channels are strided views
    keep = rng.random(n) < 0.5
    keep[0] = False
    got = component_sums(labels, mask, keep, prob, hsv[..., 1], hsv[..., 2])
    want = _numpy_sums(labels, n, prob, hsv[..., 1], hsv[..., 2])
    assert np.array_equal(got[keep], want[keep])
    assert not got[~keep].any()
