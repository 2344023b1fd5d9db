"""``workzone_ros.tools.cnn_augment``: the camera-like degradation of CNN training crops."""
import cv2
import numpy as np

from workzone_ros.tools import cnn_augment


def test_optics_blurs_some_crops_and_adds_noise_to_all(monkeypatch):
    """``_optics`` blurs about 45 % of the crops with a Gaussian (no other kernel) and adds
    sensor noise to every crop, keeping its shape and type."""
    gaussians = [0]
    gaussian = cv2.GaussianBlur

    def counting_gaussian(*args, **kwargs):
        gaussians[0] += 1
        return gaussian(*args, **kwargs)

    def no_filter2d(*args, **kwargs):
        raise AssertionError('no other blur kernel')

    monkeypatch.setattr(cnn_augment.cv2, 'GaussianBlur', counting_gaussian)
    monkeypatch.setattr(cnn_augment.cv2, 'filter2D', no_filter2d)
    img = np.full((16, 16, 3), 128.0, np.float32)
    n, changed = 400, 0
    for seed in range(n):
        out = cnn_augment._optics(img.copy(), np.random.default_rng(seed))
        assert out.shape == img.shape and out.dtype == np.float32
        changed += not np.array_equal(out, img)
    assert 0.35 * n < gaussians[0] < 0.55 * n
    assert changed > 0.95 * n
