"""core.features: crop_sign at the border, log-polar vs raw intensity under scale (Seo et al.)."""
import cv2
import numpy as np
import pytest

from workzone_ros.core import features as ft
from workzone_ros.sim import signart


def sign_scene(key, scale=1.0, side=96, shift=(0, 0), bg=(90, 120, 100)):
    """A ``side`` px crop with the simulator's art of ``key`` filling 0.8 * scale of it."""
    img = np.full((side, side, 3), bg, np.float32)
    face = signart.sign_face(key, int(round(side * 0.8 * scale)))
    h, w = face.shape[:2]
    y0, x0 = (side - h) // 2 + shift[1], (side - w) // 2 + shift[0]
    alpha = face[..., 3:4].astype(np.float32) / 255.0
    img[y0:y0 + h, x0:x0 + w] = img[y0:y0 + h, x0:x0 + w] * (1 - alpha) + face[..., :3]
    return img.astype(np.uint8)


def _relative_distance(f):
    a, b = f[0].astype(np.float64), f[1].astype(np.float64)
    return np.linalg.norm(a - b) / np.sqrt(np.linalg.norm(a) * np.linalg.norm(b))


@pytest.mark.parametrize('key', ['road_work_ahead', 'lane_shift_left', 'work_zone_begin',
                                 'end_road_work', 'stop'])
@pytest.mark.parametrize('scale', [0.9, 1.1])
def test_log_polar_varies_less_than_raw_intensity_under_rescaling(key, scale):
    # Seo et al. III.B: the log-polar image reduces the variation of sign images
    crops = [sign_scene(key), sign_scene(key, scale)]
    lp = _relative_distance(ft.log_polar_features(crops))
    raw = _relative_distance(ft.raw_intensity_features(crops))
    centred = _relative_distance(ft.log_polar_features(crops, centred=True))
    assert lp < 0.75 * raw
    assert centred < 0.75 * raw


def test_feature_shapes_and_intensity_normalisation():
    crop = sign_scene('road_work_ahead')
    dark = (crop * 0.4).astype(np.uint8)
    lp = ft.log_polar_features([crop, dark], rho=32, theta=32)
    assert lp.shape == (2, 1024) and lp.dtype == np.float32
    # exposure changes the crop, not its normalised features
    assert _relative_distance(lp) < 0.05
    raw = ft.raw_intensity_features([crop[:50, :70]], size=100)
    assert raw.shape == (1, 10000) and np.isfinite(raw).all()


def test_centred_log_polar_follows_a_shifted_sign():
    crop = sign_scene('lane_shift_left', 0.8, shift=(14, -10))
    cx, cy, r = ft.foreground_frame(crop, 64)
    # the face centre in the 64 px resized crop
    assert abs(cx - (47.5 + 14) * 64 / 96) < 3 and abs(cy - (47.5 - 10) * 64 / 96) < 3
    centred = ft.log_polar_features([sign_scene('lane_shift_left', 0.8), crop], centred=True)
    seed = ft.log_polar_features([sign_scene('lane_shift_left', 0.8), crop])
    assert _relative_distance(centred) < 0.5 * _relative_distance(seed)


def test_mirror_features_of_a_mirror_image_are_opposite():
    crop = sign_scene('left_lane_ends')
    f = ft.mirror_features([crop, crop[:, ::-1], sign_scene('right_lane_ends')])
    assert np.allclose(f[0], -f[1], atol=1e-4)
    assert np.linalg.norm(f[0]) > 1.0
    # the simulator's right sign is the mirror of its left one
    assert np.dot(f[0], f[2]) < 0


def test_color_features_tell_orange_from_yellow_diamonds():
    orange = ft.color_features([sign_scene('lane_shift_left')])[0]
    yellow = ft.color_features([sign_scene('warning_diamond')])[0]
    centre = 2 * 4                      # a*, b* of the middle cell of the 3 x 3 grid
    assert orange[centre] > yellow[centre] + 15          # orange is redder (a*)


def test_crop_sign_inside_partly_outside_and_outside():
    frame = np.zeros((100, 200, 3), np.uint8)
    frame[:, :, 2] = np.arange(200)[None, :].astype(np.uint8)
    crop, vis = ft.crop_sign(frame, (50, 30, 20, 20), margin=0.1)
    assert crop.shape == (24, 24, 3) and vis == pytest.approx(1.0)
    assert crop[0, 0, 2] == 48                                  # x from 48
    # half the grown box beyond the right border: the visible part only
    crop, vis = ft.crop_sign(frame, (188, 40, 20, 20), margin=0.1)
    assert crop.shape == (24, 14, 3) and vis == pytest.approx(14 / 24)
    crop, vis = ft.crop_sign(frame, (-12, -12, 20, 20), margin=0.0)
    assert crop.shape == (8, 8, 3) and vis == pytest.approx(64 / 400)
    # fully outside, empty or non-finite boxes: nothing to classify
    assert ft.crop_sign(frame, (300, 40, 20, 20)) == (None, 0.0)
    assert ft.crop_sign(frame, (10, -50, 20, 20))[0] is None
    assert ft.crop_sign(frame, (10, 10, 0, 20)) == (None, 0.0)
    assert ft.crop_sign(frame, (np.nan, 10, 5, 5)) == (None, 0.0)


def test_crop_sign_squares_wide_boxes_like_the_training_crops():
    frame = np.zeros((200, 200, 3), np.uint8)
    crop, _ = ft.crop_sign(frame, (60, 90, 80, 20), margin=0.0)
    assert crop.shape[:2] == (20, 80)
    crop, _ = ft.crop_sign(frame, (60, 90, 80, 20), margin=0.0, square=True)
    assert crop.shape[:2] == (80, 80)
    crop, vis = ft.crop_sign(frame, (60, 90, 80, 20), margin=0.1, square=True)
    assert crop.shape[:2] == (96, 96) and vis == pytest.approx(1.0)


@pytest.mark.parametrize('kind', ['logpolar-centred+color+mirror', 'logpolar+mirror',
                                  'logpolar-centred', 'raw+color'])
def test_one_pass_features_equal_the_separate_ones(kind):
    crops = [sign_scene('stop'), sign_scene('lane_shift_right')[5:70, 10:90]]
    base, extra = ft.features(kind, crops)
    assert np.allclose(base, ft.base_features(kind, crops), atol=1e-5)
    separate = ft.extra_features(kind, crops)
    assert (extra is None) == (separate is None)
    if extra is not None:
        assert np.allclose(extra, separate, atol=1e-5)


def test_unknown_feature_kind_is_refused():
    with pytest.raises(ValueError, match='unknown feature kind'):
        ft.base_features('hog', [np.zeros((8, 8, 3), np.uint8)])
    assert 'logpolar' in ft.FEATURE_KINDS and 'raw' in ft.FEATURE_KINDS


def test_grey_and_tiny_crops_work():
    grey = cv2.cvtColor(sign_scene('stop'), cv2.COLOR_BGR2GRAY)
    assert np.isfinite(ft.log_polar_features([grey, np.zeros((3, 2, 3), np.uint8)])).all()
    assert np.isfinite(ft.log_polar_features([grey], centred=True)).all()
