"""core.detect, two-colour (regulatory) signs: the extension from the orange top over the
white part (overcast light, grey-world gains, snow, grey walls, bold legend rows, large
numerals, thin plaques), the orange face's edges (``refine_rectangle``, ``white_beyond``),
signs cut by the image's edge, and thin orange strips that are no sign."""
import cv2
import numpy as np
import pytest
from detection_helpers import (
    BLACK,
    ORANGE,
    WHITE,
    _background,
    _default_detector,
    _foliage,
    _one,
    _plain,
    _regulatory,
    _render_art_sign,
)

from workzone_ros.core import color_model as cm
from workzone_ros.core.detect import ColorDetector, DetectorConfig, box_metrics
from workzone_ros.core.detect.rectangle import RECT_TOP_STRETCHES, refine_rectangle, white_beyond
from workzone_ros.interfaces import Box


def test_regulatory_two_color_extension(detector):
    img = _background()
    gt = _regulatory(img, 400, 80, 72, 90)
    d = _one(detector.detect(img), gt, 0.8)
    assert d.kind == 'regulatory' and d.box.h > 80
    no_ext = detector.with_config(extension=False)
    d0 = max(no_ext.detect(img), key=lambda d: d.box.area)
    assert d0.box.h < 40 and d0.box.iou(Box(*map(float, gt))) < 0.5


def test_orange_rectangle_without_white_is_not_extended(detector):
    img = _background()
    cv2.rectangle(img, (400, 150), (471, 185), ORANGE, -1)       # END ROAD WORK over trees
    cv2.putText(img, 'END', (420, 175), cv2.FONT_HERSHEY_DUPLEX, 0.6, BLACK, 2)
    d = _one(detector.detect(img), (400, 150, 72, 36), 0.8)
    assert d.kind == 'regulatory' and d.box.h < 40


def test_regulatory_extension_under_overcast_light(detector):
    """Flat, hazy light: the legend is grey, not black; the white part is judged relative."""
    img = _background()
    gt = _regulatory(img, 400, 80, 72, 90)
    hazy = cv2.addWeighted(img, 0.55, np.full_like(img, 70), 0.45, 0)
    d = _one(detector.detect(hazy), gt, 0.75)
    assert d.kind == 'regulatory' and d.box.h > 80


def test_regulatory_extension_under_a_blue_sky_with_gray_world(model):
    """Grey-world gains of a frame dominated by blue sky tint white sheeting yellow; the
    white bottom is still found (white as the camera saw it or after the gains)."""
    gw = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior,
                       {'gray_world': True}, {})
    det = ColorDetector(gw, DetectorConfig(colors=('orange',), use_prior=False))
    img = _background()
    img[:400] = (235, 150, 95)                       # deep blue sky over most of the frame
    gt = _regulatory(img, 400, 80, 72, 90)
    gains = cm.gray_world_gains(cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA))
    white = cv2.cvtColor(cm.apply_gains(np.array([[WHITE]], np.uint8), gains),
                         cv2.COLOR_BGR2HSV)[0, 0, 1]
    assert white > 45                                 # the gains make white "not white"
    d = _one(det.detect(img), gt, 0.8)
    assert d.kind == 'regulatory' and d.box.h > 80


def _snow(seed=0, shape=(480, 640)):
    """A winter scene: pale sky, dark trees at the sign's height, snow below."""
    rng = np.random.default_rng(seed)
    img = np.empty((*shape, 3), np.uint8)
    img[:] = (225, 222, 215)                               # overcast sky
    img[150:215] = (70, 90, 75)                            # tree line
    img[215:] = (236, 236, 234)                            # snow
    return cv2.add(img, rng.integers(0, 8, img.shape, dtype=np.uint8))


@pytest.mark.parametrize('size', [34, 44])
def test_regulatory_extension_ends_at_the_bottom_border_over_snow(detector, size):
    """A work-zone speed limit sign in front of snow: the white part runs on to the end of
    the reach; it ends at the sign's black bottom border."""
    img, gt = _render_art_sign(_snow(), 400.3, 190.4, size, key='work_zone_speed_limit')
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert d.color == 'orange'
    assert abs(d.box.y2 - g.y2) <= 2.0 and box_metrics(d.box, g)[0] > 0.8


@pytest.mark.parametrize('key', ['work_zone_speed_limit', 'work_zone_begin'])
@pytest.mark.parametrize('size', [24, 28, 44])
def test_bold_legend_row_over_snow_is_not_the_bottom_border(detector, key, size):
    """On a small blurred two-colour sign over snow a bold legend row is as dark as the
    bottom border: the box still ends at the bottom border, within a pixel."""
    img, gt = _render_art_sign(_snow(), 400.3, 190.4, size, key=key)
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert abs(d.box.y2 - g.y2) <= 1.0 and box_metrics(d.box, g)[0] > 0.9


@pytest.mark.parametrize('size', [26, 34, 44])
def test_two_colour_sign_ends_where_a_darker_grey_background_begins(detector, size):
    """A dim "WORK ZONE BEGINS" (winter light: orange sheeting at about the grey
    background's brightness) in front of a grey wall: the wall counts as white next to the
    dim orange, and every row below the sign is darker than the sheeting.  The box ends at
    the sign's bottom (its border merges with the wall), not at the "BEGINS" legend row."""
    img, gt = _render_art_sign(_plain((150, 153, 150), 8, size), 400.3, 190.4, size,
                               key='work_zone_begin', orange=(0, 66, 150))
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert abs(d.box.y2 - g.y2) <= 1.5 and box_metrics(d.box, g)[1] > 0.9


@pytest.mark.parametrize('bg', [130, 140])
def test_white_part_judged_against_its_own_level_over_a_duller_grey(bg):
    """A small dim "WORK ZONE BEGINS" (20 px; overcast haze: the orange at V 130, the white
    sheeting at 172) before a grey background at V 106-111, bright enough next to the
    orange to pass for white: the box is the whole sign, its bottom within a pixel."""
    img, gt = _render_art_sign(_plain((bg, bg, bg), 8, 20), 400.3, 190.4, 20,
                               key='work_zone_begin', orange=(0, 60, 180))
    img = cv2.addWeighted(img, 0.55, np.full_like(img, 70), 0.45, 0)
    g = Box(*map(float, gt))
    detector = _default_detector()
    d = _one(detector.detect(img), gt, 0.85)
    assert d.kind == 'regulatory' and abs(d.box.y2 - g.y2) <= 1.0, d.box


@pytest.mark.parametrize('size', [40, 56])
def test_speed_limit_under_a_thin_plaque_is_extended_over_its_legend(detector, size):
    """R2-1 + G20-5aP (the simulator's art): a thin orange WORK ZONE plaque over a tall white
    speed-limit sign whose large black numerals split the white rows.  The box reaches past
    the numerals to the sign's bottom (within 8 % of its height)."""
    img, gt = _render_art_sign(_foliage(), 300.3, 60.4, size, key='work_zone_speed_limit')
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.6)
    assert d.kind == 'regulatory' and abs(d.box.y2 - g.y2) <= 0.08 * g.h


def _rect_sign_value(x, y, w, h, shape=(80, 80), ss=8, blur=0.6, gain=None, seed=0):
    """Brightness of a rectangular sign's orange top (catalogue art: a black line 3 % of the
    width at 1.5-4.5 % from the edge) over a dark background, sub-pixel placed, blurred."""
    H, W = shape
    ys, xs = np.mgrid[0:H * ss, 0:W * ss]
    X, Y = (xs + 0.5) / ss, (ys + 0.5) / ss
    # distance inside the sign's outline (to the nearest edge)
    d = np.minimum(np.minimum(X - x, x + w - X), np.minimum(Y - y, y + h - Y))
    inside = (X >= x) & (X <= x + w) & (Y >= y) & (Y <= y + h)
    big = np.full(X.shape, 60.0, np.float32)
    big[inside] = 200.0
    big[inside & (d >= 0.015 * w) & (d < 0.045 * w)] = 20.0
    img = big.reshape(H, ss, W, ss).mean(axis=(1, 3))
    if gain is not None:
        img = img * (1.0 + gain * np.exp(-((np.arange(W) + 0.5 - x - w / 2) / (0.4 * w)) ** 2))[
            None]
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur)
    return img + np.random.default_rng(seed).normal(0, 2.0, img.shape).astype(np.float32)


@pytest.mark.parametrize('w, tol', [(22.0, 0.7), (40.0, 0.3)])
@pytest.mark.parametrize('gain', [None, 0.8])
def test_refine_rectangle_finds_the_orange_face_edges(w, gain, tol):
    """The orange top of a two-colour sign: from a hull box 1.5 px too wide on one side and
    1 px too high, the face's left, right and top edges (the border line's inner edge,
    4.5 % of the width inside the sign) come back within 0.3 px at 40 px; at 22 px the line
    (0.7 px) is lost in the blur and the error reaches 0.6 px.  Given the row where the
    extension ended, the bottom edge is measured too."""
    x, y, h = 20.3, 15.6, 1.4 * w
    img = _rect_sign_value(x, y, w, h, shape=(int(y + h) + 12, 80), gain=gain)
    face = 0.045 * w
    got = refine_rectangle(img, (x - 1.5, y - 1.0, w + 1.5, 0.4 * w), w,
                              bottom=float(int(y + h - face)))
    assert got is not None
    left, right, top, low = got
    assert abs(left - (x + face)) < tol and abs(right - (x + w - face)) < tol
    assert abs(top - (y + face)) < tol and abs(low - (y + h - face)) < tol
    assert refine_rectangle(img, (x - 1.5, y - 1.0, w + 1.5, 0.4 * w), w)[3] is None
    assert refine_rectangle(np.full((60, 60), 90, np.float32), (10, 10, 30, 12), 30) is None


def test_refine_rectangle_side_without_a_step_measured_on_the_white_part():
    """A two-colour sign whose orange part's left side shows no step (a small plaque's
    legend reaching it, a dim line merging with a background as bright as the face): with
    the white part's last row given, that side is measured on the white part below it
    (within 0.4 px at 30 px); without a white part nothing is returned."""
    x, y, w = 20.3, 15.6, 30.0
    h = 1.4 * w
    img = _rect_sign_value(x, y, w, h, shape=(int(y + h) + 12, 80))
    face = 0.045 * w
    img[:int(y + 0.4 * w) + 1, :int(x + 3 * face)] = 200.0      # no step beside the orange
    box = (x - 1.0, y - 1.0, w + 2.0, 0.4 * w)
    got = refine_rectangle(img, box, w, bottom=float(int(y + h - face)), free_top=True)
    assert got is not None
    assert abs(got[0] - (x + face)) < 0.4 and abs(got[1] - (x + w - face)) < 0.4
    assert refine_rectangle(img, box, w, free_top=True) is None


@pytest.mark.parametrize('w, short', [(24.0, 3.0), (30.0, 3.5), (40.0, 4.0)])
def test_refine_rectangle_hull_short_of_a_pale_side(w, short):
    """A two-colour sign whose orange hull stops 3-4 px short of its left side (over-
    exposed sheeting turning pale yellow at the side): the edge lies beyond the search on
    both parts, so the side's stretches are moved out by 1.5 or 3 px and the edge is
    found within 0.4 px.  A blob not known to be a two-colour sign (no white part below
    it) gets no such second search: it may be a diamond merged with a sky."""
    x, y = 20.3, 15.6
    h = 1.4 * w
    img = _rect_sign_value(x, y, w, h, shape=(int(y + h) + 12, 80))
    face = 0.045 * w
    box = (x + short, y - 1.0, w - short + 1.0, 0.4 * w)
    got = refine_rectangle(img, box, w, bottom=float(int(y + h - face)), free_top=True)
    assert got is not None
    assert abs(got[0] - (x + face)) < 0.4 and abs(got[1] - (x + w - face)) < 0.4
    assert refine_rectangle(img, box, w, free_top=True) is None


def test_refine_rectangle_hull_wider_than_the_sign():
    """A 16 px sign whose orange hull took in 1.8 px of background on each side (a dusk
    sky of its colour): the face is 25 % narrower than the hull and is still measured,
    within 0.4 px (``max_change`` 0.3, the detector's ``rect_max_change``); a
    ``max_change`` of 0.2 does not allow that change and gives None."""
    x, y, w = 20.3, 15.6, 16.0
    h = 1.8 * w
    img = _rect_sign_value(x, y, w, h, shape=(int(y + h) + 12, 70))
    face = 0.045 * w
    box = (x - 1.8, y - 1.0, w + 3.6, w)
    size = box[2] / 0.91                # as the detector derives it from the hull
    got = refine_rectangle(img, box, size, max_change=0.3)
    assert got is not None
    assert abs(got[0] - (x + face)) < 0.4 and abs(got[1] - (x + w - face)) < 0.4
    assert refine_rectangle(img, box, size, max_change=0.2) is None


def test_refine_rectangle_side_at_the_image_edge():
    """A sign at the image's right edge: the right side's profiles would leave the image,
    so that side is returned as None (the caller keeps the hull's and clips the box to
    the image) and the left and top are measured."""
    x, y, w = 20.3, 15.6, 30.0
    h = 1.4 * w
    img = _rect_sign_value(x, y, w, h, shape=(int(y + h) + 12, int(x + w) + 1))
    face = 0.045 * w
    got = refine_rectangle(img, (x - 1.0, y - 1.0, img.shape[1] - x + 1.0, 0.4 * w), w)
    assert got is not None and got[1] is None
    assert abs(got[0] - (x + face)) < 0.4 and abs(got[2] - (y + face)) < 0.4


def test_two_colour_sign_at_the_image_edge_boxed_to_it(detector):
    """A two-colour sign cut by the image's right edge: its left and top edges are
    measured, the box ends at the image's edge (as the labels, the visible part's box) and
    every side is within a pixel."""
    size = 40
    img, gt = _render_art_sign(_background(), 640 - size + 2.3, 190.4, size,
                               key='work_zone_speed_limit')
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert d.box.x2 <= 640.0
    assert max(abs(d.box.x - g.x), abs(d.box.y - g.y), abs(d.box.x2 - g.x2),
               abs(d.box.y2 - g.y2)) <= 1.0, (d.box, g)


@pytest.mark.parametrize('size', [30, 48])
def test_art_two_colour_sign_box_from_its_edges(detector, size):
    """The simulator's WORK ZONE BEGINS art at sub-pixel positions: every side of the box
    within a pixel of the label, under half a pixel on average."""
    errs = []
    for off in (0.0, 0.3, 0.6):
        img, gt = _render_art_sign(_background(), 380.3 + off, 110.6 + off, size,
                                   key='work_zone_begin')
        g = Box(*map(float, gt))
        d = _one(detector.detect(img), gt, 0.7)
        assert d.kind == 'regulatory'
        errs.append([d.box.x - g.x, g.x2 - d.box.x2, d.box.y - g.y, g.y2 - d.box.y2])
    errs = np.abs(errs)
    assert errs.max() <= 1.0 and errs.mean() <= 0.45, errs


def test_extension_crosses_large_numerals_with_noisy_black(detector):
    """A speed-limit sign under an orange WORK ZONE plaque: rows of large black numerals
    cover most of the width, and a dark stroke's saturation is noise (a camera's black is
    not grey).  The extension still reaches the sign's bottom: legend rows are judged
    achromatic on their bright (white) pixels."""
    img = _background()
    x, y, w, h = 400, 80, 40, 70
    cv2.rectangle(img, (x, y), (x + w - 1, y + h - 1), WHITE, -1)
    cv2.rectangle(img, (x, y), (x + w - 1, y + 13), ORANGE, -1)
    cv2.rectangle(img, (x + 1, y + 1), (x + w - 2, y + h - 2), BLACK, 2)
    cv2.putText(img, 'SPEED', (x + 5, y + 24), cv2.FONT_HERSHEY_PLAIN, 0.8, BLACK, 1)
    cv2.putText(img, '50', (x + 5, y + 58), cv2.FONT_HERSHEY_DUPLEX, 0.9, BLACK, 3)
    rng = np.random.default_rng(5)
    sign = img[y:y + h, x:x + w]
    dark = sign.max(axis=2) < 60
    noise = rng.integers(0, 28, sign.shape).astype(np.uint8)
    sign[dark] = cv2.add(sign, noise)[dark]            # dark pixels: S up to ~200
    gt = (x, y, w, h)
    d = _one(detector.detect(img), gt, 0.7)
    assert d.kind == 'regulatory'
    assert abs(d.box.y2 - (y + h)) <= 2.0, d.box


@pytest.mark.parametrize('width', [20, 24, 30])
def test_extension_bridges_a_bold_legend_row(detector, width):
    """A small two-colour sign whose bold legend row ("BEGINS") is ink across its white
    part, too few bright pixels to tell its colour by: as black it is bridged like a legend
    gap, and the white part runs on to the sign's bottom border."""
    img = _foliage()
    x0, y0 = 400, 150
    h = int(round(1.25 * width))                       # a catalogue two-colour h / w
    top = h // 3
    cv2.rectangle(img, (x0, y0), (x0 + width - 1, y0 + h - 1), (22, 22, 22), -1)
    cv2.rectangle(img, (x0 + 1, y0 + 1), (x0 + width - 2, y0 + top - 1), ORANGE, -1)
    cv2.rectangle(img, (x0 + 1, y0 + top + 1), (x0 + width - 2, y0 + h - 2), (235, 238, 238),
                  -1)
    band = y0 + top + int(0.45 * (h - top))
    cv2.rectangle(img, (x0 + 2, band), (x0 + width - 3, band + max(3, h // 7)), (22, 22, 22),
                  -1)
    img = cv2.GaussianBlur(img, (0, 0), 0.7)
    gt = (x0, y0, width, h)
    d = _one(detector.detect(img), gt, 0.3)
    assert abs(d.box.y2 - (y0 + h)) <= 1.5, (d.box, gt)


def test_rectangle_top_measured_beside_the_legend():
    """A work-zone speed-limit sign under a dim reddish dusk sky, the legend's first line
    just under the plaque's top border: the plaque's top edge, measured on stretches near
    its corners (``RECT_TOP_STRETCHES``), is right on average (within 0.15 px) and within
    0.3 px in most placements."""
    errs = []
    for size in (22, 26, 32, 40):
        for off in (0.0, 0.25, 0.5, 0.75):
            img = _plain((48, 62, 85), 6, int(size * 10 + off * 4))
            x, y = 400.0 + off, 190.0 + off
            img, _ = _render_art_sign(img, x, y, size, key='work_zone_speed_limit', blur=0.8)
            face_top = y + 0.045 * size                 # inside the border line and margin
            hull = (x + 0.5, y + 0.5, size - 1.0, 0.25 * 1.75 * size - 1.0)
            r = refine_rectangle(img.max(axis=2), hull, size, free_top=True,
                                 top_at=RECT_TOP_STRETCHES)
            assert r is not None and r[2] is not None
            errs.append(r[2] - face_top)
    errs = np.array(errs)
    assert abs(errs.mean()) < 0.15 and np.median(np.abs(errs)) < 0.3


@pytest.mark.parametrize('size', [16, 18])
def test_small_two_colour_sign_thinner_than_the_radius_filter(detector, size):
    """A 16-18 px wide "WORK ZONE BEGINS": its orange part (6-7 px) is thinner than the
    radius filter (``min_radius_px``); it is kept as a regulatory sign because the
    extension finds the white part below it (``thin_min_radius_px``)."""
    img, gt = _render_art_sign(_background(), 400.3, 190.4, size, key='work_zone_begin')
    d = _one(detector.detect(img), gt, 0.5)
    assert d.color == 'orange' and d.kind == 'regulatory'


def test_thin_orange_strip_without_a_white_part_is_not_a_sign(detector):
    """An orange strip as thin as a small plaque but with nothing white below it (a
    vehicle's stripe, a barrier's band) stays below the radius filter."""
    img = _background()
    cv2.rectangle(img, (400, 190), (421, 195), ORANGE, -1)
    img = cv2.GaussianBlur(img, (0, 0), 0.7)
    assert not [d for d in detector.detect(img) if d.box.x < 430 and d.box.x2 > 395
                and d.box.y < 200 and d.box.y2 > 185]


def test_white_beyond_a_side_measured_inside_the_sign():
    """:func:`white_beyond`: a white part (a black border line, a grey legend bar) whose
    face is given at its true sides is not white beyond them; given 3 px inside on one side,
    it is; at the image's edge it says nothing."""
    img = np.full((120, 160, 3), (60, 120, 60), np.uint8)            # green verge
    cv2.rectangle(img, (49, 29), (91, 91), (0, 0, 0), -1)            # border line
    cv2.rectangle(img, (50, 30), (90, 90), (235, 235, 235), -1)      # white sheeting
    cv2.rectangle(img, (58, 55), (82, 62), (40, 40, 40), -1)         # legend
    assert not white_beyond(img, (50.0, 91.0), (30.0, 91.0), 2.0)
    assert white_beyond(img, (53.0, 91.0), (30.0, 91.0), 2.0)
    assert white_beyond(img, (50.0, 88.0), (30.0, 91.0), 2.0)
    assert not white_beyond(img[:, 51:], (0.0, 40.0), (30.0, 91.0), 2.0)
