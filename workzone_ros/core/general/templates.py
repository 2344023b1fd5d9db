"""Template matching of red sign candidates against STOP, YIELD and DO NOT ENTER.

Cahail, Vera, Daddeo, Shelton, Menz, Long, "Traffic Sign Detection" (UT Austin), section
3.4.3: the part of the image inside a red blob's bounding box is cut out, what is not the
sign is painted white, and the templates of the three red signs are matched against it at
several sizes.  At each position the normalised correlation is computed; the number of
positions above a threshold divided by the number of positions is the template's score, the
maximum over sizes is kept, and the template with the highest score wins.

The templates are drawn by our own sign art (:func:`workzone_ros.sim.signart.sign_face`),
never downloaded, and prepared exactly as a candidate is: the red region of the face (its
outline filled), everything outside it white, cut to its box.  Both the candidate and the
templates are scaled to a square (``template_px``): a sign turned away from the camera is
narrower than it is tall, and the square absorbs that.  We also keep the best correlation,
a finer measure of fit than the share of good positions.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from workzone_ros.core.general.config import RED_TEMPLATES, GeneralConfig

__all__ = ['Match', 'template_bank', 'prepare_crop', 'match_templates', 'SHAPES']

#: The shape of each red sign.
SHAPES = {'stop': 'octagon', 'yield': 'triangle', 'do_not_enter': 'square'}
_ART_PX = 256      # size the faces are drawn at before they are shrunk to templates


@dataclass(frozen=True)
class Match:
    """The outcome of matching one candidate.

    Attributes:
        key: the template chosen by ``GeneralConfig.select_by``: the best correlation
            (``ncc``) or, Cahail et al.'s rule, the highest score (``score``).
        score: its share of positions above the correlation threshold (max over sizes).
        ncc: its best normalised correlation (max over positions and sizes).
        scores: every template's (score, ncc).
    """

    key: str
    score: float
    ncc: float
    scores: dict


def _red_region(face_bgr: np.ndarray) -> np.ndarray:
    """The filled outline of the red part of a face (uint8 0/1)."""
    hsv = cv2.cvtColor(face_bgr, cv2.COLOR_BGR2HSV)
    red = cv2.inRange(hsv, (0, 100, 60), (10, 255, 255)) | \
        cv2.inRange(hsv, (165, 100, 60), (180, 255, 255))
    contours, _ = cv2.findContours(red, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    region = np.zeros(red.shape, np.uint8)
    cv2.drawContours(region, [max(contours, key=cv2.contourArea)], -1, 1, -1)
    return region


def _template_face(key: str) -> np.ndarray:
    """Grey face of ``key``: its red region, white outside, cut to the region's box."""
    from workzone_ros.sim.signart import over, sign_face  # drawing code, loaded on use
    face = np.clip(over(sign_face(key, _ART_PX), 255.0), 0, 255).astype(np.uint8)
    region = _red_region(face)
    face[region == 0] = 255
    x, y, w, h = cv2.boundingRect(region)
    return cv2.cvtColor(face[y:y + h, x:x + w], cv2.COLOR_BGR2GRAY)


@lru_cache(maxsize=8)
def template_bank(template_px: int, scales: tuple[float, ...]) -> dict:
    """key -> list of grey templates (one per scale, ``scale * template_px`` square)."""
    bank = {}
    for key in RED_TEMPLATES:
        face = _template_face(key)
        sizes = sorted({max(8, int(round(s * template_px))) for s in scales})
        bank[key] = [cv2.resize(face, (n, n), interpolation=cv2.INTER_AREA) for n in sizes]
    return bank


def prepare_crop(bgr: np.ndarray, box: tuple[float, float, float, float],
                 region: np.ndarray, gains: np.ndarray, cfg: GeneralConfig) -> np.ndarray:
    """The candidate as the templates see it: the full-image ``box`` (x, y, w, h) scaled to
    a ``template_px`` square with a ``crop_margin`` of context, white-balanced by ``gains``,
    everything outside the blob's filled ``region`` (a mask of the box, any size) painted
    white; grey uint8."""
    H, W = bgr.shape[:2]
    n = cfg.template_px
    m = int(round(cfg.crop_margin * n))
    x, y, w, h = box
    mx, my = cfg.crop_margin * w, cfg.crop_margin * h
    x0, y0 = int(np.floor(max(0.0, x - mx))), int(np.floor(max(0.0, y - my)))
    x1, y1 = int(np.ceil(min(W, x + w + mx))), int(np.ceil(min(H, y + h + my)))
    sx, sy = n / w, n / h
    ox, oy = m - (x - x0) * sx, m - (y - y0) * sy      # crop origin in the canvas
    size = (max(1, int(round((x1 - x0) * sx))), max(1, int(round((y1 - y0) * sy))))
    patch = cv2.resize(bgr[y0:y1, x0:x1], size, interpolation=cv2.INTER_AREA)
    canvas = np.full((n + 2 * m, n + 2 * m, 3), 255, np.uint8)
    cx0, cy0 = int(round(ox)), int(round(oy))
    px0, py0 = max(0, -cx0), max(0, -cy0)
    cx0, cy0 = max(0, cx0), max(0, cy0)
    pw = min(size[0] - px0, canvas.shape[1] - cx0)
    ph = min(size[1] - py0, canvas.shape[0] - cy0)
    canvas[cy0:cy0 + ph, cx0:cx0 + pw] = patch[py0:py0 + ph, px0:px0 + pw]
    keep = np.zeros(canvas.shape[:2], np.uint8)
    keep[m:m + n, m:m + n] = cv2.resize(region, (n, n), interpolation=cv2.INTER_NEAREST)
    keep = cv2.dilate(keep, np.ones((3, 3), np.uint8))
    canvas = cv2.transform(canvas, np.diag(gains.astype(np.float32)))
    canvas[keep == 0] = 255
    return cv2.cvtColor(canvas, cv2.COLOR_BGR2GRAY)


def match_templates(crop: np.ndarray, cfg: GeneralConfig) -> Match:
    """Match every red template at every size against ``crop`` (:func:`prepare_crop`)."""
    bank = template_bank(cfg.template_px, tuple(cfg.scales))
    scores = {}
    for key, tpls in bank.items():
        best_frac, best_ncc = 0.0, -1.0
        for t in tpls:
            if t.shape[0] > crop.shape[0] or t.shape[1] > crop.shape[1]:
                continue
            r = cv2.matchTemplate(crop, t, cv2.TM_CCOEFF_NORMED)
            best_frac = max(best_frac, float(np.count_nonzero(r > cfg.corr_threshold)) / r.size)
            best_ncc = max(best_ncc, float(r.max()))
        scores[key] = (best_frac, best_ncc)
    if cfg.select_by == 'score':       # the paper's rule: the highest share of good positions
        key = max(scores, key=lambda k: scores[k])
    else:                              # the best correlation (docs/general_signs.md)
        key = max(scores, key=lambda k: (scores[k][1], scores[k][0]))
    return Match(key, scores[key][0], scores[key][1], scores)
