"""Module-scoped fixtures of the ``test_detection*`` modules (re-created per test module):
``model``, a colour model boosted on eight drawn frames, and ``detector``, the colour
detector on it without the location prior.  Their drawings: ``detection_helpers.py``."""
import cv2
import numpy as np
import pytest
from detection_helpers import ORANGE, _background, _diamond

from workzone_ros.core import color_model as cm
from workzone_ros.core.detect import ColorDetector, DetectorConfig


@pytest.fixture(scope='module')
def model():
    pos = np.zeros((cm.H_BINS, cm.S_BINS))
    neg = np.zeros_like(pos)
    rng = np.random.default_rng(1)
    for k in range(8):
        img = _background(k)
        mask = np.zeros(img.shape[:2], np.uint8)
        shade = rng.uniform(0.55, 1.0)
        _diamond(img, int(rng.integers(100, 540)), int(rng.integers(60, 200)),
                 int(rng.integers(10, 60)), tuple(c * shade for c in ORANGE), mask)
        cv2.rectangle(img, (20, 400), (60, 460), (30, 70, 140), -1)       # brown box
        cv2.circle(img, (600, 420), 20, (40, 35, 195), -1)                # red sign
        cv2.circle(img, (540, 420), 20, (10, 205, 250), -1)               # yellow sign
        p, n = cm.histogram_from_pixels(cv2.cvtColor(img, cv2.COLOR_BGR2HSV), mask, 50)
        pos += p
        neg += n
    clf = cm.fit_boosted(pos, neg, n_estimators=20)
    return cm.default_model(cm.boosted_lut(clf), 50)


@pytest.fixture(scope='module')
def detector(model):
    return ColorDetector(model, DetectorConfig(use_prior=False))
