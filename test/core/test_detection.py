"""core.detect, the detector as a whole: drawn signs found and kept, degenerate frames,
LiDAR ROIs, the location prior and the mounting geometry, other cameras, the
configuration's checks, the HSV and RGB-LP baselines, and the small functions it is built
on (NMS, box metrics, histogram mode, table lookup).  The topics apart:
``test_detection_diamond.py`` (measuring a warning diamond), ``test_detection_diamond_boxes.py``
(the detector's warning boxes), ``test_detection_two_colour.py`` (two-colour signs),
``test_detection_clutter.py`` (cones, drums, flags, warm surfaces),
``test_detection_budget.py`` (per-frame budgets); the shipped detector on labelled camera
frames, rendered signs, cones and drums: ``test_detection_frames.py``."""
import cv2
import numpy as np
import pytest
from detection_helpers import (
    BLACK,
    ORANGE,
    _background,
    _catalogue_diamond,
    _default_detector,
    _diamond,
    _flagged_diamond,
    _one,
    _regulatory,
)

from workzone_ros.core import color_model as cm
from workzone_ros.core.detect import (
    Candidate,
    ColorDetector,
    DetectorConfig,
    box_metrics,
    fit_rgb_lp,
    nms,
    rgb_histograms,
)
from workzone_ros.core.detect.common import _lookup, _mode
from workzone_ros.interfaces import Box, Roi


@pytest.mark.parametrize('r', [10, 25, 70])
def test_diamond_at_known_box(detector, r):
    img = _background()
    gt = _diamond(img, 420, 150, r)
    dets = detector.detect(img)
    d = _one(dets, gt, 0.85)
    assert d.color == 'orange' and d.kind == 'warning' and d.sources == ['color']
    assert 0.5 <= d.confidence <= 1.0
    _, precision, recall = box_metrics(d.box, Box(*map(float, gt)))
    # the orange hull's box grows by border_frac (4 %) per side for the border / outer margin
    # that renders and cameras blend away; this drawn sign is sharp to its edge
    assert recall > 0.97 and precision > 0.8
    assert len(dets) == 1
    exact = _one(detector.with_config(border_frac=0.0).detect(img), gt, 0.85)
    _, precision, recall = box_metrics(exact.box, Box(*map(float, gt)))
    assert precision > 0.9 and recall > 0.9


def test_every_sign_is_kept(detector):
    img = _background()
    gts = [_diamond(img, 150, 120, 20), _diamond(img, 420, 150, 30), _diamond(img, 560, 90, 15)]
    dets = detector.detect(img)
    assert len(dets) == 3
    for gt in gts:
        _one(dets, gt)


@pytest.mark.parametrize('value', [0, 255])
def test_black_and_overexposed_frames(detector, value):
    """An all-black frame (a covered lens) and an all-white one (the sun in the lens) give
    no detection, by either method, with a LiDAR ROI, and from the shipped detector."""
    img = np.full((480, 640, 3), value, np.uint8)
    for method in ('learned', 'hsv'):
        assert detector.with_config(method=method).detect(img) == []
    assert detector.detect(img, [Roi(1, Box(100, 100, 40, 40), (120, 120), 30, 0.6,
                                     (1, 0, 30))]) == []
    assert _default_detector().detect(img) == []


def test_tiny_and_odd_frames(detector):
    assert detector.detect(np.zeros((1, 1, 3), np.uint8)) == []
    assert detector.detect(np.zeros((31, 17, 3), np.uint8)) == []
    with pytest.raises(ValueError):
        detector.detect(np.zeros((10, 10), np.uint8))


def test_red_and_yellow_general_signs(detector):
    img = _background()
    cv2.circle(img, (200, 120), 25, (40, 35, 195), -1)        # do-not-enter-like red disc
    _diamond(img, 450, 140, 30, color=(10, 205, 250))          # yellow warning diamond
    dets = detector.detect(img)
    colors = sorted(d.color for d in dets)
    assert colors == ['red', 'yellow'] and all(d.kind == 'general' for d in dets)


def _roi(box, cid=7):
    return Roi(cid, Box(*map(float, box)), (box[0] + box[2] / 2, box[1] + box[3] / 2), 40.0,
               0.6, (0.0, 0.0, 40.0))


def test_lidar_roi_raises_the_prior(model):
    """A sign where the prior says signs never are is found once a LiDAR ROI points at it."""
    prior = cm.fit_prior([(380, 60, 80, 80)] * 5, (640, 480), floor=0.2)
    # _diamond's border is not the catalogue's (a 4 px orange margin outside a thin line),
    # which the brightness refinement assumes: boxes here come from the orange mask
    det = ColorDetector(model.with_prior(prior), DetectorConfig(threshold=0.5,
                                                                      diamond_refine=False))
    img = _background()
    gt = _diamond(img, 120, 330, 25)
    assert not [d for d in det.detect(img) if d.box.iou(Box(*map(float, gt))) > 0.3]
    d = _one(det.detect(img, [_roi(gt)]), gt, 0.85)
    assert d.sources == ['color', 'lidar'] and d.roi_id == 7


def test_lidar_support_and_unsupported_blobs(detector):
    img = _background()
    a = _diamond(img, 150, 120, 20)
    b = _diamond(img, 420, 150, 30)
    plain = {d.box.x: d.confidence for d in detector.detect(img)}
    dets = detector.detect(img, [_roi(b, 3), _roi((40, 300, 30, 30), 4)])
    da, db = _one(dets, a), _one(dets, b)
    assert da.sources == ['color'] and da.confidence == plain[da.box.x]
    assert db.sources == ['color', 'lidar'] and db.roi_id == 3
    assert db.confidence > plain[db.box.x]
    assert len(dets) == 2       # an ROI on plain asphalt is no sign: no lidar-only report
    assert ['color', 'lidar'] in [d.sources for d in detector.with_config(
        lidar_only=False).detect(img, [_roi(b, 3)])]


def test_lidar_roi_never_changes_colour_detections(detector):
    """The colour-only pass is run unchanged; an ROI it explains adds no second pass."""
    img = _background()
    a = _diamond(img, 300, 150, 22)
    b = _diamond(img, 360, 150, 22)
    plain = sorted((d.box.x, d.box.y, d.box.w, d.box.h) for d in detector.detect(img))
    roi = _roi((a[0] - 10, a[1] - 10, b[0] + b[2] - a[0] + 20, a[3] + 20))
    dets = detector.detect(img, [roi])
    assert sorted((d.box.x, d.box.y, d.box.w, d.box.h) for d in dets) == plain


def test_lidar_only_detection_needs_sign_colour(model):
    """An ROI whose sign the colour pass cannot report (here: where the prior says signs never
    are, with the in-ROI threshold out of reach) gives a lidar-only detection with its own
    box when the ROI holds a sign-coloured region; an ROI with no sign colour gives nothing."""
    prior = cm.fit_prior([(380, 60, 80, 80)] * 5, (640, 480), floor=0.2)
    det = ColorDetector(model.with_prior(prior), DetectorConfig(roi_threshold=0.99,
                                                                        roi_prior=0.2))
    img = _background()
    gt = _catalogue_diamond(img, 120.3, 330.6, 25.2)
    roi = _roi((gt[0] - 25, gt[1] - 25, gt[2] + 50, gt[3] + 50), 9)
    assert det.detect(img) == []
    d = _one(det.detect(img, [roi]), gt, 0.75)
    assert d.sources == ['lidar'] and d.roi_id == 9 and d.color == 'orange'
    assert det.with_config(lidar_only=False).detect(img, [roi]) == []
    assert det.detect(_background(), [roi]) == []


def test_lidar_supported_blob_needs_less_evidence(detector):
    """A plain orange diamond (no legend: fails the legend test on colour alone) is accepted
    inside a LiDAR ROI."""
    img = _background()
    gt = (390, 120, 61, 61)
    pts = np.array([[420, 120], [450, 150], [420, 180], [390, 150]], np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    assert detector.detect(img) == []
    d = _one(detector.detect(img, [_roi((365, 95, 110, 110), 2)]), gt, 0.75)
    assert d.sources == ['color', 'lidar']


def test_lidar_roi_relaxes_the_height_filter(model):
    """A low sign (on a portable stand) fails the learned mounting-height test on colour
    alone; a LiDAR ROI on it lifts that test."""
    geo = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, {},
                        {'geometry': np.array([0.5, 0.26])})
    det = ColorDetector(geo, DetectorConfig(use_prior=False, use_geometry=True))
    img = _background()
    low = _diamond(img, 300, 400, 30)
    assert det.detect(img) == []
    d = _one(det.detect(img, [_roi((low[0] - 20, low[1] - 20, low[2] + 40, low[3] + 40))]),
             low)
    assert 'lidar' in d.sources


def test_prior_suppresses_unlikely_locations(model):
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2)
    det = ColorDetector(model.with_prior(prior), DetectorConfig(threshold=0.5))
    img = _background()
    sign = _diamond(img, 420, 140, 25)
    cone = _diamond(img, 100, 430, 20)           # an orange thing low on the road
    dets = det.detect(img)
    _one(dets, sign)
    assert not [d for d in dets if d.box.iou(Box(*map(float, cone))) > 0.3]


def test_nms_keeps_separate_boxes():
    c = [Candidate(0, 0, 10, 10, 'orange', 0.9), Candidate(1, 1, 8, 8, 'orange', 0.9),
         Candidate(50, 50, 10, 10, 'orange', 0.5)]
    kept = nms(c, 0.3, 0.7)
    assert [(k.x, k.y) for k in kept] == [(0, 0), (50, 50)]


def test_box_metrics_definitions():
    iou, p, r = box_metrics(Box(0, 0, 10, 10), Box(0, 0, 10, 20))
    assert iou == pytest.approx(0.5) and p == pytest.approx(1.0) and r == pytest.approx(0.5)


def test_hsv_baseline_finds_square_signs_only(detector):
    img = _background()
    gt = _diamond(img, 420, 150, 30)
    _regulatory(img, 150, 80, 72, 90)
    hsv = detector.with_config(method='hsv', scale=1)
    dets = hsv.detect(img)
    _one(dets, gt, 0.7)
    assert all(d.box.w / d.box.h < 1.7 for d in dets)          # its aspect filter


def test_rgb_lp_thresholds_and_mser(model):
    pos = np.zeros(32 ** 3)
    neg = np.zeros(32 ** 3)
    rng = np.random.default_rng(3)
    for k in range(4):
        img = _background(k)
        mask = np.zeros(img.shape[:2], np.uint8)
        _diamond(img, int(rng.integers(100, 540)), int(rng.integers(60, 200)), 30,
                 tuple(c * rng.uniform(0.6, 1.0) for c in ORANGE), mask)
        p, n = rgb_histograms(img, mask)
        pos += p
        neg += n
    lp = fit_rgb_lp(pos, neg, w=1.0, max_thresholds=4, time_limit=20)
    assert 1 <= len(lp.thresholds) <= 4
    assert lp.metadata['fn_rate'] < 0.2 and lp.metadata['fp_rate'] < 0.2
    det = ColorDetector(model, DetectorConfig(method='rgb_lp', use_prior=False, scale=1),
                           rgb_lp=lp)
    img = _background(9)
    gt = _diamond(img, 420, 150, 30)
    dets = det.detect(img)
    assert max(d.box.iou(Box(*map(float, gt))) for d in dets) > 0.7
    with pytest.raises(cm.ModelError):
        ColorDetector(model, DetectorConfig(method='rgb_lp'))


def test_config_validation():
    with pytest.raises(ValueError):
        DetectorConfig(method='cnn')
    with pytest.raises(ValueError):
        DetectorConfig(colors=('blue',))
    with pytest.raises(ValueError):
        DetectorConfig(threshold=1.5)
    for bad, name in (({'diamond_max_change': 0.0}, 'diamond_max_change'),
                      ({'diamond_hold': 1.5}, 'diamond_hold'),
                      ({'ext_ratio_tol': -0.1}, 'ext_ratio_tol'),
                      ({'ext_band_long': 0.0}, 'ext_band_long'),
                      ({'hold_sat': -0.1}, 'hold_sat'),
                      ({'diamond_blur_sigma': 0.0}, 'diamond_blur_sigma'),
                      ({'blur_fit_ratio': 0.1}, 'blur_fit_ratio'),
                      ({'blur_fit_max_sigma': 0.2}, 'blur_fit_max_sigma'),
                      ({'blur_fit_bias': 5.0}, 'blur_fit_bias'),
                      ({'rim_chroma': 1.5}, 'rim_chroma'),
                      ({'diamond_tall_max': 0.9}, 'diamond_tall_max'),
                      ({'diamond_wide_max': 2.5}, 'diamond_wide_max'),
                      ({'grow_level': 1.5}, 'grow_level'), ({'grow_reach': -1.0}, 'grow_reach'),
                      ({'shift_min_px': -1.0}, 'shift_min_px'),
                      ({'grow_min_px': -1.0}, 'grow_min_px'),
                      ({'white_own_rel': 1.0}, 'white_own_rel'),
                      ({'diamond_bright_bias': (3.0, 0.47, 0.95)}, 'diamond_bright_bias'),
                      ({'diamond_bright_bias': (0.3, 0.95, 0.47)}, 'diamond_bright_bias'),
                      ({'diamond_bright_bias': (0.3,)}, 'diamond_bright_bias'),
                      ({'rect_dim_bias': (-0.1, 80.0, 170.0)}, 'rect_dim_bias'),
                      ({'rect_dim_bias': (0.3, 170.0, 80.0)}, 'rect_dim_bias'),
                      ({'ext_overlong': -0.1}, 'ext_overlong'),
                      ({'ext_overlong_border': 1.5}, 'ext_overlong_border'),
                      ({'rect_inward': (1.5, -3.0)}, 'rect_inward'),
                      ({'clip_grow': -0.5}, 'clip_grow'),
                      ({'rect_clip_bias': -0.3}, 'rect_clip_bias')):
        with pytest.raises(ValueError, match=name):
            DetectorConfig(**bad)


def test_plain_orange_panel_is_not_a_sign(detector):
    """Sign faces carry a legend and border; a plain orange panel (a truck side) does not."""
    img = _background()
    cv2.rectangle(img, (380, 100), (459, 159), ORANGE, -1)
    assert detector.detect(img) == []
    _diamond(img, 200, 120, 30)
    assert len(detector.detect(img)) == 1


def test_geometry_rejects_orange_things_on_the_road(model):
    """With the trained mounting geometry, a blob whose bottom is far below the mid row
    (a drum, a cone) is not a sign; the same blob up at sign height is."""
    geo = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, {},
                        {'geometry': np.array([0.5, 0.26])})
    det = ColorDetector(geo, DetectorConfig(use_prior=False, use_geometry=True))
    img = _background()
    low = _diamond(img, 300, 400, 30)
    high = _diamond(img, 500, 150, 30)
    dets = det.detect(img)
    _one(dets, high)
    assert not [d for d in dets if d.box.iou(Box(*map(float, low))) > 0.3]
    assert len(det.with_config(use_geometry=False).detect(img)) == 2


def test_soft_mounting_limit_keeps_low_sign_faces(model):
    """Between the usual mounting (soft limit) and the lowest training sign (hard limit,
    portable stands) a clear diamond face passes, a vehicle-like orange block does not."""
    geo = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, {},
                        {'geometry': np.array([0.5, 1.5, 0.26])})
    det = ColorDetector(geo, DetectorConfig(use_prior=False, use_geometry=True))
    img = _background()
    low = _diamond(img, 200, 290, 30)
    cv2.rectangle(img, (420, 250), (500, 320), ORANGE, -1)          # a truck's rear
    cv2.rectangle(img, (432, 258), (488, 280), BLACK, -1)            # its window
    dets = det.detect(img)
    _one(dets, low)
    assert len(dets) == 1
    assert len(det.with_config(use_geometry=False).detect(img)) == 2


def test_saturation_norm_finds_hazy_signs_and_ignores_warm_grey():
    """A table that wants saturated orange (S >= 150) finds a washed-out sign on a hazy
    frame once the frame's saturation is normalised (without it, nothing is found), and
    still ignores warm grey ground on a colourful frame (asphalt and dry lawns at S
    50..120)."""
    lut = np.zeros((cm.H_BINS, cm.S_BINS), np.float32)
    lut[5:22, 150:] = 0.97
    meta = {'sat_norm': cm.SatNorm(0.9, 120.0, 4.0).to_dict()}
    normed = cm.default_model(lut, 50, None, meta)
    plain = cm.default_model(lut, 50)
    hazy = np.full((480, 640, 3), (168, 165, 160), np.uint8)
    hazy[240:] = (120, 122, 124)
    hazy = cv2.add(hazy, np.random.default_rng(3).integers(0, 6, hazy.shape, dtype=np.uint8))
    pale = (120, 150, 200)                                       # orange, S ~ 102
    gt = _diamond(hazy, 420, 150, 40, pale)
    cfg = DetectorConfig(colors=('orange',), use_prior=False)
    _one(ColorDetector(normed, cfg).detect(hazy), gt, iou=0.6)
    assert ColorDetector(plain, cfg).detect(hazy) == []
    vivid = _background(4)                                        # blue sky, grass, asphalt
    vivid[300:420, 100:500] = (95, 130, 165)                     # dry lawn, S ~ 108
    assert ColorDetector(normed, cfg).detect(vivid) == []


def test_other_camera_does_not_get_the_fixed_camera_prior(model):
    """A 722x406 frame from an unknown camera: the prior's heat map (rows and columns of our
    640x480 camera) is not stretched over it; a sign where that map is at its floor is
    found.  The model's own camera still gets the heat map."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    det = ColorDetector(model.with_prior(prior), DetectorConfig(colors=('orange',)))
    img = _background(shape=(406, 722))
    low = _diamond(img, 150, 300, 30)             # on a sidewalk, low left: heat at its floor
    _one(det.detect(img), low)
    assert det.same_camera(640, 480) and not det.same_camera(722, 406)
    assert det.with_config(camera_match=False).detect(img) == []     # the stretched map
    own = _background()
    _diamond(own, 150, 360, 30)
    assert det.detect(own) == []                  # our camera: the heat map applies


def test_other_camera_has_no_fixed_row_mounting_test(model):
    """The fixed mounting-height row is our camera's horizon: a low sign face in another
    camera's frame is not judged by it (the same face in our camera's frame is); a 640x480
    stream whose intrinsics say it is another lens is another camera too."""
    meta = {'camera': {'width': 640, 'height': 480, 'fx': 554.26, 'fy': 554.26, 'cx': 320,
                       'cy': 240}}
    geo = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, meta,
                        {'geometry': np.array([0.5, 0.26])})
    det = ColorDetector(geo, DetectorConfig(colors=('orange',), use_prior=False))
    img = _background(shape=(406, 722))
    low = _diamond(img, 300, 340, 30)
    _one(det.detect(img), low)
    assert det.with_config(camera_match=False).detect(img) == []
    own = _background()
    low = _diamond(own, 300, 400, 30)
    assert det.detect(own) == []
    det.set_camera((554.26, 554.26, 320.0, 240.0))
    assert det.detect(own) == []
    det.set_camera((380.0, 380.0, 320.0, 240.0))                   # a 80 deg lens
    _one(det.detect(own), low)
    _one(det.with_config(threshold=0.5).detect(own), low)          # with_config keeps it
    det.set_camera(None)
    assert det.detect(own) == []
    with pytest.raises(ValueError, match='fx, fy, cx, cy'):
        det.set_camera((1.0, 2.0))


def test_foreign_prior_config_and_default(model):
    """foreign_prior 0 takes the model prior's ROI mean relative to the orange table's peak;
    an explicit value is used as is; out-of-range values are refused."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2, saturate=0.1)
    det = ColorDetector(model.with_prior(prior), DetectorConfig(colors=('orange',)))
    peak = float(model.lut('orange').max())
    assert det.foreign_prior() == pytest.approx(min(1.0, prior.expected() / peak))
    assert det.with_config(foreign_prior=0.7).foreign_prior() == pytest.approx(0.7)
    for bad in (-0.1, 1.5):
        with pytest.raises(ValueError, match='foreign_prior'):
            DetectorConfig(foreign_prior=bad)


def test_soft_mounting_limit_keeps_symbol_and_flag_diamonds(model):
    """Below the usual mounting a diamond whose black symbol cuts its orange face (a lane
    shift arrow) passes on its outline, and so does one whose portable stand's flags sit
    above its top corner; an orange triangle (a cone's shape, solid) and the truck's rear
    still do not."""
    geo = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, {},
                        {'geometry': np.array([0.5, 1.5, 0.26])})
    det = ColorDetector(geo, DetectorConfig(use_prior=False, use_geometry=True,
                                                  band_test=False))
    img = _background()
    arrow = _diamond(img, 150, 290, 30)
    cv2.line(img, (143, 300), (143, 288), BLACK, 6)                  # a bent arrow
    cv2.line(img, (143, 288), (156, 279), BLACK, 6)
    flagged = _flagged_diamond(img, 290, 300, 26)
    tri = np.array([[470, 262], [500, 322], [440, 322]], np.int32)
    cv2.fillConvexPoly(img, tri, ORANGE)
    dets = det.detect(img)
    _one(dets, arrow, 0.6)
    _one(dets, flagged, 0.6)
    assert not [d for d in dets if d.box.x > 420]


@pytest.mark.parametrize('height', [101, 333])
@pytest.mark.parametrize('method', ['learned', 'hsv'])
def test_sign_cut_by_the_bottom_of_an_odd_sized_frame(model, height, method):
    """A frame of odd height with an orange blob cut by its bottom edge: the half-resolution
    blob scaled back up reaches a row past the frame: no error, finite boxes."""
    img = np.full((height, 240, 3), (90, 90, 90), np.uint8)
    pts = np.array([[120, height - 30], [150, height - 1], [120, height + 29],
                    [90, height - 1]], np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    det = ColorDetector(model, DetectorConfig(method=method, use_prior=False))
    dets = det.detect(img)
    assert all(np.isfinite([d.box.x, d.box.y, d.box.w, d.box.h]).all() for d in dets)


def test_histogram_mode_equals_numpys_histogram():
    """The detector's _mode is the centre of np.histogram's fullest bin exactly (ties, values
    on bin edges and at the range's ends)."""
    rng = np.random.default_rng(5)
    edges = np.histogram_bin_edges(np.empty(0, np.float32), bins=20, range=(0.0, 1.0))
    for dtype in (np.float32, np.float64):
        for n in list(range(1, 12)) + [63, 64, 65, 200, 1001]:
            v = (rng.integers(0, 21, n) / 20.0).astype(dtype)       # on the bin edges
            for w in (v, rng.random(n).astype(dtype), edges[rng.integers(0, 21, n)]):
                hist, e = np.histogram(w, bins=20, range=(0.0, 1.0))
                i = int(np.argmax(hist))
                assert _mode(w) == float(0.5 * (e[i] + e[i + 1]))


def test_table_lookup_equals_two_index_lookup():
    rng = np.random.default_rng(7)
    table = rng.random((180, 256)).astype(np.float32)
    hue = rng.integers(0, 180, (13, 17)).astype(np.uint8)
    sat = rng.integers(0, 256, (13, 17)).astype(np.uint8)
    assert np.array_equal(_lookup(table, hue, sat), table[hue, sat])
    h, s = hue[:, 3:9], sat[:, 3:9]                  # strided views, as HSV channels are
    assert np.array_equal(_lookup(table, h, s), table[h, s])
