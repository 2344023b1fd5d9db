"""Tests for the speed limit reader (core/digits.py) on our own sign art."""
import dataclasses

import cv2
import numpy as np
import pytest

from workzone_ros.core import digits
from workzone_ros.sim import signart

KEY = 'work_zone_speed_limit'
GRASS = (60, 110, 50)


def _crop(value: int, size: int, margin: float = 0.1, shift=(0.0, 0.0), bg=GRASS,
          key: str = KEY) -> np.ndarray:
    """The sign ``size`` px high on a flat background, grown by ``margin`` a side and
    shifted by ``shift`` (fractions of the sign's width, height), as a classifier crops it."""
    face = signart.sign_face(key, size, speed_value=value)
    h, w = face.shape[:2]
    H, W = int(round(h * (1 + 2 * margin))), int(round(w * (1 + 2 * margin)))
    big = np.empty((3 * H, 3 * W, 3), np.float32)
    big[:] = bg
    oy, ox = (3 * H - h) // 2, (3 * W - w) // 2
    big[oy:oy + h, ox:ox + w] = signart.over(face, big[oy:oy + h, ox:ox + w])
    cy, cx = 3 * H // 2 + int(round(shift[1] * h)), 3 * W // 2 + int(round(shift[0] * w))
    out = big[cy - H // 2:cy - H // 2 + H, cx - W // 2:cx - W // 2 + W]
    return np.clip(out, 0, 255).astype(np.uint8)


@pytest.mark.parametrize('value', [25, 45, 55, 65])
@pytest.mark.parametrize('size', [32, 48, 96, 200])
def test_reads_clean_sign_art(value, size):
    r = digits.read_speed_limit(_crop(value, size))
    assert r.value == value, r
    assert r.reason == ''
    assert digits.MIN_CONFIDENCE <= r.confidence <= 1.0


@pytest.mark.parametrize('value', [5, 10, 15, 30, 35, 40, 50, 60, 70, 75, 80, 85])
def test_reads_every_other_speed_at_64px(value):
    assert digits.read_speed_limit(_crop(value, 64)).value == value


def test_crop_below_min_height_is_not_read():
    crop = _crop(45, 18)
    assert crop.shape[0] < 24
    r = digits.read_speed_limit(crop, min_height_px=24)
    assert r.value is None and r.reason == 'too small' and r.confidence == 0.0
    # the same crop scaled up is read: the refusal is the size rule, not the content
    assert digits.read_speed_limit(crop, min_height_px=8).value in (45, None)


def test_drum_texture_is_not_a_speed_limit():
    drum = cv2.resize(np.ascontiguousarray(signart.drum_texture()), (48, 96),
                      interpolation=cv2.INTER_NEAREST)
    r = digits.read_speed_limit(drum)
    assert r.value is None and r.reason


def test_warning_diamond_is_not_a_speed_limit():
    face = signart.sign_face('warning_diamond', 96)
    crop = np.clip(signart.over(face, np.full(face.shape[:2] + (3,), 90.0, np.float32)),
                   0, 255).astype(np.uint8)
    r = digits.read_speed_limit(crop)
    assert r.value is None and r.reason


def test_white_speed_limit_without_plaque_reads_or_refuses_never_wrong():
    r = digits.read_speed_limit(_crop(65, 96, key='speed_limit'))
    assert r.value in (65, None)


def test_blurred_crop_still_reads():
    crop = cv2.GaussianBlur(_crop(55, 64), (0, 0), 1.0)
    assert digits.read_speed_limit(crop).value == 55


def test_vertical_motion_blur_still_reads():
    k = np.zeros((5, 5), np.float32)
    k[:, 2] = 1 / 5
    crop = cv2.filter2D(_crop(35, 96), -1, k)
    assert digits.read_speed_limit(crop).value == 35


@pytest.mark.parametrize('shift', [(0.1, 0.0), (-0.1, 0.0), (0.0, 0.1), (0.0, -0.1),
                                   (0.1, 0.1), (-0.1, -0.1)])
def test_ten_percent_shifted_crop_still_reads(shift):
    assert digits.read_speed_limit(_crop(45, 80, shift=shift)).value == 45


def test_noisy_jpeg_crop_still_reads():
    rng = np.random.default_rng(3)
    crop = np.clip(_crop(65, 64) + rng.normal(0, 6, (1,) + _crop(65, 64).shape[1:]), 0, 255)
    ok, buf = cv2.imencode('.jpg', crop.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 50])
    assert ok
    assert digits.read_speed_limit(cv2.imdecode(buf, cv2.IMREAD_COLOR)).value == 65


@pytest.mark.parametrize('keep', [0.55, 0.65, 0.75, 0.85])
def test_number_cut_by_the_crop_is_never_misread(keep):
    # 55 with its right side cut away: a lone '5' would be a wrong, plausible limit
    crop = _crop(55, 96)
    w = crop.shape[1]
    cut = crop[:, :int(round(0.1 * w + keep * 0.8 * w))]
    r = digits.read_speed_limit(cut)
    assert r.value in (55, None), r


@pytest.mark.parametrize('value', [50, 55, 25])
@pytest.mark.parametrize('at', [0.50, 0.53, 0.56])
def test_lone_first_digit_of_a_cut_number_is_not_read(value, at):
    # the crop (or the image border) cuts the sign between its two digits: '5' of 50 alone
    # is a valid speed and must not come out
    crop = _crop(value, 96)
    w = signart.sign_face(KEY, 96).shape[1]
    x0 = (crop.shape[1] - w) // 2
    r = digits.read_speed_limit(crop[:, :x0 + int(round(at * w))])
    assert r.value is None, r


@pytest.mark.parametrize('value', [50, 55, 15])
def test_lone_digit_off_the_centre_is_not_read(value):
    # the second digit painted over (faded, occluded): a lone '5' left of the centre
    crop = _crop(value, 96)
    h, w = signart.sign_face(KEY, 96).shape[:2]
    y0, x0 = (crop.shape[0] - h) // 2, (crop.shape[1] - w) // 2
    crop[y0 + int(0.64 * h):y0 + int(0.93 * h), x0 + int(0.5 * w):x0 + int(0.9 * w)] = 235
    r = digits.read_speed_limit(crop)
    assert r.value is None, r


@pytest.mark.parametrize('keep', [0.7, 0.75, 0.8])
def test_number_cut_at_the_bottom_is_not_read(keep):
    # the crop's rows (sign grown by 10 %): the number ends at 0.83 of them
    crop = _crop(85, 96)
    r = digits.read_speed_limit(crop[:int(keep * crop.shape[0])])
    assert r.value is None and r.reason, r


def test_not_a_multiple_of_five_is_not_returned():
    r = digits.read_speed_limit(_crop(43, 96))
    assert r.value is None and r.reason == 'not a speed'


def test_out_of_range_is_not_returned():
    r = digits.read_speed_limit(_crop(95, 96))
    assert r.value is None


def test_grey_and_bgra_inputs_are_read():
    crop = _crop(45, 96)
    grey = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
    bgra = cv2.cvtColor(crop, cv2.COLOR_BGR2BGRA)
    assert digits.read_speed_limit(bgra).value == 45
    assert digits.read_speed_limit(grey).value in (45, None)     # no orange without colour


@pytest.mark.parametrize('bad', [np.zeros((32, 32, 3), np.float32), np.zeros((32,), np.uint8),
                                 np.zeros((32, 32, 2), np.uint8)])
def test_bad_input_raises(bad):
    with pytest.raises(ValueError):
        digits.read_speed_limit(bad)


def test_empty_crop_is_too_small():
    assert digits.read_speed_limit(np.zeros((0, 0, 3), np.uint8)).reason == 'too small'


def test_reading_is_frozen_and_deterministic():
    a = digits.read_speed_limit(_crop(65, 64))
    b = digits.read_speed_limit(_crop(65, 64))
    assert a == b
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.value = 5


def test_higher_threshold_refuses_more():
    crop = cv2.GaussianBlur(_crop(25, 40), (0, 0), 1.2)
    r = digits.read_speed_limit(crop)
    strict = digits.read_speed_limit(crop, min_confidence=1.01)
    assert strict.value is None
    if r.value is not None:
        assert strict.reason == 'low confidence'


def test_digit_model_is_deterministic_and_separates_digits():
    m = digits.digit_model()
    assert m.samples > 1000 and m.W.shape == (len(digits.features(
        np.zeros((digits.GLYPH_H, digits.GLYPH_W), np.float32))), 10)
    again = digits.digit_model.__wrapped__()
    np.testing.assert_allclose(m.W, again.W)


def test_warm_up_runs():
    digits.warm_up()
