"""Tests for the procedural sign art (sim/signart.py)."""
import itertools

import cv2
import numpy as np
import pytest

from workzone_ros.core import signs
from workzone_ros.core.signs import UnknownSignError
from workzone_ros.sim import signart

KEYS = [c.key for c in signs.CATALOGUE if c.key != 'background']


def _on_grey(face: np.ndarray, size: int = 64) -> np.ndarray:
    """Composite a face on grey in a size x size square (what a classifier crop sees)."""
    rgb = signart.over(face, 128.0)
    out = np.full((size, size, 3), 128.0, np.float32)
    h, w = rgb.shape[:2]
    oy, ox = (size - h) // 2, (size - w) // 2
    out[oy:oy + h, ox:ox + w] = rgb
    return out


@pytest.mark.parametrize('key', KEYS)
def test_every_class_renders_at_64px(key):
    face = signart.sign_face(key, 64)
    assert face.dtype == np.uint8 and face.ndim == 3 and face.shape[2] == 4
    assert max(face.shape[:2]) == 64
    alpha = face[..., 3]
    assert alpha.max() == 255
    shape = signs.get(key).shape
    if shape in ('diamond', 'octagon', 'triangle'):
        assert alpha[0, 0] == 0 and alpha[-1, -1] == 0 or shape == 'triangle'
        assert alpha[-1, 0] == 0 and alpha[-1, -1] == 0
    else:
        assert alpha[alpha.shape[0] // 2, 1] > 0
    assert (face[..., :3][alpha > 250].std(axis=0) > 10).any()   # not a flat colour


#: Text-only signs that differ in one word (W20-5L / W20-5R): only that word differs.
ONE_WORD_PAIRS = {('left_lane_closed_ahead', 'right_lane_closed_ahead')}


def test_classes_pairwise_different_at_64px():
    crops = {k: _on_grey(signart.sign_face(k, 64)) for k in KEYS}
    for a, b in itertools.combinations(KEYS, 2):
        d = np.abs(crops[a] - crops[b]).mean(-1)
        local = float(cv2.resize(d, (8, 8), interpolation=cv2.INTER_AREA).max())
        floor = 1.5 if (a, b) in ONE_WORD_PAIRS else 6.0
        assert d.mean() > floor, f'{a} and {b} look alike at 64 px ({d.mean():.1f})'
        assert local > 30.0, f'{a} and {b}: no 8x8 block differs clearly ({local:.1f})'


@pytest.mark.parametrize('key', sorted(signart.VARIANTS))
def test_variants_differ_and_the_first_is_the_default(key):
    variants = signart.VARIANTS[key]
    faces = [_on_grey(signart.sign_face(key, 64, variant=v)) for v in variants]
    for a, b in itertools.combinations(faces, 2):
        assert np.abs(a - b).mean() > 6.0
    assert np.array_equal(faces[0], _on_grey(signart.sign_face(key, 64)))


def _red_share(face: np.ndarray) -> float:
    hsv = cv2.cvtColor(np.ascontiguousarray(face[..., :3]), cv2.COLOR_BGR2HSV)
    red = ((hsv[..., 0] < 8) | (hsv[..., 0] > 170)) & (hsv[..., 1] > 120)
    return float(np.count_nonzero(red & (face[..., 3] > 250))) / face[..., 3].size


def test_stop_ahead_is_a_yellow_diamond_with_a_red_octagon():
    """Cahail et al., Fig. 3.8: a red symbol on a warning sign (W3-1 STOP AHEAD)."""
    face = signart.sign_face('warning_diamond', 128, variant='stop_ahead')
    assert 0.03 < _red_share(face) < 0.15
    assert _red_share(signart.sign_face('warning_diamond', 128)) == 0.0
    assert face[0, 0, 3] == 0


@pytest.mark.parametrize('left,right', signart.MIRROR_PAIRS)
def test_left_right_are_mirror_images(left, right):
    lf = signart.sign_face(left, 128).astype(np.float32)
    rf = signart.sign_face(right, 128).astype(np.float32)
    assert np.abs(lf - rf).mean() > 5.0                      # really different ...
    assert np.abs(lf[:, ::-1] - rf).mean() < 2.0             # ... and mirror-related


@pytest.mark.parametrize('key,size', [('road_work_ahead', 32), ('right_lane_ends', 48),
                                      ('work_zone_speed_limit', 40)])
def test_shape_fills_its_rectangle_centred(key, size):
    # the outline spans the whole face rectangle, centred: the box labels drawn from the
    # alpha are the sign's (the art was half a drawing pixel right of and below its
    # rectangle, the right and bottom tips cut: labels up to a pixel short on those sides)
    alpha = signart.sign_face(key, size)[..., 3].astype(np.float64) / 255.0
    h, w = alpha.shape
    cx = (alpha * np.arange(w)).sum() / alpha.sum()
    cy = (alpha.T * np.arange(h)).sum() / alpha.sum()
    assert abs(cx - (w - 1) / 2) < 0.02 and abs(cy - (h - 1) / 2) < 0.02
    # the first and last rows and columns hold the same share of the shape
    assert abs(alpha[:, 0].mean() - alpha[:, -1].mean()) < 0.02
    assert abs(alpha[0].mean() - alpha[-1].mean()) < 0.02
    shape = signs.get(key).shape
    exact = 0.5 * w * h if shape == 'diamond' else float(w * h)
    assert abs(alpha.sum() / exact - 1.0) < 0.06          # anti-aliased edge: a little more


@pytest.mark.parametrize('key', ['end_road_work', 'work_zone_begin', 'speed_limit'])
def test_rectangle_border_line_symmetric(key):
    # the border line lies as far in from the right edge as from the left one (it was a
    # drawing pixel further in on the right and bottom)
    f = signart.sign_face(key, 96)
    dark = 255.0 - f[..., :3].astype(np.float64).mean(-1)[int(0.9 * f.shape[0])]
    cols = np.arange(8) + 0.5                       # pixel centres from the edge
    left = (dark[:8] * cols).sum() / dark[:8].sum()
    right = (dark[::-1][:8] * cols).sum() / dark[::-1][:8].sum()
    assert abs(left - right) < 0.05, (left, right)


def test_colours_of_work_zone_and_general_signs():
    def main_colour(key):
        f = signart.sign_face(key, 128)
        px = f[..., :3][f[..., 3] > 250].reshape(-1, 3)
        vals, counts = np.unique(px // 16, axis=0, return_counts=True)
        return vals[counts.argmax()] * 16 + 8

    b, g, r = main_colour('road_work_ahead')
    assert r > 200 and 80 < g < 140 and b < 40                # fluorescent orange
    b, g, r = main_colour('stop')
    assert r > 150 and g < 80 and b < 80                      # red
    b, g, r = main_colour('warning_diamond')
    assert r > 200 and g > 170 and b < 60                     # yellow
    b, g, r = main_colour('guide')
    assert g > r and g > b                                    # green
    f = signart.sign_face('work_zone_begin', 150)
    top, bottom = f[10:int(f.shape[0] * 0.28), 20:-20, :3], f[-60:-20, 20:-20, :3]
    assert np.median(top[..., 2]) > 200 and np.median(top[..., 0]) < 60    # orange top
    assert np.median(bottom.reshape(-1, 3), axis=0).min() > 200           # white bottom


def test_cache_and_speed_value():
    a = signart.sign_face('work_zone_speed_limit', 96)
    assert signart.sign_face('work_zone_speed_limit', 96) is a
    assert not a.flags.writeable
    b = signart.sign_face('work_zone_speed_limit', 96, speed_value=55)
    assert np.abs(a.astype(int) - b.astype(int)).mean() > 0.5


def test_aspect_follows_catalogue():
    for key in KEYS:
        w, h = signart.face_size(key, 200)
        c = signs.get(key)
        want = 1.0 if c.shape == 'diamond' else c.width_m / c.height_m
        assert abs(w / h - want) < 0.02


def test_unknown_class_raises():
    with pytest.raises(UnknownSignError):
        signart.sign_face('no_such_sign')
    with pytest.raises(UnknownSignError):
        signart.sign_face('background')
    with pytest.raises(ValueError):
        signart.sign_face('other_workzone', variant='nope')
    with pytest.raises(ValueError, match='warning_diamond variant'):
        signart.sign_face('warning_diamond', variant='flagger')


def test_drum_texture():
    tex = signart.drum_texture()
    assert tex.shape == (96, 64, 3)
    assert cv2.cvtColor(tex, cv2.COLOR_BGR2HSV)[..., 1].max() > 200
