"""tools.train_color: colour augmentation and background hue rotation (no training run)."""
import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.tools import train_color as tc


def _frame():
    img = np.full((60, 80, 3), (120, 122, 125), np.uint8)        # grey asphalt
    img[:20] = (200, 150, 90)                                      # blue sky
    face = np.zeros(img.shape[:2], bool)
    img[30:50, 30:50] = (0, 110, 245)                              # orange sign
    face[30:50, 30:50] = True
    return img, face


def test_augment_stays_in_camera_ranges():
    img, face = _frame()
    rng = np.random.default_rng(0)
    hues = []
    for _ in range(20):
        out = tc.augment(img, rng)
        assert out.shape == img.shape and out.dtype == np.uint8
        hues.append(int(cv2.cvtColor(out[40:41, 40:41], cv2.COLOR_BGR2HSV)[0, 0, 0]))
    # the sign stays orange-ish (hue within the jitter plus white balance), never blue
    assert all(h <= 30 or h >= 170 for h in hues) and len(set(hues)) > 2


def test_background_hue_rotation_keeps_the_sign():
    img, face = _frame()
    rng = np.random.default_rng(1)
    hsv0 = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    out = tc.rotate_background_hue(img, face, rng, warm=1.0)
    hsv = cv2.cvtColor(out, cv2.COLOR_BGR2HSV)
    assert abs(int(hsv[40, 40, 0]) - int(hsv0[40, 40, 0])) <= 1          # sign untouched
    assert hsv[5, 5, 0] <= 31                                          # sky into earth tones
    assert abs(int(hsv[5, 5, 1]) - int(hsv0[5, 5, 1])) <= 3             # same saturation


def test_table_hsv_normalises_saturation():
    img, _ = _frame()
    dull = cv2.addWeighted(img, 0.3, np.full_like(img, 150), 0.7, 0)   # haze
    norm = cm.SatNorm(0.9, 120.0, 4.0)
    raw = cv2.cvtColor(dull, cv2.COLOR_BGR2HSV)[40, 40, 1]
    assert tc.table_hsv(dull, False, norm, 30)[40, 40, 1] > 2 * raw
    assert tc.table_hsv(dull, False, None, 30)[40, 40, 1] == raw
