"""``workzone_ros.tools.cnn_augment``: the camera-like degradation of CNN training crops."""
import cv2
import numpy as np

from workzone_ros.tools import cnn_augment


def test_optics_blur_shares_include_motion_blur(monkeypatch):
    """``_optics`` blurs 45 % of crops with a Gaussian and the next 15 % with a 3-5 px
    linear motion blur (horizontal, or vertical 30 % of the time): a dashcam on a moving
    vehicle.  The motion branch was once unreachable (``elif r < 0.42`` after ``r < 0.45``).
    """
    kernels, gaussians = [], [0]
    filter2d, gaussian = cv2.filter2D, cv2.GaussianBlur

    def counting_filter2d(img, ddepth, kern, *args, **kwargs):
        kernels.append(np.array(kern))
        return filter2d(img, ddepth, kern, *args, **kwargs)

    def counting_gaussian(*args, **kwargs):
        gaussians[0] += 1
        return gaussian(*args, **kwargs)

    monkeypatch.setattr(cnn_augment.cv2, 'filter2D', counting_filter2d)
    monkeypatch.setattr(cnn_augment.cv2, 'GaussianBlur', counting_gaussian)
    img = np.zeros((16, 16, 3), np.float32)
    img[:, 8:] = 255.0                                  # a sharp vertical edge
    n = 400
    for seed in range(n):
        out = cnn_augment._optics(img.copy(), np.random.default_rng(seed))
        assert out.shape == img.shape and out.dtype == np.float32
    assert 0.35 * n < gaussians[0] < 0.55 * n           # Gaussian: 45 %
    assert 0.08 * n < len(kernels) < 0.22 * n           # motion blur: 15 %
    vertical = 0
    for kern in kernels:
        k = kern.shape[0]
        assert kern.shape == (k, k) and 3 <= k <= 5
        assert np.isclose(kern.sum(), 1.0)
        is_vertical = bool(np.count_nonzero(kern[:, k // 2]) == k)
        line = kern[:, k // 2] if is_vertical else kern[k // 2]
        vertical += is_vertical
        assert np.allclose(line, 1.0 / k) and np.count_nonzero(kern) == k
    assert 0 < vertical < len(kernels)                  # both directions occur
