"""Drawings and checks shared by the ``test_detection*`` modules (their fixtures ``model``
and ``detector``: ``conftest.py``): drawn diamonds (plain, on a stand with flags, in the
catalogue's proportions) and two-colour signs on a sky / trees / asphalt frame, the
simulator's sign art rendered at sub-pixel boxes, plain and foliage backgrounds, the
shipped detector, and the matching of detections to a labelled box."""
import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.interfaces import Box

ORANGE = (0, 110, 245)
WHITE = (238, 240, 240)
BLACK = (22, 22, 22)


def _background(seed=0, shape=(480, 640)):
    rng = np.random.default_rng(seed)
    img = np.empty((*shape, 3), np.uint8)
    img[: shape[0] // 2] = (205, 175, 150)          # sky
    img[shape[0] // 2:] = (85, 88, 84)              # asphalt
    img[shape[0] // 2 - 30: shape[0] // 2] = (50, 105, 60)   # tree line
    return cv2.add(img, rng.integers(0, 16, img.shape, dtype=np.uint8))


def _diamond(img, cx, cy, r, color=ORANGE, mask=None):
    pts = np.array([[cx, cy - r], [cx + r, cy], [cx, cy + r], [cx - r, cy]], np.int32)
    cv2.fillConvexPoly(img, pts, color)
    inner = np.array([[cx, cy - r + 4], [cx + r - 4, cy], [cx, cy + r - 4],
                      [cx - r + 4, cy]], np.int32)
    cv2.polylines(img, [inner], True, BLACK, max(1, r // 20))
    cv2.putText(img, 'RW', (cx - r // 2, cy + r // 5), cv2.FONT_HERSHEY_DUPLEX, r / 45, BLACK,
                max(1, r // 15))
    if mask is not None:
        cv2.fillConvexPoly(mask, pts, 1)
    return (cx - r, cy - r, 2 * r + 1, 2 * r + 1)


def _regulatory(img, x, y, w, h):
    """R22-1 style: orange top third, white bottom with a black legend and border."""
    cv2.rectangle(img, (x, y), (x + w - 1, y + h - 1), WHITE, -1)
    cv2.rectangle(img, (x, y), (x + w - 1, y + h // 3), ORANGE, -1)
    cv2.rectangle(img, (x + 2, y + 2), (x + w - 3, y + h - 3), BLACK, 2)
    cv2.putText(img, 'BEGINS', (x + 6, y + int(0.7 * h)), cv2.FONT_HERSHEY_DUPLEX, w / 130,
                BLACK, 2)
    return (x, y, w, h)


def _default_detector():
    """The learned detector with the shipped model, as ``evaluate color`` builds it."""
    from workzone_ros.resources import config_path
    from workzone_ros.tools import eval_color as ec
    model = cm.load_model(config_path('models/color_orange.npz'))
    return ec.build_detectors(model, ['learned'], False, 0.5)['learned'][0]


def _near(dets, gt, iou=0.2):
    """The detections overlapping box ``gt`` by more than ``iou``."""
    return [d for d in dets if d.box.iou(Box(*map(float, gt))) > iou]


def _one(dets, gt, iou=0.8):
    hits = [d for d in dets if d.box.iou(Box(*map(float, gt))) >= iou]
    assert len(hits) == 1, (gt, dets)
    return hits[0]


def _flagged_diamond(img, cx, cy, r):
    """A diamond on a portable stand with two orange flags above its top corner."""
    gt = _diamond(img, cx, cy, r)
    for dx in (-r // 3, r // 3):
        q = max(3, r // 3)
        top = cy - r + 2                       # on the mast, behind the top corner
        cv2.fillConvexPoly(img, np.array([[cx + dx, top - 2 * q], [cx + dx + q, top - q],
                                          [cx + dx, top], [cx + dx - q, top - q]], np.int32),
                           ORANGE)
    return gt


def _plain(bgr, noise, seed, shape=(480, 640)):
    """A frame of one colour plus uniform noise in ``[0, noise)``."""
    img = np.empty((*shape, 3), np.uint8)
    img[:] = bgr
    return cv2.add(img, np.random.default_rng(seed).integers(0, noise, img.shape,
                                                              dtype=np.uint8))


def _render_art_sign(img, x, y, size, key='road_work_ahead', blur=0.7, orange=None,
                     angle=0.0):
    """The simulator's sign art warped to a sub-pixel box (its outer edge at x, y and
    x + size, y + size), composited by its alpha and blurred a little like a camera; the
    ground-truth box as ``synth`` labels it (pixels more than half covered).  ``orange``:
    the sheeting's BGR (default the simulator's); ``angle``: the face turned about its
    middle by this (degrees, clockwise in the image: a leaning post)."""
    from workzone_ros.sim import signart
    art = signart.sign_face(key, next(a for a in (32, 48, 64, 96, 128, 192, 256, 384)
                                      if a >= 1.5 * size), orange=orange)
    s = size / art.shape[1]
    hm = np.array([[s, 0, x - 0.5 + 0.5 * s], [0, s, y - 0.5 + 0.5 * s], [0, 0, 1.0]])
    if angle:
        c = (x - 0.5 + 0.5 * size, y - 0.5 + 0.5 * s * art.shape[0])
        hm = np.vstack([cv2.getRotationMatrix2D(c, -angle, 1.0), (0, 0, 1)]) @ hm
    warped = cv2.warpPerspective(art, hm, (img.shape[1], img.shape[0]),
                                 flags=cv2.INTER_LINEAR)
    out = np.clip(signart.over(warped, img), 0, 255).astype(np.uint8)
    ys, xs = np.nonzero(warped[..., 3] > 127.5)
    box = (int(xs.min()), int(ys.min()), int(xs.max() + 1 - xs.min()),
           int(ys.max() + 1 - ys.min()))
    return cv2.GaussianBlur(out, (0, 0), blur), box


def _foliage(seed=0, shape=(480, 640)):
    """Dark green roadside foliage behind the whole sign (no white background)."""
    rng = np.random.default_rng(seed)
    img = np.empty((*shape, 3), np.uint8)
    img[:] = (60, 100, 70)
    img[300:] = (85, 88, 84)
    return cv2.add(img, rng.integers(0, 16, img.shape, dtype=np.uint8))


def _catalogue_diamond(img, cx, cy, outer, ss=8):
    """A warning sign in the catalogue's proportions (orange face, black line from 0.8876 to
    0.9724 of the half-diagonal, orange margin) with a legend, area-sampled at a sub-pixel
    centre; returns its continuous box."""
    n = int(2 * outer) + 12
    x0, y0 = int(cx - outer) - 6, int(cy - outer) - 6
    ys, xs = np.mgrid[0:n * ss, 0:n * ss]
    d = np.abs((xs + 0.5) / ss + x0 - cx) + np.abs((ys + 0.5) / ss + y0 - cy)
    layers = np.zeros(d.shape, np.float32)       # 0 background, 1 orange, 2 black
    layers[d <= outer] = 1
    layers[d <= 0.9724 * outer] = 2
    layers[d <= 0.8876 * outer] = 1
    patch = img[y0:y0 + n, x0:x0 + n].astype(np.float32)
    for value, colour in ((1, ORANGE), (2, BLACK)):
        cover = (layers == value).reshape(n, ss, n, ss).mean(axis=(1, 3))[..., None]
        patch = patch * (1 - cover) + np.array(colour, np.float32) * cover
    img[y0:y0 + n, x0:x0 + n] = np.clip(patch, 0, 255).astype(np.uint8)
    cv2.putText(img, 'RW', (int(cx - 0.55 * outer), int(cy + 0.24 * outer)),
                cv2.FONT_HERSHEY_DUPLEX, outer / 45, BLACK, 1)
    return (cx - outer, cy - outer, 2 * outer, 2 * outer)
