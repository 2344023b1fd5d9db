"""Recall-first sign candidates for the learned verification stage (``verify='cnn'``).

The paper's pipeline (:mod:`.detector`, ``verify='templates'``) asks the colour blob to be
the sign: one threshold, one shape test.  Small signs (16-40 px) fail that: a yellow diamond
merges with dry grass, a STOP's legend cuts its red in pieces, a speed limit panel's white
joins the sky, a guide sign joins the trees.  Here the colour masks only *propose* boxes,
generously, and a CNN (:mod:`workzone_ros.core.cnn_classifier`) decides sign or background:

* every colour is thresholded at several saturation levels (a sign and a background of
  its hue separate at some level: the sheeting is the most saturated);
* each mask is opened (the paper's erosion then dilation) and closed (pieces of one face
  cut by the legend joined); optionally (``edge_cut``) also cut along edges of the value
  channel (a face's border line separates it from a background of the same colour);
* a white mask is also opened with a horizontal line (the light post under a panel goes);
* white is also proposed where it is *locally* bright (brighter than the mean of its
  neighbourhood, unsaturated): the frame-wide white threshold follows the brightest
  pixels, so in rain or overcast a grey panel's background is white too and the panel
  merges with it, or the panel is tinted past the saturation cap in warm sun;
* yellow is also closed with a 7 px disc: a warning diamond's black arrow cuts its yellow
  diagonally into pieces that neither the 5x3 closing nor the stacked / side-by-side
  joins put back together;
* pieces of one face are joined: stacked one above the other (the test of
  :func:`colour.merge_stacked`) or side by side (a diamond cut by its arrow); red blobs
  also propose a box grown around them (the DO NOT ENTER disc on its white plate, a STOP
  seen with its white rim);
* boxes are kept when their size and aspect can be a sign's (full-image px), near
  duplicates are merged (non-maximum suppression), and at most ``max_candidates`` per frame
  are kept, ranked by a cheap score (colour share of the box and contrast inside it).

No ROS import (DESIGN.md, principle 1).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import cv2
import numpy as np

from workzone_ros.core.general import colour
from workzone_ros.core.general.config import GeneralConfig

__all__ = ['Candidate', 'propose', 'nms', 'ASPECT']

_K3 = np.ones((3, 3), np.uint8)
_K5 = np.ones((5, 5), np.uint8)        # white: a panel's legend lines
_K53 = np.ones((5, 3), np.uint8)       # 5 high: a legend line across a face
_KH = np.ones((1, 5), np.uint8)        # horizontal opening: a thin post under a panel
_KDISC = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))   # yellow: a diamond's arrow

#: Box aspect (w / h) a candidate of each colour may have.
ASPECT = {'red': (0.6, 1.6), 'yellow': (0.6, 1.6), 'white': (0.45, 1.2),
          'green': (0.2, 5.0)}


@dataclass(frozen=True)
class Candidate:
    """A proposed sign box in working px, the colour that proposed it, a cheap score (for
    the per-frame cap) and how it was made (``'<level>/<op>'``, for diagnostics)."""

    box: tuple[int, int, int, int]
    colour: str
    score: float
    source: str = ''


def _hue_lut(ranges) -> np.ndarray:
    lut = np.zeros(256, np.uint8)
    for lo, hi in ranges:
        lut[lo:hi + 1] = 255
    return lut


def _masks(work: colour.Working, cfg: GeneralConfig) -> dict[str, list[tuple, np.ndarray]]:
    """The colour masks, several levels each (uint8 0/255, working px): each colour's
    saturation where the hue is in its range and the value above the floor, thresholded at
    each saturation floor (the same pixels as :func:`colour.red_mask` etc. at that floor,
    with one hue look-up per colour instead of a 3-channel range test per level); white:
    the panels' white and the locally bright white (:func:`_local_white`)."""
    hsv = work.hsv
    sats = sorted(cfg.candidate_saturations)
    hue, sat, val = cv2.split(hsv)
    sat = cv2.bitwise_and(sat, cv2.threshold(val, cfg.min_value - 1, 255,
                                             cv2.THRESH_BINARY)[1])
    luts = {'red': [(0, cfg.red_hue_lo), (cfg.red_hue_hi, 180)],
            'yellow': [cfg.yellow_hue], 'green': [cfg.green_hue]}
    green_lo = max(sats[0], cfg.green_min_saturation)
    out: dict[str, list[tuple]] = {}
    for which, ranges in luts.items():
        s_c = cv2.bitwise_and(sat, cv2.LUT(hue, _hue_lut(ranges)))
        if which == 'green':
            # green sheeting is darker than the floor of red and yellow: its own value floor
            s_c = cv2.bitwise_and(cv2.extractChannel(hsv, 1), cv2.bitwise_and(
                cv2.LUT(hue, _hue_lut(ranges)),
                cv2.threshold(val, cfg.green_min_value - 1, 255, cv2.THRESH_BINARY)[1]))
            strict = cv2.bitwise_and(s_c, cv2.LUT(hue, _hue_lut([(cfg.green_strict_hue,
                                                                 cfg.green_hue[1])])))
        levels = []
        for v in sats:
            src = s_c if which != 'green' or v == sats[0] else strict
            floor = green_lo if which == 'green' and v == sats[0] else v
            levels.append((v, cv2.threshold(src, floor - 1, 255, cv2.THRESH_BINARY)[1]))
        out[which] = levels
    white = colour.white_mask(hsv, cfg)
    if np.abs(np.log(work.gains)).max() > 0.1:
        # a strong grey-world correction (half the frame dry grass) tints white panels;
        # white is also what is white in the camera's own balance
        raw = cv2.cvtColor(colour.balance(work.bgr, 1.0 / work.gains), cv2.COLOR_BGR2HSV)
        white = cv2.bitwise_or(white, colour.white_mask(raw, cfg))
    out['white'] = [(cfg.white_max_saturation, white), ('local', _local_white(hsv, cfg))]
    return out


def _local_white(hsv: np.ndarray, cfg: GeneralConfig) -> np.ndarray:
    """Unsaturated pixels (saturation <= ``local_white_saturation``) brighter by
    ``local_white_delta`` than the mean value of the ``local_white_block`` square around
    them: a panel against grey rain or a warm-lit panel, which the frame-wide white
    threshold of :func:`colour.white_mask` joins to its background or misses."""
    val = cv2.extractChannel(hsv, 2)
    k = cfg.local_white_block
    bright = cv2.compare(val, cv2.add(cv2.blur(val, (k, k)), cfg.local_white_delta),
                         cv2.CMP_GT)
    pale = cv2.threshold(cv2.extractChannel(hsv, 1), cfg.local_white_saturation, 255,
                         cv2.THRESH_BINARY_INV)[1]
    return cv2.bitwise_and(bright, pale)


def _components(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Boxes (x, y, w, h) of the outer outlines of ``mask`` (findContours is ~10x faster
    than connectedComponentsWithStats on these sparse masks)."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return [cv2.boundingRect(c) for c in contours]


def _sized(boxes: list, min_side: float, max_side: float) -> list:
    return [b for b in boxes if min(b[2], b[3]) >= min_side and max(b[2], b[3]) <= max_side]


def _groups(boxes: np.ndarray, pairs: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Union boxes of the groups (two or more boxes) that ``pairs`` join transitively."""
    parent = list(range(len(boxes)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i, j in pairs:
        parent[root(int(i))] = root(int(j))
    groups: dict[int, list[int]] = {}
    for i in range(len(boxes)):
        groups.setdefault(root(i), []).append(i)
    out = []
    for g in groups.values():
        if len(g) < 2:
            continue
        b = boxes[g]
        x0, y0 = b[:, 0].min(), b[:, 1].min()
        out.append((int(x0), int(y0), int((b[:, 0] + b[:, 2]).max() - x0),
                    int((b[:, 1] + b[:, 3]).max() - y0)))
    return out


def _joined(boxes: list, min_side: float, max_side: float) -> list:
    """Boxes of pieces of one face joined: stacked (a STOP or a speed limit panel cut by
    its legend lines, :func:`colour._stacked_pairs`) or side by side (a warning diamond
    cut by its arrow, a guide sign by its legend)."""
    b = np.array([x for x in boxes if min(x[2], x[3]) >= 2 and max(x[2], x[3]) >= 4
                  and max(x[2], x[3]) <= max_side], np.int64).reshape(-1, 4)
    if len(b) < 2 or len(b) > 300:
        return []
    out = _groups(b, colour._stacked_pairs(b))
    t = b[:, [1, 0, 3, 2]]                  # transposed: side by side is stacked
    out += [(y, x, h, w) for x, y, w, h in _groups(t, colour._stacked_pairs(t))]
    return _sized(out, min_side, max_side)


def nms(cands: list, thr: float) -> list:
    """Highest score first; drop one whose IoU with a kept one exceeds ``thr`` (anything
    with ``box`` and ``score``)."""
    if not cands:
        return []
    order = sorted(range(len(cands)), key=lambda i: -cands[i].score)
    b = np.array([cands[i].box for i in order], np.float64)
    x0, y0, x1, y1 = b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
    area = b[:, 2] * b[:, 3]
    alive = np.ones(len(b), bool)
    keep = []
    for i in range(len(b)):
        if not alive[i]:
            continue
        keep.append(order[i])
        iw = np.clip(np.minimum(x1[i], x1) - np.maximum(x0[i], x0), 0, None)
        ih = np.clip(np.minimum(y1[i], y1) - np.maximum(y0[i], y0), 0, None)
        inter = iw * ih
        alive &= ~(inter > thr * (area[i] + area - inter))
    return [cands[k] for k in keep]


def _score(work: colour.Working, loose: np.ndarray, grey: np.ndarray, box, which: str
           ) -> float:
    """Cheap sign-likeness: the share of the box in the loose colour mask near what a face
    fills (0.5 for a diamond or triangle, ~0.8 for a rectangle), times the contrast inside
    the box (a legend), times a size factor (larger is likelier)."""
    x, y, w, h = box
    share = float(np.count_nonzero(loose[y:y + h, x:x + w])) / float(w * h)
    want = 0.75 if which in ('white', 'green') else 0.65
    fit = max(0.0, 1.0 - abs(share - want) / 0.6)
    g = grey[y:y + h, x:x + w]
    contrast = min(1.0, float(g.std()) / 40.0)
    size = min(1.0, min(w, h) * work.scale / 40.0)
    return round(fit * (0.3 + 0.7 * contrast) * (0.5 + 0.5 * size), 4)


def _ops(which: str, mask: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The variants of one colour mask boxes are taken from: opened (the paper's erosion,
    dilation; first, the loose mask of :func:`_score`), closed (a legend line across a
    face), yellow also closed with a disc (a diamond cut diagonally by its arrow), white
    also opened with a horizontal line (the light grey post under a panel goes)."""
    opened = cv2.dilate(cv2.erode(mask, _K3), _K3)
    ops = [('open', opened), ('close', cv2.morphologyEx(opened, cv2.MORPH_CLOSE,
                                                        _K5 if which == 'white' else _K53))]
    if which == 'yellow':
        ops.append(('disc', cv2.morphologyEx(opened, cv2.MORPH_CLOSE, _KDISC)))
    if which == 'white':
        ops.append(('hopen', cv2.morphologyEx(opened, cv2.MORPH_OPEN, _KH)))
    return ops


def _colour_boxes(which: str, levels: list, cfg: GeneralConfig, not_edges, min_side: float,
                  max_side: float) -> tuple[dict[tuple, str], Optional[np.ndarray]]:
    """Boxes (working px) -> how they were made, of one colour's mask levels, and the
    colour's loose opened mask (None when every level is empty)."""
    loose = None
    boxes: dict[tuple, str] = {}
    for level, m in levels:
        if not cv2.countNonZero(m):
            continue
        ops = _ops(which, m)
        if loose is None:
            loose = ops[0][1]
        if not_edges is not None and which in cfg.edge_cut:
            # a face's border line cuts it from a background of its colour
            ops.append(('cut', cv2.dilate(cv2.erode(cv2.bitwise_and(m, not_edges), _K3),
                                          _K3)))
        # brighter than its neighbourhood means something on the block's scale: a larger
        # locally white region is a wall or a patch of sky
        top = min(max_side, cfg.local_white_block) if level == 'local' else max_side
        for op, mm in ops:
            found = _components(mm)
            comps = _sized(found, min_side, top)
            if op in ('close', 'disc') or which == 'white':
                comps += _joined(found, min_side, top)
            for c in comps:
                boxes.setdefault(tuple(c), f'{level}/{op}')
    return boxes, loose


def _scored(work: colour.Working, cfg: GeneralConfig, which: str, boxes: dict,
            loose: np.ndarray, grey: np.ndarray) -> list[Candidate]:
    """Candidates of one colour's boxes of a sign's aspect, with their cheap score; red
    boxes also grown (a disc on a white plate, a face with its white rim)."""
    H, W = grey.shape
    lo_a, hi_a = ASPECT[which]
    out = []
    for box, src in boxes.items():
        x, y, w, h = box
        if not lo_a <= w / h <= hi_a:
            continue
        if which == 'red':
            g = cfg.candidate_grow
            gx, gy = int(round(w * g / 2)), int(round(h * g / 2))
            gb = (max(0, x - gx), max(0, y - gy), min(W, x + w + gx) - max(0, x - gx),
                  min(H, y + h + gy) - max(0, y - gy))
            out.append(Candidate(gb, which, _score(work, loose, grey, gb, which) * 0.9,
                                 src + '/grown'))
        out.append(Candidate(box, which, _score(work, loose, grey, box, which), src))
    return out


def propose(work: colour.Working, cfg: GeneralConfig, rois=None,
            keep: Optional[Callable[[Candidate], bool]] = None) -> list[Candidate]:
    """Candidate boxes (working px) of red, yellow, white and green signs, at most
    ``cfg.max_candidates``, best cheap score first; with ``keep``, only candidates it
    accepts count towards (and fill) the cap (the verifier's cheap colour checks: a red
    brick wall's boxes must not use up the CNN batch before a small diamond's)."""
    s = work.scale
    min_side = cfg.candidate_min_px / s
    max_side = cfg.candidate_max_share * work.hsv.shape[0]
    grey = cv2.extractChannel(work.hsv, 2)          # value: contrast and edges
    not_edges = None
    if cfg.edge_cut:
        lo, hi = cfg.edge_thresholds
        not_edges = cv2.bitwise_not(cv2.dilate(cv2.Canny(grey, lo, hi), _K3))
    raw: list[Candidate] = []
    for which, levels in _masks(work, cfg).items():
        boxes, loose = _colour_boxes(which, levels, cfg, not_edges, min_side, max_side)
        if loose is not None:
            raw += _scored(work, cfg, which, boxes, loose, grey)
    if rois is not None:
        raw = [c for c in raw if _centre_in(c.box, s, rois)]
    out: list[Candidate] = []
    for c in nms(raw, cfg.candidate_nms):
        if len(out) == cfg.max_candidates:
            break
        if keep is None or keep(c):
            out.append(c)
    return out


def _centre_in(box, s: float, rois) -> bool:
    cx, cy = (box[0] + box[2] / 2) * s, (box[1] + box[3] / 2) * s
    return any(r[0] <= cx <= r[0] + r[2] and r[1] <= cy <= r[1] + r[3] for r in rois)
