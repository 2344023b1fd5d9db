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


def test_a_real_sign_is_transplanted_whole_onto_another_background():
    """``transplant`` copies the sign's box pixel for pixel into a canvas 1.4-2.2 times its
    size filled from the other background, and returns where it put it."""
    crop = np.zeros((40, 50, 3), np.uint8)
    crop[10:30, 12:36] = (0, 128, 255)                         # the sign's box
    crop[12:28, 14:34] = (20, 20, 20)                          # its legend
    backdrop = np.full((30, 30, 3), (90, 160, 60), np.uint8)  # a lawn
    for seed in range(20):
        canvas, (x, y, w, h) = cnn_augment.transplant(crop, (12, 10, 24, 20), backdrop,
                                                     np.random.default_rng(seed))
        assert (w, h) == (24, 20)
        assert 1.4 * 24 - 1 <= canvas.shape[1] <= 2.2 * 24 + 1
        xi, yi, w, h = int(x), int(y), int(w), int(h)
        assert np.array_equal(canvas[yi:yi + h, xi:xi + w], crop[10:30, 12:36])
        outside = np.ones(canvas.shape[:2], bool)
        outside[yi:yi + h, xi:xi + w] = False
        assert np.all(canvas[outside] == (90, 160, 60))


def _plaque_crop() -> np.ndarray:
    """A white panel under an orange top band (a work-zone speed limit) on grey."""
    crop = np.full((64, 64, 3), 110, np.uint8)
    crop[12:52, 20:44] = 240
    crop[12:20, 20:44] = (0, 110, 245)
    return crop


def test_keep_top_never_frames_or_covers_the_top_of_the_sign_away():
    """The WORK ZONE plaque tells a work-zone speed limit from a speed limit: with
    ``keep_top`` neither the framing nor the occluder hides it; without, some draws do."""
    crop, box = _plaque_crop(), (20, 12, 24, 40)
    lost = {True: 0, False: 0}
    for keep in (True, False):
        for seed in range(300):
            rng = np.random.default_rng(seed)
            win = cnn_augment._window(crop, box, rng, keep)
            img = win.astype(np.float32)
            if rng.random() < 0.5:
                cnn_augment._occlude(img, rng, None, keep)
            orange = (img[..., 2] > 200) & (img[..., 0] < 60)
            lost[keep] += np.count_nonzero(orange) < 0.4 * 8 * 24     # most of it hidden
    assert lost[True] == 0
    assert lost[False] > 10
