"""core.detect, measuring a warning diamond's outline: the mask fits (``fit_diamond``,
``fit_rhombus``, ``diamond_holds``), the refinement on the face's brightness edges
(``refine_diamond``, ``refine_shifted``, the bright-background shift), the blurred-chroma
fit (``fit_blurred_diamond``), the detector's own use of them (edge bias, plausible shapes,
square boxes of far signs, the chroma beyond an outline) and the label-like pixel boxes."""
import cv2
import numpy as np
import pytest
from detection_helpers import _background, _render_art_sign

from workzone_ros.core.detect import DetectorConfig
from workzone_ros.core.detect.common import pixel_box
from workzone_ros.core.detect.diamond import (
    _RHOMBUS_SIGNS,
    diamond_pixel_box,
    fit_diamond,
    fit_rhombus,
    refine_diamond,
    refine_shifted,
)
from workzone_ros.core.detect.diamond_search import (
    _blurred_diamond,
    diamond_holds,
    fit_blurred_diamond,
)
from workzone_ros.core.detect.edges import _taper


def _aa_diamond_mask(cx, cy, a, b, shape=(120, 120), ss=8):
    """Coverage of a diamond at sub-pixel centre / half-diagonals, thresholded at 0.5."""
    h, w = shape
    ys, xs = np.mgrid[0:h * ss, 0:w * ss]
    inside = np.abs((xs + 0.5) / ss - cx) / a + np.abs((ys + 0.5) / ss - cy) / b <= 1.0
    cover = inside.reshape(h, ss, w, ss).mean(axis=(1, 3))
    return (cover >= 0.5).astype(np.uint8)


@pytest.mark.parametrize('cx, cy, a, b', [(40.3, 50.6, 10.2, 10.7), (60.8, 55.1, 24.5, 23.0),
                                          (58.4, 61.9, 41.0, 44.3)])
def test_fit_diamond_recovers_a_diamond_with_flags_on_top(cx, cy, a, b):
    mask = _aa_diamond_mask(cx, cy, a, b)
    fit = fit_diamond(mask)
    assert fit is not None
    assert abs(fit[0] - cx) < 0.5 and abs(fit[1] - cy) < 0.75
    assert abs(fit[2] - a) < 1.0 and abs(fit[3] - b) < 1.0 and fit[4] > 0.8
    # a portable stand's two orange flags just above the top corner
    flags = mask.copy()
    fy = int(cy - b)
    for dx in (-0.35 * a, 0.35 * a):
        r = max(2, int(0.3 * a))
        cv2.fillConvexPoly(flags, np.array([[cx + dx, fy - 2 * r], [cx + dx + r, fy - r],
                                            [cx + dx, fy], [cx + dx - r, fy - r]], np.int32),
                           1)
    ys = np.nonzero(flags.any(axis=1))[0]
    assert ys[0] < cy - b - 2                 # the blob's box reaches over the flags
    fit = fit_diamond(flags)
    assert fit is not None
    assert abs(fit[1] - cy) < 1.0 and abs(fit[2] - a) < 1.0 and abs(fit[3] - b) < 1.5


def test_fit_diamond_rejects_what_is_no_diamond():
    rect = np.zeros((60, 60), np.uint8)
    rect[10:40, 12:50] = 1
    fit = fit_diamond(rect)
    assert fit is None or fit[4] < 0.5
    assert fit_diamond(np.zeros((10, 10), np.uint8)) is None
    assert fit_diamond(rect[:3]) is None


def _sign_value(cx, cy, a_face, shape=(90, 90), ss=8, blur=0.6, face=200.0, line=20.0,
                bg=60.0, gain=None, seed=0):
    """Brightness of a warning sign (catalogue art: face, black line, thin orange margin) at a
    sub-pixel centre, area-sampled, blurred, noisy; ``gain``: a radial hot spot."""
    h, w = shape
    ys, xs = np.mgrid[0:h * ss, 0:w * ss]
    d = np.abs((xs + 0.5) / ss - cx) + np.abs((ys + 0.5) / ss - cy)     # a = b diamonds
    big = np.full(d.shape, bg, np.float32)
    outer = a_face / 0.8876
    big[d <= outer] = face
    big[d <= 0.9724 * outer] = line
    big[d <= a_face] = face
    img = big.reshape(h, ss, w, ss).mean(axis=(1, 3))
    if gain is not None:
        yy, xx = np.mgrid[0:h, 0:w]
        img = img * (1.0 + gain * np.exp(-((xx + 0.5 - cx) ** 2 + (yy + 0.5 - cy) ** 2)
                                         / (2 * (0.5 * a_face) ** 2)))
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur)
    return img + np.random.default_rng(seed).normal(0, 2.0, img.shape).astype(np.float32)


@pytest.mark.parametrize('a_face, gain', [(14.5, None), (14.5, 0.5), (26.0, None),
                                          (26.0, 1.5)])
def test_refine_diamond_finds_the_face_edges_to_a_fraction_of_a_pixel(a_face, gain):
    """From a first estimate 6 % too wide, 6 % too short and 0.6 px off (a mask fit's
    typical error), the brightness edges give the face within 2 % and 0.25 px, also under a
    headlight's hot spot (the face's brightness up to 2.5x higher in its middle).  Not
    claimed: faces under ~12 px half-diagonal (signs under ~28 px), where the error stays at
    3-9 % with a hot spot."""
    cx, cy = 45.3, 44.8
    img = _sign_value(cx, cy, a_face, gain=gain)
    got = refine_diamond(img, (cx + 0.6, cy - 0.6, 1.06 * a_face, 0.94 * a_face))
    assert got is not None
    assert abs(got[0] - cx) < 0.25 and abs(got[1] - cy) < 0.25
    assert abs(got[2] / a_face - 1) < 0.02 and abs(got[3] / a_face - 1) < 0.02


@pytest.mark.parametrize('dx, dy', [(4.0, 2.5), (-3.5, -3.0)])
def test_refine_from_shifted_starts_finds_a_large_face(dx, dy):
    """A large face (46 px half-diagonal: a sign of ~100 px, real frames) from a start whose
    centre is 4.6-4.7 px off (a mask that took in a surface of the sign's colour beside it):
    the edges lie past the few-pixel search and the refinement fails.  From the start moved
    by 2.25 px in the eight directions, the smallest fit is the face, within 0.3 px and 2 %
    (other moves fit the sign's outer edge, 2-5 px larger).  A flat patch gives none.  Not
    claimed: starts 6 px off, from which every moved start may fit an outer edge."""
    cx, cy, a_face = 75.4, 74.7, 46.0
    img = _sign_value(cx, cy, a_face, shape=(150, 150), blur=0.8)
    start = (cx + dx, cy + dy, a_face / 0.8876, a_face / 0.8876)
    assert refine_diamond(img, start) is None
    fits = []

    def refine(st):
        fit = refine_diamond(img, st)
        if fit is not None:
            fits.append(fit)
        return fit
    got, verdict = refine_shifted([start], refine, lambda f: (f, 'holds'))
    assert verdict == 'holds'
    assert abs(got[0] - cx) < 0.3 and abs(got[1] - cy) < 0.3
    assert abs(got[2] / a_face - 1) < 0.02 and abs(got[3] / a_face - 1) < 0.02
    assert max(f[2] for f in fits) > a_face + 1.5        # an outer edge fitted too
    flat = np.full((150, 150), 120, np.float32)
    assert refine_shifted([start], lambda st: refine_diamond(flat, st)) is None


def test_refine_diamond_gives_up_without_an_edge():
    """A flat patch, and a diamond cut by the window's edge, give None (the caller keeps its
    mask-based box)."""
    flat = np.full((60, 60), 120, np.float32)
    assert refine_diamond(flat, (30, 30, 12, 12)) is None
    img = _sign_value(10.0, 45.0, 18.0)
    assert refine_diamond(img, (10.0, 45.0, 18.0, 18.0)) is None
    assert refine_diamond(img, (45.0, 45.0, 2.0, 2.0)) is None


def test_pixel_boxes_are_the_pixels_a_label_holds():
    """``pixel_box`` equals the box of the pixel centres inside a rectangle, and
    ``diamond_pixel_box`` the box of the pixels more than half covered by a diamond (brute
    force over every pixel, 8 x 8 samples each), at random sub-pixel places; at a diamond's
    corners that is inside the box of the pixel centres it holds."""
    rng = np.random.default_rng(3)
    cols = np.arange(0, 120) + 0.5
    sub = (np.arange(8) + 0.5) / 8
    grid = (np.arange(0, 120)[:, None] + sub[None, :]).ravel()          # 960 samples
    inner = 0
    for _ in range(200):
        cx, cy = rng.uniform(40, 80, 2)
        a, b = rng.uniform(2.0, 30.0, 2)
        inside = (np.abs(grid[None, :] - cx) / a + np.abs(grid[:, None] - cy) / b) <= 1.0
        cover = inside.reshape(120, 8, 120, 8).mean(axis=(1, 3))
        ys, xs = np.nonzero(cover > 0.5)
        centres = (np.abs(cols[None, :] - cx) / a + np.abs(cols[:, None] - cy) / b) <= 1.0
        yc, xc = np.nonzero(centres)
        got = diamond_pixel_box(cx, cy, a, b)
        if xs.size:
            assert got == (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1), (cx, cy, a, b)
            inner += got != (xc.min(), yc.min(), xc.max() + 1, yc.max() + 1)
        x, y = cx - a, cy - b
        xs = np.nonzero((cols >= x) & (cols <= x + 2 * a))[0]
        ys = np.nonzero((cols >= y) & (cols <= y + 2 * b))[0]
        assert pixel_box(x, y, 2 * a, 2 * b) == (xs.min(), ys.min(), xs.max() + 1 - xs.min(),
                                                    ys.max() + 1 - ys.min())
    assert inner > 40           # the corner rule takes a pixel less on a third of them


def test_fit_rhombus_drops_a_stroke_taken_for_an_edge():
    """Eight edge points of a diamond, one of them pulled 3 px inwards (a legend stroke next
    to the edge): the fit drops it and returns the diamond; with four points off by 2.5-3 px
    in and out it gives up rather than guess."""
    cx, cy, a, b = 40.3, 35.8, 14.0, 12.5
    signs = np.repeat(_RHOMBUS_SIGNS, 2, axis=0)
    t = np.tile([0.3, 0.7], 4)[:, None]
    # points along each edge from its x-axis corner to its y-axis corner
    pts = np.column_stack([cx + signs[:, 0] * a * (1 - t[:, 0]), cy + signs[:, 1] * b * t[:, 0]])
    got = fit_rhombus(pts, signs)
    assert np.allclose(got, (cx, cy, a, b), atol=1e-6)
    bad = pts.copy()
    bad[3] -= 3.0 * signs[3] / np.sqrt(2)
    assert np.allclose(fit_rhombus(bad, signs), (cx, cy, a, b), atol=1e-6)
    assert fit_rhombus(bad, signs, max_drop=0) is None
    worse = pts.copy()
    for i, shift in ((0, 3.0), (3, -3.0), (4, 3.0), (7, -2.5)):
        worse[i] -= shift * signs[i] / np.sqrt(2)
    assert fit_rhombus(worse, signs) is None


def test_diamond_holds_judges_the_layout_not_stray_orange():
    """A face whose catalogue outline holds the orange passes, also with orange flags above
    it; an orange diamond reaching well beyond the outline all round (its line far inside
    the edge: not the catalogue's layout) does not."""
    yy, xx = np.mgrid[0:80, 0:80] + 0.5
    face = (40.0, 42.0, 16.0, 16.0)
    sign = (np.abs(xx - 40) + np.abs(yy - 42) <= 16 * 1.1266).astype(np.uint8)
    assert diamond_holds(sign, face, 1.1266, 0.97)
    flags = sign.copy()
    flags[2:14, 30:50] = 1
    assert diamond_holds(flags, face, 1.1266, 0.97)
    wide = (np.abs(xx - 40) + np.abs(yy - 42) <= 16 * 1.35).astype(np.uint8)
    assert not diamond_holds(wide, face, 1.1266, 0.97)


def test_refine_diamond_tolerates_a_stretch_hidden_by_a_symbol():
    """A black symbol reaching the face's edge over one stretch (a lane-shift arrow, a
    reverse curve) leaves that stretch without a face-to-border step: the diamond is still
    measured from the other seven (within 3 % and 0.4 px), and only with no stretch allowed
    to go missing does it give up."""
    cx, cy, a_face = 45.3, 44.8, 20.0
    img = _sign_value(cx, cy, a_face)
    # dark across the upper-right edge's first stretch, from 9 px inside to 6 px outside
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]] + 0.5
    along = (xx - cx) + (yy - cy)                 # -a at the top corner, a at the right
    normal = ((xx - cx) - (yy - cy)) / a_face     # 1 on the upper-right edge
    img[(np.abs(along + 0.4 * a_face) < 0.3 * a_face) & (normal > 0.55) & (normal < 1.3)] = 20.0
    fit = (cx + 0.5, cy - 0.4, 1.05 * a_face, 0.95 * a_face)
    got = refine_diamond(img, fit)
    assert got is not None
    assert abs(got[0] - cx) < 0.4 and abs(got[1] - cy) < 0.4
    assert abs(got[2] / a_face - 1) < 0.03 and abs(got[3] / a_face - 1) < 0.03
    assert refine_diamond(img, fit, max_lost=0) is None


def _lane_ends_value(cx, cy, a_face, seed, ss=8, blur=0.6):
    """As :func:`_sign_value` with a black vertical bar (0.14 x the half-diagonal wide) at
    0.3 of the half-diagonal left of the middle, from edge to edge: the lane-ends symbol's
    long line, which runs into the upper-left edge near the top and the lower-left one near
    the bottom."""
    h, w = 90, 90
    ys, xs = np.mgrid[0:h * ss, 0:w * ss]
    x, y = (xs + 0.5) / ss, (ys + 0.5) / ss
    d = np.abs(x - cx) + np.abs(y - cy)
    big = np.full(d.shape, 60.0, np.float32)
    outer = a_face / 0.8876
    big[d <= outer] = 200.0
    big[d <= 0.9724 * outer] = 20.0
    big[d <= a_face] = 200.0
    big[(np.abs(x - (cx - 0.3 * a_face)) <= 0.07 * a_face) & (d <= a_face)] = 20.0
    img = big.reshape(h, ss, w, ss).mean(axis=(1, 3))
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur)
    return img + np.random.default_rng(seed).normal(0, 2.0, img.shape).astype(np.float32)


def test_refine_diamond_leaves_out_stretches_a_stroke_runs_into():
    """A legend stroke running into an edge reads there as a soft step inside the edge.
    With ``stroke_steps`` such stretches, fitted much blurrier than the sign's others, are
    left out: over ten noise draws the face of a 29 px lane-ends diamond is measured within
    0.3 px (centre and half-diagonals) in at least eight; on a plain diamond it changes
    nothing.  Out-of-range settings are refused."""
    cx, cy, a_face = 45.3, 44.8, 14.5
    start = (cx + 0.4, cy - 0.3, 1.04 * a_face, 0.96 * a_face)

    def error(got):
        return np.inf if got is None else max(abs(got[0] - cx), abs(got[1] - cy),
                                              abs(got[2] - a_face), abs(got[3] - a_face))

    on = []
    for seed in range(10):
        img = _lane_ends_value(cx, cy, a_face, seed)
        on.append(error(refine_diamond(img, start, stroke_steps=2)))
        plain = _sign_value(cx, cy, a_face, seed=seed)
        assert refine_diamond(plain, start, stroke_steps=2) == \
            refine_diamond(plain, start, stroke_steps=0)
    assert sum(e < 0.3 for e in on) >= 8
    with pytest.raises(ValueError, match='diamond_stroke_steps'):
        DetectorConfig(diamond_stroke_steps=7)
    with pytest.raises(ValueError, match='diamond_stroke_steps'):
        DetectorConfig(diamond_stroke_steps=-1)


def test_small_refined_diamond_taken_as_square(detector):
    """A refined outline of a far sign (``diamond_square_max``) whose width and height
    differ by no more than ``diamond_square_px`` is boxed as a square of their mean size:
    one measurement of the sign's size instead of two noisy ones.  A larger sign, one whose
    sides differ by more (turned, a tip hidden) or one measured above an occluder's cut
    keeps its own width and height; bad settings are refused."""
    cfg = detector.config
    k = cfg.diamond_face_ratio

    def box(a, b, cut=False, det=detector):
        c = 2 + a * k                              # the blob's box is the sign's
        got = det._diamond_box((c + 0.3, c + 0.1, a, b, k, cfg.diamond_clamp_px), True,
                               (2, 2, round(2 * a * k), round(2 * b * k)), True, cut)
        return got[2], got[3]

    a = 10.0 / k                                   # a 20 px sign
    w, h = box(a, a + 1.0 / k)                     # 20 x 22 measured
    assert w == h and w in (20, 21, 22)
    assert box(a, a + 3.0 / k) == box(a, a + 3.0 / k, det=detector.with_config(
        diamond_square_px=0.0))                    # 20 x 26: not a square
    w, h = box(a, a + 1.0 / k, cut=True)           # measured above a cut: its own height
    assert h - w >= 1
    big = 17.0 / k                                 # a 34 px sign
    w, h = box(big, big + 1.0 / k)
    assert h - w >= 1
    for bad in (dict(diamond_square_px=-1.0), dict(diamond_square_max=-2.0),
                dict(diamond_box_bias=3.0)):
        with pytest.raises(ValueError, match='diamond_square|diamond_box_bias'):
            DetectorConfig(**bad)


@pytest.mark.parametrize('blur', [0.7, 1.5])
def test_outline_inside_a_sign_is_told_by_the_chroma_beyond_it(detector, blur):
    """``rim_chroma``: the sign outline of the correct face leaves background chroma just
    beyond it; the outline of a face 12 % too small (a legend's edge taken for the line, in
    a faded sign whose mask stops short too) leaves the sign's own orange there."""
    size, x, y = 36, 380.3, 130.6
    img, gt = _render_art_sign(_background(), x, y, size, blur=blur)
    a_face = 0.5 * size / detector.config.diamond_face_ratio
    cx, cy = x + 0.5 * size, y + 0.5 * size
    window = (int(x) - 4, int(y) - 4, int(x + size) + 5, int(y + size) + 5)
    wx, wy = window[:2]
    right = (cx - wx, cy - wy, a_face, a_face)
    small = (cx - wx, cy - wy, 0.88 * a_face, 0.88 * a_face)
    assert not detector._inside_sign(img, window, right, size, size)
    assert detector._inside_sign(img, window, small, size, size)
    assert not detector.with_config(rim_chroma=0.0)._inside_sign(img, window, small, size,
                                                                 size)


def _blurred_chroma(cx, cy, a, b, sigma, shape=(70, 76), ss=8, face=150.0, bg=10.0,
                    tilt=(0.6, -0.4), art=False, stroke=True, seed=1):
    """Chroma (R - B) of a sign: a diamond of half-diagonals ``(a, b)`` (with ``art``: the
    catalogue's face, black line and thin margin inside that outline) over a tilted
    background plane, a legend stroke (chroma 0) across its middle, area-sampled, blurred
    by ``sigma`` px, noisy."""
    h, w = shape
    ys, xs = np.mgrid[0:h * ss, 0:w * ss]
    x, y = (xs + 0.5) / ss, (ys + 0.5) / ss
    rel = np.abs(x - cx) / a + np.abs(y - cy) / b
    big = bg + tilt[0] * (x - cx) + tilt[1] * (y - cy)
    big = np.where(rel <= 1.0, face, big)
    if art:
        big = np.where((rel <= 0.9724) & (rel > 0.8876), 0.0, big)
    if stroke:
        big = np.where((np.abs(x - cx) < 0.12 * a) & (rel <= 0.6), 0.0, big)
    img = big.reshape(h, ss, w, ss).mean(axis=(1, 3)).astype(np.float32)
    img = cv2.GaussianBlur(img, (0, 0), sigma)
    return img + np.random.default_rng(seed).normal(0, 3.0, img.shape).astype(np.float32)


@pytest.mark.parametrize('a, b, sigma, stroke', [
    (9.3, 10.1, 1.0, False), (9.3, 10.1, 2.5, False), (17.6, 16.2, 2.5, False),
    (9.3, 10.1, 1.0, True), (17.6, 16.2, 1.0, True)])
def test_fit_blurred_diamond_recovers_a_blurred_sign(a, b, sigma, stroke):
    """From the mask's typical start (15 % small, 1 px off), the diamond of a sign blurred
    by up to 2.5 px over a background gradient is found within 0.25 px (centre and
    half-diagonals; the larger sign on a window binned 2 x 2), also with a legend stroke
    down its middle at 1 px blur; its blur within 0.35 px."""
    cx, cy = 37.4, 34.7
    img = _blurred_chroma(cx, cy, a, b, sigma, stroke=stroke)
    fit = fit_blurred_diamond(img, (cx + 1.0, cy - 0.8, 0.85 * a, 0.85 * b))
    assert fit is not None
    fcx, fcy, fa, fb, fs, face, bg = fit
    assert max(abs(fcx - cx), abs(fcy - cy), abs(fa - a), abs(fb - b)) < 0.25, fit
    assert abs(fs - sigma) < 0.35 and face > bg


def test_fit_blurred_diamond_of_the_catalogue_art_lies_between_face_and_outline():
    """With the catalogue's black line inside the outline, blurred, the fitted diamond lies
    between the face's and the sign's outline (the detector scales it by
    ``blur_fit_ratio``)."""
    cx, cy, a = 37.4, 34.7, 12.0
    fit = fit_blurred_diamond(_blurred_chroma(cx, cy, a, a, 1.5, art=True, stroke=False),
                                 (cx, cy, 0.85 * a, 0.85 * a))
    assert fit is not None
    assert 0.8876 * a < fit[2] < a and 0.8876 * a < fit[3] < a, fit


def test_fit_blurred_diamond_gives_none_without_a_coloured_sign():
    """A flat image, or a 'sign' less coloured than its surround, gives no diamond."""
    flat = np.random.default_rng(0).normal(20.0, 3.0, (60, 60)).astype(np.float32)
    assert fit_blurred_diamond(flat, (30.0, 30.0, 10.0, 10.0)) is None
    hole = -_blurred_chroma(30.0, 30.0, 10.0, 10.0, 1.5, shape=(60, 60), stroke=False)
    assert fit_blurred_diamond(hole, (30.0, 30.0, 10.0, 10.0)) is None
    assert fit_blurred_diamond(flat[:3, :3], (1.5, 1.5, 1.0, 1.0)) is None


def test_blurred_diamond_jacobian_matches_finite_differences():
    """The analytic Jacobian the fit uses agrees with central differences."""
    ys, xs = np.mgrid[0:40, 0:44]
    xs, ys = xs.ravel() + 0.5, ys.ravel() + 0.5
    p = np.array([21.3, 19.8, 9.2, 10.4, 1.4, 150.0, 12.0, 0.3, -0.2])
    _, jac = _blurred_diamond(p, xs, ys, jac=True)
    eps = 1e-5
    num = np.stack([(_blurred_diamond(p + e, xs, ys)[0] - _blurred_diamond(p - e, xs, ys)[0])
                    / (2 * eps) for e in np.eye(9) * eps], axis=1)
    assert np.abs(jac - num).max() < 1e-5 * np.abs(num).max()


def test_refine_reports_the_edge_blur_and_the_detector_takes_its_bias(detector):
    """``refine_diamond(..., info=)`` reports the edges' fitted blur: small for a sharp face,
    1 px or more for a defocused one; the detector then takes ``diamond_blur_bias`` off the
    face (heavily blurred faces are measured further out), ``diamond_edge_bias`` otherwise."""
    cx, cy, a_face = 45.3, 44.8, 16.0
    sharp, soft = _sign_value(cx, cy, a_face, blur=0.5), _sign_value(cx, cy, a_face, blur=2.0)
    infos = []
    for img in (sharp, soft):
        info = {}
        assert refine_diamond(img, (cx, cy, a_face, a_face), max_change=0.4,
                                 info=info) is not None
        infos.append(info['blur'])
    assert infos[0] < 1.0 <= infos[1], infos
    cfg = detector.config
    for img, bias in ((sharp, cfg.diamond_edge_bias), (soft, cfg.diamond_blur_bias)):
        raw = refine_diamond(img, (cx, cy, a_face, a_face), cfg.diamond_border_rel,
                                cfg.diamond_margin_rel, cfg.diamond_max_change)
        got = detector._refine(img, (cx, cy, a_face, a_face))
        assert got[2] == pytest.approx(raw[2] - bias) and got[3] == pytest.approx(raw[3] - bias)


@pytest.mark.parametrize('sx, sy', [(1.0, 1.16), (1.12, 1.0)])
def test_refined_face_cut_back_to_a_plausible_shape(detector, sx, sy):
    """A face measured 16 % taller than wide (a small sign stretched by vertical motion
    blur) or 12 % wider than tall is no square sign facing the road: the refined face keeps
    its centre and is cut back to ``diamond_tall_max`` (1.08) x its width or
    ``diamond_wide_max`` (1.06) x its height; with the limits off it keeps the measured
    shape."""
    cx, cy, a_face = 45.3, 44.8, 16.0
    img = _sign_value(cx, cy, a_face)
    img = cv2.resize(img, None, fx=sx, fy=sy, interpolation=cv2.INTER_LINEAR)
    start = (cx * sx, cy * sy, a_face * sx, a_face * sy)
    free = detector.with_config(diamond_tall_max=2.0, diamond_wide_max=2.0)._refine(img, start)
    assert free is not None and abs(free[3] / free[2] - sy / sx) < 0.03
    got = detector._refine(img, start)
    assert abs(got[0] - free[0]) < 1e-9 and abs(got[1] - free[1]) < 1e-9
    if sy > sx:
        assert abs(got[3] / got[2] - 1.08) < 1e-9 and got[2] == free[2]
    else:
        assert abs(got[2] / got[3] - 1.06) < 1e-9 and got[3] == free[3]


def test_bright_shift_tapers_with_the_border_line():
    """The shift for a background brighter than the face (:func:`_taper`): full on a border
    line up to ``line0`` px wide, none from ``line1``, linear between; 0 px turns it off."""
    bb = (0.3, 0.5, 1.0)
    assert _taper(bb, 0.3) == pytest.approx(0.3)
    assert _taper(bb, 0.75) == pytest.approx(0.15)
    assert _taper(bb, 1.0) == 0.0 and _taper(bb, 2.0) == 0.0
    assert _taper((0.0, 0.5, 1.0), 0.3) == 0.0


def _art_diamond(size, bg, rng, blur=0.6):
    """The catalogue's "ROAD WORK AHEAD" art, ``size`` px, over a grey ``bg`` (8-bit),
    blurred ``blur`` px, with noise: (luma image, true (cx, cy, a, b) of the sign)."""
    from workzone_ros.sim import signart
    art = signart.sign_face('road_work_ahead', 32)
    k = size / art.shape[1]
    ox, oy = rng.uniform(20.0, 21.0, 2)
    m = np.array([[k, 0, 0.5 * k + ox - 0.5], [0, k, 0.5 * k + oy - 0.5]], np.float32)
    n = int(size + 45)
    wp = cv2.warpAffine(art, m, (n, n), flags=cv2.INTER_LINEAR).astype(np.float32)
    alpha = wp[..., 3:] / 255.0
    face = np.minimum(wp[..., :3] / np.maximum(alpha, 1 / 255), 255) * 0.8
    img = np.full((n, n, 3), float(bg), np.float32) * (1 - alpha) + face * alpha
    img = cv2.GaussianBlur(img, (0, 0), blur)
    img = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
    half = size / 2
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), (ox + half, oy + half, half, half)


@pytest.mark.parametrize('bg', [60, 230])
def test_small_diamond_against_a_brighter_background_taken_further_out(bg):
    """A 14 px diamond (the catalogue art, blurred 0.6 px) over grey: against a
    background brighter than its face (luma 230 vs about 100) each edge stretch is taken
    ``diamond_bright_bias`` (0.3 px) further out along its normal, so the half-diagonals
    come out 0.3 x sqrt(2) px larger; against a darker one (luma 60) the measurement is the
    same with and without it."""
    rng = np.random.default_rng(3)
    diffs = []
    for _ in range(12):
        luma, true = _art_diamond(14, bg, rng)
        start = (true[0] + 0.3, true[1] - 0.3, true[2] / 1.1266 * 1.03, true[3] / 1.1266 * 1.03)
        off = refine_diamond(luma, start)
        on = refine_diamond(luma, start, bright_bias=(0.3, 0.47, 0.95))
        if off is None or on is None:
            continue
        diffs.append(0.5 * (on[2] + on[3] - off[2] - off[3]))
    assert len(diffs) >= 8
    if bg < 100:
        assert np.allclose(diffs, 0.0)
    else:
        assert 0.38 <= float(np.median(diffs)) <= 0.46, diffs
