"""Tests of the general sign recogniser (workzone_ros/core/general): templates, colours,
the orange guard, mile numbers and input checks, for both verification modes (the CNN
sign classifier, the default, and the paper's templates).  Signs are our own sign art
pasted on a road-like background (sky, trees, asphalt)."""
from __future__ import annotations

import numpy as np
import pytest

from workzone_ros.core.general import (
    GeneralConfig,
    GeneralSign,
    GeneralSignDetector,
    GeneralSignError,
)
from workzone_ros.sim.signart import over, sign_face

RED = ('stop', 'yield', 'do_not_enter')


@pytest.fixture(scope='module', params=('cnn', 'templates'))
def detector(request) -> GeneralSignDetector:
    """Either verification mode (tests that hold for both)."""
    return GeneralSignDetector(GeneralConfig(verify=request.param))


@pytest.fixture(scope='module')
def paper() -> GeneralSignDetector:
    """The paper's pipeline: blob tests and red templates."""
    return GeneralSignDetector(GeneralConfig(verify='templates'))


@pytest.fixture(scope='module')
def cnn() -> GeneralSignDetector:
    return GeneralSignDetector()


def scene(h: int = 360, w: int = 640, seed: int = 0) -> np.ndarray:
    """Sky, a tree line and asphalt with a little noise (uint8 BGR)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    img[:] = (200, 170, 140)
    img[int(0.35 * h):int(0.5 * h)] = (40, 90, 50)
    img[int(0.5 * h):] = (95, 100, 100)
    img += rng.normal(0, 4, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def paste(img: np.ndarray, key: str, size: int, x: int, y: int, **kw) -> tuple:
    """Composite the sign art of ``key`` at (x, y); returns its box."""
    face = sign_face(key, size, **kw)
    h, w = face.shape[:2]
    img[y:y + h, x:x + w] = np.clip(over(face, img[y:y + h, x:x + w].astype(np.float32)),
                                    0, 255).astype(np.uint8)
    return (x, y, w, h)


def iou(a, b) -> float:
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy / float(a[2] * a[3] + b[2] * b[3] - ix * iy)


@pytest.mark.parametrize('key', RED)
@pytest.mark.parametrize('size', (28, 56, 120))
def test_red_template_matches_its_own_sign(paper, key, size):
    img = scene()
    box = paste(img, key, size, 300, 100)
    found = paper.detect(img)
    assert len(found) == 1, found
    g = found[0]
    assert g.class_key == key and g.template == key and g.colour == 'red'
    assert iou(g.box, box) > 0.6
    assert g.template_ncc >= 0.7 and 0 < g.template_score <= 1
    assert g.shape == {'stop': 'octagon', 'yield': 'triangle', 'do_not_enter': 'square'}[key]


@pytest.mark.parametrize('key', RED)
@pytest.mark.parametrize('size', (28, 56, 120))
def test_red_sign_is_recognised_with_the_cnn(cnn, key, size):
    img = scene()
    box = paste(img, key, size, 300, 100)
    found = cnn.detect(img)
    assert [(g.class_key, g.colour) for g in found] == [(key, 'red')], found
    assert iou(found[0].box, box) > 0.6 and 0.0 < found[0].score <= 1.0


def grass(h: int = 360, w: int = 640, seed: int = 1) -> np.ndarray:
    """Sky over dry, yellowish grass with texture (the background small yellow diamonds
    merge with in the colour mask)."""
    import cv2
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    img[:] = (205, 175, 140)
    g0 = int(0.3 * h)
    img[g0:] = (60, 150, 175)                    # dry grass, hue ~20, saturation ~100
    img[g0:] += cv2.GaussianBlur(rng.normal(0, 25, (h - g0, w, 1)).astype(np.float32),
                                 (0, 0), 1.5)[..., None]
    img += rng.normal(0, 4, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize('key', ('warning_diamond', 'stop', 'speed_limit'))
def test_small_sign_on_grass_is_found_with_the_cnn(cnn, key):
    """A 24 px sign on dry grass: recall-first candidates, the CNN decides."""
    img = grass()
    box = paste(img, key, 24, 300, 150)
    found = cnn.detect(img)
    assert [g.class_key for g in found] == [key], found
    assert iou(found[0].box, box) > 0.5


@pytest.mark.parametrize('red', (False, True))
@pytest.mark.parametrize('size', (24, 48))
def test_drum_and_cone_are_not_general_signs(cnn, size, red):
    """Orange and white channelizers (the simulator's drum texture, a cone) on grass and
    on asphalt give no general sign; nor does a drum whose sheeting reads red (as the
    houston clip's does after the white balance)."""
    import cv2

    from workzone_ros.sim.signart import drum_texture
    for img in (grass(), scene()):
        drum = cv2.resize(np.ascontiguousarray(drum_texture()), (size, int(1.5 * size)))
        if red:
            drum[(drum != 255).any(axis=2)] = (40, 40, 225)
        img[150:150 + drum.shape[0], 200:200 + size] = drum
        cone = np.array([[420, 150 + 2 * size], [420 + size, 150 + 2 * size],
                         [420 + size // 2, 150]], np.int32)
        cv2.fillPoly(img, [cone], (0, 100, 250))
        band = 150 + size
        cv2.line(img, (420 + size // 4, band), (420 + 3 * size // 4, band), (245, 245, 245),
                 max(2, size // 8))
        assert cnn.detect(img) == []


@pytest.mark.parametrize('key', RED)
def test_red_template_rejects_the_others(paper, key):
    """The sign's own template correlates clearly better than the other two."""
    from workzone_ros.core.general import colour, templates
    cfg = paper.config
    img = scene()
    paste(img, key, 64, 300, 100)
    work = colour.working_image(img, cfg)
    blob = max(colour.blobs(colour.clean(colour.red_mask(work.hsv, cfg, 45), cfg), 8),
               key=lambda b: b.area)
    crop = templates.prepare_crop(img, blob.box, blob.mask, work.gains, cfg)
    m = templates.match_templates(crop, cfg)
    own = m.scores[key][1]
    assert m.key == key
    assert all(own - v[1] > 0.15 for k, v in m.scores.items() if k != key), m.scores


def test_paper_rule_is_available():
    """select_by='score' picks by Cahail et al.'s share of good positions."""
    det = GeneralSignDetector(GeneralConfig(select_by='score', verify='templates'))
    img = scene()
    paste(img, 'yield', 64, 300, 100)
    assert [g.class_key for g in det.detect(img)] == ['yield']


def test_yellow_diamond_is_a_warning_sign(detector):
    img = scene()
    box = paste(img, 'warning_diamond', 64, 200, 80)
    found = detector.detect(img)
    assert [(g.class_key, g.colour, g.shape) for g in found] == \
        [('warning_diamond', 'yellow', 'diamond')]
    assert iou(found[0].box, box) > 0.5


@pytest.mark.parametrize('key', ('road_work_ahead', 'lane_shift_left', 'other_workzone'))
@pytest.mark.parametrize('hue_shift', (-4, 0, 4))
def test_orange_workzone_diamond_is_not_a_general_sign(detector, key, hue_shift):
    import cv2
    hsv = np.uint8([[[13 + hue_shift, 240, 240]]])
    orange = tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])
    img = scene()
    paste(img, key, 64, 200, 80, orange=orange)
    paste(img, key, 30, 420, 120, orange=orange)
    assert detector.detect(img) == []


def test_red_symbol_on_a_warning_sign_stays_a_warning_sign(detector):
    """Cahail et al., Fig. 3.8: a small red octagon on a yellow diamond is its symbol."""
    img = scene()
    paste(img, 'warning_diamond', 96, 200, 60)
    paste(img, 'stop', 24, 236, 96)
    assert [g.class_key for g in detector.detect(img)] == ['warning_diamond']


def test_white_and_green_panels(detector):
    img = scene()
    paste(img, 'speed_limit', 80, 100, 90)
    paste(img, 'guide', 140, 300, 60)
    found = sorted(g.class_key for g in detector.detect(img))
    assert found == ['guide', 'speed_limit']


def test_mile_marker_number_is_read(detector):
    img = scene()
    paste(img, 'mile_marker', 150, 300, 60, speed_value=247)
    found = detector.detect(img)
    assert len(found) == 1 and found[0].class_key == 'mile_marker', found
    assert found[0].mile == 247 and found[0].mile_confidence >= 0.8


def test_small_mile_marker_number_is_none(detector):
    img = scene()
    paste(img, 'mile_marker', 40, 300, 60, speed_value=247)
    found = detector.detect(img)
    assert [g.class_key for g in found] == ['mile_marker']
    assert found[0].mile is None and found[0].mile_confidence is None


def test_rois_restrict_the_search(detector):
    img = scene()
    paste(img, 'stop', 48, 100, 100)
    paste(img, 'yield', 48, 400, 100)
    assert [g.class_key for g in detector.detect(img, rois=[(380, 80, 100, 100)])] == ['yield']
    assert detector.detect(img, rois=[]) == []


def test_hd_frame(detector):
    import cv2
    img = cv2.resize(scene(), (1280, 720))
    paste(img, 'stop', 80, 900, 200)
    assert [g.class_key for g in detector.detect(img)] == ['stop']


@pytest.mark.parametrize('bad', [
    np.zeros((0, 0, 3), np.uint8), np.zeros((10, 10, 3), np.float32),
    np.zeros((10, 10), np.uint8), np.zeros((10, 10, 4), np.uint8), [[1, 2, 3]], None])
def test_bad_image_is_a_clear_value_error(detector, bad):
    with pytest.raises(ValueError, match='image must be') as exc:
        detector.detect(bad)
    assert '\n' not in str(exc.value)


def test_bad_roi_and_config():
    with pytest.raises(ValueError, match='roi'):
        GeneralSignDetector().detect(scene(), rois=[(0, 0, -1, 5)])
    with pytest.raises(GeneralSignError, match='max_aspect'):
        GeneralConfig(max_aspect=0.5)
    with pytest.raises(ValueError, match='select_by'):
        GeneralConfig(select_by='best')
    with pytest.raises(ValueError, match='yellow_hue'):
        GeneralConfig(yellow_hue=(40, 20))
    with pytest.raises(ValueError, match='config'):
        GeneralSignDetector(config={'max_aspect': 2})


def test_result_type(detector):
    img = scene()
    paste(img, 'stop', 48, 100, 100)
    g = detector.detect(img)[0]
    assert isinstance(g, GeneralSign)
    assert all(isinstance(v, int) for v in g.box) and 0.0 <= g.score <= 1.0


def test_local_white_keeps_a_grey_panel_apart_from_grey_rain():
    """In rain the frame's brightest pixels are the panel's, so the frame-wide white
    threshold also takes the grey background; the locally bright mask does not."""
    import cv2

    from workzone_ros.core.general import candidates, colour
    rng = np.random.default_rng(2)
    img = np.clip(np.full((360, 640, 3), 150, np.float32) + rng.normal(0, 5, (360, 640, 3)),
                  0, 255).astype(np.uint8)
    x, y, w, h = paste(img, 'speed_limit', 30, 300, 150)
    img = (img.astype(np.float32) * 0.72).astype(np.uint8)
    cfg = GeneralConfig()
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    background = np.ones(hsv.shape[:2], bool)
    background[y - 25:y + h + 25, x - 25:x + w + 25] = False
    frame_wide = colour.white_mask(hsv, cfg) > 0
    local = candidates._local_white(hsv, cfg) > 0
    assert frame_wide[background].mean() > 0.3
    assert local[background].mean() < 0.01
    assert local[y + 2:y + h - 2, x + 2:x + w - 2].mean() > 0.4


@pytest.mark.parametrize('band, general', (((40, 40, 170), True), ((0, 120, 255), False)))
def test_red_wall_above_a_panel_is_no_work_zone_plaque(cnn, band, general):
    """An orange band on top of a speed limit panel is a WORK ZONE plaque (the sign is the
    classifier's); a red one is a brick wall behind the panel."""
    img = scene()
    x, y, w, h = paste(img, 'speed_limit', 30, 300, 150)
    img[y - 12:y, x:x + w] = band
    found = [g.class_key for g in cnn.detect(img)]
    assert found == (['speed_limit'] if general else []), found


def test_candidate_shortcuts_match_the_plain_computation():
    """The faster candidate stage gives what the plain one gives: the joins equal
    :func:`colour._stacked_pairs` (and it transposed) over all pairs, and a mask's boxes
    from its padded crop equal those from the whole frame, in the same order."""
    from workzone_ros.core.general import candidates, colour
    rng = np.random.default_rng(5)
    for _ in range(40):
        b = np.column_stack([rng.integers(0, 120, (60, 2)), rng.integers(2, 25, (60, 2))])
        stacked, side = candidates._join_pairs(b.astype(np.int32))
        t = b[:, [1, 0, 3, 2]]
        assert stacked == [tuple(p) for p in colour._stacked_pairs(b).tolist()]
        assert side == [tuple(p) for p in colour._stacked_pairs(t).tolist()]
    for k in range(12):
        m = np.zeros((120, 160), np.uint8)
        x, y = int(rng.integers(0, 140)), int(rng.integers(0, 100))
        sub = m[y:y + 20, x:x + 20]
        sub[:] = (rng.random(sub.shape) < 0.6) * 255
        which = ('red', 'yellow', 'white', 'green')[k % 4]
        x0, y0, x1, y1 = candidates._crop(m)
        part = candidates._ops(which, m[y0:y1, x0:x1])
        for (op, full), (_, crop) in zip(candidates._ops(which, m), part):
            assert candidates._components(full) == candidates._components(crop, (x0, y0)), op
            assert np.array_equal(candidates._paste(crop, m.shape, x0, y0), full), op
