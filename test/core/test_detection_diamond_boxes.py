"""core.detect, the detector's warning-diamond boxes on drawn and rendered signs: flags
above a diamond, the simulator's art at sub-pixel places, catalogue-proportioned signs
boxed as their whole-pixel labels, bright and dark backgrounds, blended rims, guardrails
across a face and faded legends."""
import cv2
import numpy as np
import pytest
from detection_helpers import (
    ORANGE,
    _background,
    _catalogue_diamond,
    _default_detector,
    _flagged_diamond,
    _near,
    _one,
    _render_art_sign,
)

from workzone_ros.core.detect import box_metrics
from workzone_ros.core.detect.diamond import diamond_pixel_box
from workzone_ros.interfaces import Box


@pytest.mark.parametrize('r', [14, 20, 35])
def test_flags_above_a_diamond_stay_out_of_its_box(detector, r):
    """A portable stand's two orange flags just above a diamond's top corner: the box is
    the diamond's, its top edge at the top corner."""
    img = _background()
    gt = _flagged_diamond(img, 420, 150, r)
    d = _one(detector.detect(img), gt, 0.5)
    _, precision, recall = box_metrics(d.box, Box(*map(float, gt)))
    assert d.kind == 'warning'
    assert precision > 0.8 and recall > 0.9
    assert d.box.y >= gt[1] - 0.15 * gt[3] - 1      # the top edge at the top corner


@pytest.mark.parametrize('size', [28, 40, 64])
def test_art_diamond_box_within_a_pixel(detector, size):
    """A warning diamond with its black border (the simulator's art) at sub-pixel
    positions: each edge of its box within about a pixel of the label, half a pixel on
    average."""
    errs = []
    for off in (0.0, 0.3, 0.6):
        img, gt = _render_art_sign(_background(), 400.3 + off, 140.6 + off, size)
        g = Box(*map(float, gt))
        d = _one(detector.detect(img), gt, 0.7)
        assert d.kind == 'warning'
        errs.append([d.box.x - g.x, g.x2 - d.box.x2, d.box.y - g.y, g.y2 - d.box.y2])
    errs = np.abs(errs)
    assert errs.max() <= 1.25 and errs.mean() <= 0.6


def test_refined_diamond_box_in_the_detector(detector):
    """``diamond_refine`` (default): the warning box comes from the face's brightness edges
    scaled by the art's face ratio.  A catalogue-proportioned sign (face, black line, margin)
    drawn at a sub-pixel position is boxed within 1 px per side; with the option off the
    sign is still found, by its mask-based box."""
    img = _background()
    cx, cy, outer = 420.4, 150.7, 22.3
    gt = _catalogue_diamond(img, cx, cy, outer)
    refined = _one(detector.detect(img), gt)
    b = refined.box
    assert refined.kind == 'warning'
    assert max(abs(b.x - gt[0]), abs(b.y - gt[1]), abs(b.x + b.w - gt[0] - gt[2]),
               abs(b.y + b.h - gt[1] - gt[3])) < 1.0, b
    assert _one(detector.with_config(diamond_refine=False).detect(img), gt, 0.7).kind == \
        'warning'


def test_refined_warning_boxes_match_whole_pixel_labels(detector):
    """``pixel_boxes`` (default): a refined warning box is the box of the pixels the measured
    outline covers more than half, as box labels are drawn.  On catalogue-proportioned
    signs of 9-30 px half-diagonal at random sub-pixel places, no box edge is more than a
    pixel from the label's and at least half the boxes equal it."""
    rng = np.random.default_rng(5)
    # exact, area-sampled catalogue geometry, no blur: the catalogue's face ratio, no
    # blurred line's bias and no operating point (``diamond_box_bias``)
    detector = detector.with_config(diamond_face_ratio=1 / 0.8876, diamond_edge_bias=0.0,
                                    diamond_box_bias=0.0)
    exact = 0
    for k in range(16):
        img = _background(k % 8)
        cx, cy, outer = rng.uniform(300, 500), rng.uniform(120, 170), rng.uniform(9, 30)
        _catalogue_diamond(img, cx, cy, outer)
        label = diamond_pixel_box(cx, cy, outer, outer)
        b = _one(detector.detect(img), (cx - outer, cy - outer, 2 * outer, 2 * outer), 0.7).box
        err = np.abs(np.array([b.x, b.y, b.x2, b.y2]) - np.array(label))
        assert err.max() <= 1.0, (outer, b, label)
        exact += err.max() == 0
    assert exact >= 8


def test_refined_diamond_size_does_not_depend_on_the_background(detector):
    """Blurred along the road (a 5 px motion blur), a warning sign is boxed the same size
    against a bright blue-white sky as against dark foliage (width + height of sub-pixel
    boxes, mean of 12 placements per background, within 0.9 px of each other)."""
    kern = np.full((1, 5), 0.2, np.float32)

    def size_err(det, colour):
        errs = []
        for size in (24, 32, 40):
            for off in (0.0, 0.25, 0.5, 0.75):
                bg = np.empty((480, 640, 3), np.uint8)
                bg[:] = colour
                img, gt = _render_art_sign(bg, 400.3 + off, 150.4 + off, size, blur=0.5)
                img = cv2.filter2D(img, -1, kern)
                d = _one(det.detect(img), gt, 0.6)
                errs.append(d.box.w - gt[2] + d.box.h - gt[3])
        return float(np.mean(errs))

    det = detector.with_config(pixel_boxes=False)
    assert abs(size_err(det, (235, 205, 170)) - size_err(det, (40, 55, 45))) <= 0.9


@pytest.mark.parametrize('size', [32, 46])
def test_refined_fit_kept_when_the_orange_left_out_is_a_blended_background(detector, size):
    """A sign whose blob takes in a rim of a duller orange background all round (a dusk sky
    blended into its edge): the catalogue's outline leaves that rim out on every side, but
    the rim is less saturated than the face, so the refined fit is kept (``hold_sat``): the
    box leaves the rim out, every side within a pixel.  (A face that a rim of its own orange
    surrounds, a wider margin, is boxed with it: :func:`test_diamond_at_known_box` and the
    brick-wall test.)"""
    x, y = 380.3, 130.6
    img = _background()
    rim = np.zeros(img.shape[:2], np.uint8)
    c, r = (x + size / 2, y + size / 2), size / 2 + 4.0
    cv2.fillConvexPoly(rim, np.round(np.array([(c[0], c[1] - r), (c[0] + r, c[1]),
                                               (c[0], c[1] + r), (c[0] - r, c[1])])
                                     ).astype(np.int32), 1)
    img[rim > 0] = (60, 120, 200)
    img, gt = _render_art_sign(img, x, y, size)
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert max(abs(d.box.x - g.x), abs(d.box.y - g.y), abs(d.box.x2 - g.x2),
               abs(d.box.y2 - g.y2)) <= 1.0, d.box


def test_refined_outline_extrapolates_a_tip_a_guardrail_hides(detector):
    """A guardrail across a sign's lower part, the tip showing below it: the labels are
    the whole sign's, and the outline measured on the edges above the rail gives its
    bottom within a pixel."""
    size = 44
    img, gt = _render_art_sign(_background(), 380.4, 120.3, size)
    rail_top = int(120.3 + 0.82 * size)
    img[rail_top:rail_top + 5, 340:470] = (150, 152, 150)
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.7)
    assert d.kind == 'warning'
    assert abs(g.y2 - d.box.y2) <= 1.0, d.box


@pytest.mark.parametrize('size, x, top', [(30, 380.7, 120.1), (36, 420.6, 140.2),
                                           (48, 300.4, 110.7), (56, 250.5, 100.5)])
def test_guardrail_across_the_lower_face_the_tip_below_it_boxed(detector, size, x, top):
    """A guardrail across a sign's lower part (a portable stand's sign behind it) hides a
    band of the face, and the tip shows again below it; the labels are the visible pixels'
    box, the tip included: every side within a pixel."""
    img, gt = _render_art_sign(_background(), x, top, size)
    rail = int(top + 0.7 * size)
    img[rail:rail + max(4, int(0.2 * size)), 200:600] = (150, 152, 150)
    g = Box(*map(float, gt))
    d = _one(detector.detect(img), gt, 0.5)
    assert d.kind == 'warning'
    errs = [d.box.x - g.x, g.x2 - d.box.x2, d.box.y - g.y, g.y2 - d.box.y2]
    assert np.abs(errs).max() <= 1.0, errs


def test_faded_legend_kept_by_its_measured_outline(detector):
    """A warning sign whose legend has faded to 0.72 of the face's brightness has no dark
    pixels for the legend test: its diamond edges, measured in the brightness, keep it.  A
    legendless orange blob of the same size (three discs: a warning's hull fill, found when
    the legend test is off) has no diamond edges and is rejected."""
    img, gt = _render_art_sign(_background(), 400.3, 130.6, 44)
    x, y, w, h = gt
    face = img[y:y + h, x:x + w]
    # the legend and border lightened to dark orange (the outline's contrast with the
    # background stays)
    img[y:y + h, x:x + w] = np.maximum(face, (np.array(ORANGE) * 0.72).astype(np.uint8))
    d = _one(detector.detect(img), gt, 0.7)
    assert d.kind == 'warning'

    blob = _background()
    for c, r in (((292, 125), 14), ((310, 140), 13), ((300, 120), 10)):
        cv2.circle(blob, c, r, ORANGE, -1)
    patch = (278, 110, 46, 44)
    found = detector.with_config(min_dark_inside=0.0).detect(blob)
    assert _near(found, patch) and _near(found, patch)[0].kind == 'warning'
    assert not _near(detector.detect(blob), patch)


@pytest.mark.parametrize('size, top', [(30, 222.4), (34, 223.4), (40, 220.4), (40, 226.4)])
def test_low_sign_behind_a_guardrail_kept_by_its_measured_outline(size, top):
    """A portable stand's sign mounted low (its bottom below the usual mounting row of the
    default model's geometry) with a guardrail across its lower corner: the mask is no clear
    diamond, which the mounting test demands down there (it rejects drums, cones and
    vehicles); its edges, measured in the brightness above the rail, keep it (IoU >= 0.8
    with the whole sign).  Not claimed: at 30 px the refinement misses at some sub-pixel
    positions (3 of 14 one-pixel steps)."""
    det = _default_detector()
    img, gt = _render_art_sign(_background(), 500.3, top, size)
    rail = gt[1] + int(0.75 * gt[3])
    img[rail:rail + 5, 380:640] = (150, 152, 150)
    d = _one(det.detect(img), gt, 0.8)
    assert d.kind == 'warning'
