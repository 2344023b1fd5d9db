"""core.detect, orange things beside and behind signs that are no sign: cones and drums
(the band test on row profiles, the row taper, white caps), a stand's flags over a pale
sky, warm surfaces (brick walls, dirt piles: the surround test and ``rect_needs_edges``),
and growing a sign's mask over its paler or clipped parts without taking a surface in."""
import cv2
import numpy as np
import pytest
from detection_helpers import (
    BLACK,
    ORANGE,
    WHITE,
    _background,
    _diamond,
    _near,
    _one,
    _render_art_sign,
)

from workzone_ros.core import color_model as cm
from workzone_ros.core.detect import ColorDetector, DetectorConfig
from workzone_ros.core.detect.mask import _clipped_growth
from workzone_ros.core.profiles import banded_rows, row_taper, white_cap
from workzone_ros.interfaces import Box


def _step_model(prior):
    """A table shaped like the default model's: warm mid-saturation surfaces (brick, dry
    lawns, beige fronts) at 0.75, the sign's saturated sheeting at 0.98."""
    lut = np.zeros((cm.H_BINS, cm.S_BINS), np.float32)
    lut[4:22, 48:144] = 0.75
    lut[4:22, 144:] = 0.98
    return cm.default_model(lut, 60, prior)


def _brick_wall(img, x0, y0, x1, y1, seed=3):
    brick = cv2.cvtColor(np.uint8([[[9, 120, 165]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
    cv2.rectangle(img, (x0, y0), (x1, y1), brick, -1)
    for y in range(y0, y1, 12):                       # mortar courses
        cv2.line(img, (x0, y), (x1, y), (150, 150, 150), 1)
    noise = np.random.default_rng(seed).integers(0, 14, (y1 - y0, x1 - x0, 3), np.uint8)
    img[y0:y1, x0:x1] = cv2.add(img[y0:y1, x0:x1], noise)


def test_sign_in_front_of_a_brick_wall_is_separated():
    """On an unknown camera the location-free prior (the heat map's mean over its ROI)
    raises the posterior threshold above warm mid-saturation walls: the sign is found on
    its own, not merged with the brick behind it."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    det = ColorDetector(_step_model(prior), DetectorConfig(colors=('orange',)))
    img = _background(shape=(406, 722))
    _brick_wall(img, 360, 30, 640, 250)
    sign = _diamond(img, 474, 130, 36)
    gt = Box(*map(float, sign))
    dets = det.detect(img)
    assert len(dets) == 1
    d = dets[0].box
    # the face alone (the box may still grow by the soft-edge rings the wall passes)
    assert d.x <= gt.x + 2 and d.y <= gt.y + 2 and d.x2 >= gt.x2 - 2 and d.y2 >= gt.y2 - 2
    assert d.w * d.h < 2.5 * gt.w * gt.h and d.iou(gt) >= 0.4


@pytest.mark.parametrize('r', [60])
def test_diamond_paler_at_its_tips_is_grown_whole(r):
    """On another camera the posterior threshold is the sheeting's own likelihood (0.94
    here), and part of a diamond's face lies lower (paler under the sky: 0.85-0.95): above
    the threshold is only a band across its middle.  The diamond is still found whole, and
    the warm wall beside it (0.75) stays out of its box."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    lut = np.zeros((cm.H_BINS, cm.S_BINS), np.float32)
    lut[4:22, 48:100] = 0.75                       # brick, lawns, beige fronts
    lut[4:22, 100:170] = 0.90                      # the paler sheeting
    lut[4:22, 170:] = 0.98                         # the sheeting
    det = ColorDetector(cm.default_model(lut, 60, prior),
                           DetectorConfig(colors=('orange',)))
    img = _background(shape=(406, 722))
    _brick_wall(img, 520, 60, 700, 330)
    cx, cy = 380, 200
    pts = np.array([[cx, cy - r], [cx + r, cy], [cx, cy + r], [cx - r, cy]], np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    inner = np.array([[cx, cy - r + 4], [cx + r - 4, cy], [cx, cy + r - 4],
                      [cx - r + 4, cy]], np.int32)
    cv2.polylines(img, [inner], True, BLACK, max(1, r // 20))
    tips = (np.abs(np.arange(img.shape[0]) - cy) > 0.35 * r)[:, None] & (
        img == ORANGE).all(axis=2)
    img[tips] = (110, 170, 245)                    # saturation 141: likelihood 0.90
    gt = (cx - r, cy - r, 2 * r + 1, 2 * r + 1)
    d = _one(det.detect(img), gt, 0.85)
    assert d.kind == 'warning' and d.box.x2 < 520   # the wall is not in it


def _cone(img, cx, base_y, h):
    """A traffic cone side on (MUTCD 6F.63): an orange truncated cone, its top a quarter of
    its base, with a white retro-reflective band across it at 55-70 % of its height."""
    w = int(0.55 * h)
    top_y = base_y - h
    pts = np.array([[cx - w // 8, top_y], [cx + w // 8, top_y], [cx + w // 2, base_y],
                    [cx - w // 2, base_y]], np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    b0, b1 = top_y + int(0.3 * h), top_y + int(0.45 * h)
    band = np.zeros(img.shape[:2], np.uint8)
    cv2.fillConvexPoly(band, pts, 1)
    band[:b0] = 0
    band[b1:] = 0
    img[band > 0] = WHITE
    return (cx - w // 2, b1, w, base_y - b1)


def _drum(img, x, y, w, h, stripes=5):
    """A channelizing drum (MUTCD 6F.64): alternating horizontal orange and white stripes
    over its whole width, orange at the top and the bottom."""
    step = h / stripes
    for k in range(stripes):
        cv2.rectangle(img, (x, int(y + k * step)), (x + w - 1, int(y + (k + 1) * step) - 1),
                      ORANGE if k % 2 == 0 else WHITE, -1)
    return (x, y, w, h)


def test_banded_rows_cone_drum_and_two_colour_sign():
    """The band test on row masks: a white band with orange beyond it (cone, drum) is one;
    a two-colour sign's white part ending at its black border is not; a plain face is not."""
    def strip(rows):
        o = np.array([[c == 'o'] * 10 for c in rows])
        wh = np.array([[c == 'w'] * 10 for c in rows])
        d = np.array([[c == 'd'] * 10 for c in rows])
        return o, wh, d
    # cone: tip, band, then the blob (rows 10-19)
    o, wh, d = strip('...oooowww' + 'o' * 10 + '.....')
    assert banded_rows(o, wh, d, 10, 20, 2, 2, 10)
    # drum bridged into one blob (rows 3-17) by the closing: bands inside
    o, wh, d = strip('...' + 'ooowwwooowwwooo' + '...')
    assert banded_rows(o, wh, d, 3, 18, 2, 2, 15)
    # two-colour sign: orange top (the blob, rows 3-7), white part, black border, orange dirt
    o, wh, d = strip('...' + 'ooooo' + 'wwwwwwww' + 'dd' + 'ooo')
    assert not banded_rows(o, wh, d, 3, 8, 1, 2, 10)
    # a plain face with a pale sky above and road below
    o, wh, d = strip('wwwww' + 'o' * 10 + '.....')
    assert not banded_rows(o, wh, d, 5, 15, 1, 2, 10)


@pytest.mark.parametrize('h', [50, 80])
def test_cone_and_drum_rejected_diamond_beside_them_kept(detector, h):
    """A cone's lower orange part under its white band and a drum's stripes are rejected by
    the band test; a diamond beside them is kept.  (The legend test is off here: the plain
    renders carry no dark pixels; real cones and drums pass it by shading and dirt.)"""
    img = _background()
    cone = _cone(img, 120, 60 + h, h)
    drum = _drum(img, 250, 40, int(0.6 * h), h)
    sign = _diamond(img, 470, 120, 40)
    on = detector.with_config(min_dark_inside=0.0, rect_needs_edges=False)
    off = on.with_config(band_test=False)

    d_on, d_off = on.detect(img), off.detect(img)
    assert _near(d_off, cone) and _near(d_off, drum)          # without the test: found
    assert not _near(d_on, cone) and not _near(d_on, drum)    # with it: rejected
    assert _near(d_on, sign) and _near(d_off, sign)


def test_row_taper_and_white_cap():
    """A diamond is symmetric about its middle row, a cone's body widens downward; a white
    band right over a blob is a cap, one further away is not."""
    img = np.zeros((120, 120), np.uint8)
    cv2.fillConvexPoly(img, np.array([[60, 10], [110, 60], [60, 110], [10, 60]]), 1)
    assert 0.9 < row_taper(img) < 1.1
    cone = np.zeros((120, 120), np.uint8)
    cv2.fillConvexPoly(cone, np.array([[45, 20], [75, 20], [95, 110], [25, 110]]), 1)
    assert row_taper(cone) < 0.8
    white = np.zeros((30, 10), bool)
    white[10:16] = True
    assert white_cap(white, 17, 3, 2)
    assert not white_cap(white, 25, 3, 2)


def test_cone_with_white_top_rejected(detector):
    """A cone whose top above its white band is lost (white, or too thin to see): the band
    caps a blob that widens downward and is rejected; a diamond beside it is kept."""
    img = _background()
    on = detector.with_config(min_dark_inside=0.0)
    h = 70
    pts = np.array([[120 - 12, 60], [120 + 12, 60], [120 + 22, 60 + h], [120 - 22, 60 + h]],
                   np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    img[60:60 + int(0.3 * h), 90:150][img[60:60 + int(0.3 * h), 90:150, 0] < 100] = WHITE
    body = (98, 60 + int(0.3 * h), 45, h - int(0.3 * h))
    sign = _diamond(img, 400, 140, 40)

    assert _near(on.with_config(cone_taper=0.0).detect(img), body)
    d_on = on.detect(img)
    assert not _near(d_on, body)
    assert _near(d_on, sign)


@pytest.mark.parametrize('r', [20, 35])
def test_flags_over_a_pale_sky_are_not_a_band(detector, r):
    """A portable stand's orange flags above a diamond, the overcast sky between them and
    its top corner: the white between them runs on past the diamond's sides, it is the
    background, not a cone's or drum's band; the diamond is kept."""
    img = _background()
    img[:240] = (236, 236, 234)                             # pale overcast sky
    cx, cy = 400, 150
    gt = _diamond(img, cx, cy, r)
    q = max(3, r // 3)
    top = cy - r - r // 2                                   # flags well above the corner
    for dx in (-r // 3, r // 3):
        cv2.fillConvexPoly(img, np.array([[cx + dx, top - 2 * q], [cx + dx + q, top - q],
                                          [cx + dx, top], [cx + dx - q, top - q]], np.int32),
                           ORANGE)
    assert _one(detector.detect(img), gt, 0.5).kind == 'warning'


def _dirt(img, x0, y0, x1, y1, seed=5):
    """A dirt pile: warm mid-saturation soil (0.75 in the step table) speckled with clods of
    saturated orange-brown (0.98: the sign's own level), a dense patch of them in the middle
    with a few dark stones."""
    rng = np.random.default_rng(seed)
    soil = cv2.cvtColor(np.uint8([[[9, 120, 165]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
    clod = cv2.cvtColor(np.uint8([[[12, 200, 210]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
    img[y0:y1, x0:x1] = soil
    speck = rng.random((y1 - y0, x1 - x0)) < 0.15
    img[y0:y1, x0:x1][speck] = clod
    cx, cy = (x0 + x1) // 2, (y0 + y1) // 2
    img[cy - 25:cy + 25, cx - 25:cx + 25] = clod
    stones = rng.random((50, 50)) < 0.05
    img[cy - 25:cy + 25, cx - 25:cx + 25][stones] = (30, 30, 30)
    return (cx - 25, cy - 25, 50, 50)


def test_patch_of_a_sign_coloured_surface_rejected_sign_kept():
    """A patch of sign-coloured clods in a dirt pile: its surroundings are more sign-coloured
    than not (mean likelihood above 0.5) and hold the face's own colour, so it is a part of
    a surface, not an object; a diamond on the road side is kept (its surroundings are
    not sign-coloured), as is a diamond in front of a brick wall (warm, but not at the
    face's level: test_sign_in_front_of_a_brick_wall_is_separated)."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    det = ColorDetector(_step_model(prior), DetectorConfig(colors=('orange',)))
    img = _background(shape=(406, 722))
    patch = _dirt(img, 60, 60, 300, 300)
    sign = _diamond(img, 520, 130, 36)

    assert _near(det.with_config(max_surround_like=1.0, rect_needs_edges=False).detect(img),
                 patch, 0.3)
    dets = det.detect(img)
    assert not _near(dets, patch, 0.3)
    assert _near(dets, sign, 0.3)


def test_orange_patch_without_border_edges_is_dropped_sign_with_them_kept(detector):
    """A rectangular orange blob that is neither a two-colour sign nor shows a face-to-
    border step on its sides (``rect_needs_edges``) is a patch of something orange (dirt,
    a cone, a vest, a brick wall), not a
    sign: a dirt patch that the surround test lets through (found when the edge test is
    off) is dropped; an orange END ROAD WORK rectangle with its black border line is kept."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    det = ColorDetector(_step_model(prior), DetectorConfig(colors=('orange',),
                                                                 max_surround_like=1.0))
    img = _background(shape=(406, 722))
    patch = _dirt(img, 60, 60, 300, 300)
    assert _near(det.with_config(rect_needs_edges=False).detect(img), patch, 0.3)
    assert not _near(det.detect(img), patch, 0.3)
    img, gt = _render_art_sign(_background(), 380.3, 180.6, 44, key='end_road_work')
    d = _one(detector.detect(img), gt, 0.7)
    assert d.kind == 'regulatory'


def test_clipped_growth_only_through_clipped_pixels():
    """:func:`_clipped_growth`: weak pixels join the core only where the red is clipped
    and connected to it; a clipped part far larger than the core (a surface) does not."""
    bgr = np.zeros((40, 60, 3), np.uint8)
    bgr[..., 2], bgr[..., 1] = 200, 120
    strong = np.zeros((40, 60), np.uint8)
    strong[10:20, 20:30] = 1
    weak = np.zeros_like(strong)
    weak[10:20, 14:36] = 1
    bgr[10:20, 14:20, 2] = 255                      # clipped on the left of the core only
    got = _clipped_growth(bgr, weak, strong, 0.5)
    assert got[10:20, 14:20].all() and not got[10:20, 30:36].any()
    bgr[10:20, 30:36, 2] = 255
    bgr[10:20, 30:36, 1] = 255                      # red and green clipped: white, not orange
    assert not _clipped_growth(bgr, weak, strong, 0.5)[10:20, 30:36].any()
    weak[5:35, 0:60] = 1
    bgr[5:35, 0:60, 2], bgr[5:35, 0:60, 1] = 255, 120   # a clipped surface around the core
    assert not _clipped_growth(bgr, weak, strong, 0.5).any()
