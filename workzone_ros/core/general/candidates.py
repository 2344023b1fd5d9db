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
from typing import Callable, Iterator, Optional

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
#: Margin (px) around a mask's pixels its morphology is computed in: at least 2 r + 1 for
#: the largest kernel radius r (the 7 px disc: 3), see :func:`_crop`.
_PAD = 8

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
    hue, sat_all, val = cv2.split(hsv)
    sat = cv2.bitwise_and(sat_all, cv2.threshold(val, cfg.min_value - 1, 255,
                                                 cv2.THRESH_BINARY)[1])
    luts = {'red': [(0, cfg.red_hue_lo), (cfg.red_hue_hi, 180)],
            'yellow': [cfg.yellow_hue], 'green': [cfg.green_hue]}
    green_lo = max(sats[0], cfg.green_min_saturation)
    out: dict[str, list[tuple]] = {}
    for which, ranges in luts.items():
        in_hue = cv2.LUT(hue, _hue_lut(ranges))
        if which == 'green':
            # green sheeting is darker than the floor of red and yellow: its own value floor
            s_c = cv2.bitwise_and(sat_all, cv2.bitwise_and(
                in_hue, cv2.threshold(val, cfg.green_min_value - 1, 255, cv2.THRESH_BINARY)[1]))
            strict = cv2.bitwise_and(s_c, cv2.LUT(hue, _hue_lut([(cfg.green_strict_hue,
                                                                 cfg.green_hue[1])])))
        else:
            s_c = cv2.bitwise_and(sat, in_hue)
        levels = []
        for v in sats:
            src = s_c if which != 'green' or v == sats[0] else strict
            floor = green_lo if which == 'green' and v == sats[0] else v
            levels.append((v, cv2.threshold(src, floor - 1, 255, cv2.THRESH_BINARY)[1]))
        out[which] = levels
    white = colour.white_mask(hsv, cfg, value=val)
    if np.abs(np.log(work.gains)).max() > 0.1:
        # a strong grey-world correction (half the frame dry grass) tints white panels;
        # white is also what is white in the camera's own balance
        raw = cv2.cvtColor(colour.balance(work.bgr, 1.0 / work.gains), cv2.COLOR_BGR2HSV)
        white = cv2.bitwise_or(white, colour.white_mask(raw, cfg))
    out['white'] = [(cfg.white_max_saturation, white),
                    ('local', _local_white(hsv, cfg, val, sat_all))]
    return out


def _local_white(hsv: np.ndarray, cfg: GeneralConfig, val: Optional[np.ndarray] = None,
                 sat: Optional[np.ndarray] = None) -> np.ndarray:
    """Unsaturated pixels (saturation <= ``local_white_saturation``) brighter by
    ``local_white_delta`` than the mean value of the ``local_white_block`` square around
    them: a panel against grey rain or a warm-lit panel, which the frame-wide white
    threshold of :func:`colour.white_mask` joins to its background or misses.  ``val`` and
    ``sat``: the value and saturation channels of ``hsv`` when they are at hand."""
    val = cv2.extractChannel(hsv, 2) if val is None else val
    sat = cv2.extractChannel(hsv, 1) if sat is None else sat
    k = cfg.local_white_block
    bright = cv2.compare(val, cv2.add(cv2.blur(val, (k, k)), cfg.local_white_delta),
                         cv2.CMP_GT)
    pale = cv2.threshold(sat, cfg.local_white_saturation, 255, cv2.THRESH_BINARY_INV)[1]
    return cv2.bitwise_and(bright, pale)


def _components(mask: np.ndarray, offset: tuple[int, int] = (0, 0)
                ) -> list[tuple[int, int, int, int]]:
    """Boxes (x, y, w, h) of the outer outlines of ``mask``, moved by ``offset`` (the
    mask's place in the frame; findContours is ~10x faster than
    connectedComponentsWithStats on these sparse masks)."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE,
                                   offset=offset)
    return [cv2.boundingRect(c) for c in contours]


def _sized(boxes: list, min_side: float, max_side: float) -> list:
    return [b for b in boxes if min(b[2], b[3]) >= min_side and max(b[2], b[3]) <= max_side]


def _groups(boxes: list, pairs: list) -> list[tuple[int, int, int, int]]:
    """Union boxes of the groups (two or more of ``boxes``) that the index ``pairs`` (i < j)
    join transitively, in the order of each group's first box."""
    if not pairs:
        return []
    parent = list(range(len(boxes)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i, j in pairs:
        parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in sorted({k for pair in pairs for k in pair}):
        groups.setdefault(root(i), []).append(i)
    out = []
    for g in groups.values():
        b = [boxes[i] for i in g]
        x0, y0 = min(v[0] for v in b), min(v[1] for v in b)
        out.append((x0, y0, max(v[0] + v[2] for v in b) - x0, max(v[1] + v[3] for v in b) - y0))
    return out


def _join_pairs(b: np.ndarray) -> tuple[list, list]:
    """Index pairs of boxes (N, 4) stacked one above the other (the test of
    :func:`colour._stacked_pairs`) and side by side (the same test transposed), computed
    on the shared overlaps (the gap between two boxes is minus their overlap) of the pairs
    near enough for either (each gap at most half the first box's side plus 2)."""
    x0, y0, w, h = (b[:, k] for k in range(4))
    ox = np.minimum.outer(x0 + w, x0 + w) - np.maximum.outer(x0, x0)
    oy = np.minimum.outer(y0 + h, y0 + h) - np.maximum.outer(y0, y0)
    near = (2 * ox >= -(w[:, None] + 4)) & (2 * oy >= -(h[:, None] + 4))
    i, j = np.nonzero(np.triu(near, 1))
    if not len(i):
        return [], []
    ox, oy = ox[i, j], oy[i, j]
    wi, wj, hi, hj = w[i], w[j], h[i], h[j]
    stacked = colour.stacked_test(ox, -oy, wi, wj, hi, hj)
    side = colour.stacked_test(oy, -ox, hi, hj, wi, wj)
    i, j = i.tolist(), j.tolist()
    return ([(i[k], j[k]) for k in np.flatnonzero(stacked).tolist()],
            [(i[k], j[k]) for k in np.flatnonzero(side).tolist()])


def _joined(boxes: list, min_side: float, max_side: float) -> list:
    """Boxes of pieces of one face joined: stacked (a STOP or a speed limit panel cut by
    its legend lines, :func:`colour._stacked_pairs`) or side by side (a warning diamond
    cut by its arrow, a guide sign by its legend)."""
    if len(boxes) < 2:
        return []
    a = np.array(boxes, np.int32)
    lo, hi = np.minimum(a[:, 2], a[:, 3]), np.maximum(a[:, 2], a[:, 3])
    b = a[(lo >= 2) & (hi >= 4) & (hi <= max_side)]
    if len(b) < 2 or len(b) > 300:
        return []
    stacked, side = _join_pairs(b)
    boxes = b.tolist()
    return _sized(_groups(boxes, stacked) + _groups(boxes, side), min_side, max_side)


def nms(cands: list, thr: float) -> list:
    """Highest score first; drop one whose IoU with a kept one exceeds ``thr`` (anything
    with ``box`` and ``score``)."""
    return list(_nms_iter(cands, thr))


def _nms_iter(cands: list, thr: float) -> Iterator:
    """:func:`nms`, one kept candidate at a time (a caller that needs only the first few
    stops early)."""
    if not cands:
        return
    order = sorted(range(len(cands)), key=lambda i: -cands[i].score)
    b = np.array([cands[i].box for i in order], np.float64)
    x0, y0, x1, y1 = b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
    area = b[:, 2] * b[:, 3]
    alive = np.ones(len(b), bool)
    for i in range(len(b)):
        if not alive[i]:
            continue
        yield cands[order[i]]
        iw = np.clip(np.minimum(x1[i], x1) - np.maximum(x0[i], x0), 0, None)
        ih = np.clip(np.minimum(y1[i], y1) - np.maximum(y0[i], y0), 0, None)
        inter = iw * ih
        alive &= ~(inter > thr * (area[i] + area - inter))


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


def _crop(m: np.ndarray) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the box of ``m``'s non-zero pixels padded by ``_PAD`` (within
    the frame).  The morphology and outlines of :func:`_colour_boxes` come out the same on
    it as on the whole frame: every kernel's reach (radius r <= 3, twice in a closing)
    stays inside the padding, and beyond it everything is zero."""
    x, y, w, h = cv2.boundingRect(m)
    H, W = m.shape
    return max(0, x - _PAD), max(0, y - _PAD), min(W, x + w + _PAD), min(H, y + h + _PAD)


def _paste(part: np.ndarray, shape: tuple, x0: int, y0: int) -> np.ndarray:
    out = np.zeros(shape, part.dtype)
    out[y0:y0 + part.shape[0], x0:x0 + part.shape[1]] = part
    return out


def _colour_boxes(which: str, levels: list, cfg: GeneralConfig, not_edges, min_side: float,
                  max_side: float) -> tuple[dict[tuple, str], Optional[np.ndarray]]:
    """Boxes (working px) -> how they were made, of one colour's mask levels, and the
    colour's loose opened mask (None when every level is empty).  Each level is worked
    on the part of the frame its pixels lie in (:func:`_crop`)."""
    loose = None
    boxes: dict[tuple, str] = {}
    for level, m in levels:
        if not cv2.countNonZero(m):
            continue
        x0, y0, x1, y1 = _crop(m)
        part = m[y0:y1, x0:x1]
        ops = _ops(which, part)
        if loose is None:
            loose = _paste(ops[0][1], m.shape, x0, y0)
        if not_edges is not None and which in cfg.edge_cut:
            # a face's border line cuts it from a background of its colour
            cut = cv2.bitwise_and(part, not_edges[y0:y1, x0:x1])
            ops.append(('cut', cv2.dilate(cv2.erode(cut, _K3), _K3)))
        # brighter than its neighbourhood means something on the block's scale: a larger
        # locally white region is a wall or a patch of sky
        top = min(max_side, cfg.local_white_block) if level == 'local' else max_side
        for op, mm in ops:
            found = _components(mm, (x0, y0))
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
    for c in _nms_iter(raw, cfg.candidate_nms):
        if len(out) == cfg.max_candidates:
            break
        if keep is None or keep(c):
            out.append(c)
    return out


def _centre_in(box, s: float, rois) -> bool:
    cx, cy = (box[0] + box[2] / 2) * s, (box[1] + box[3] / 2) * s
    return any(r[0] <= cx <= r[0] + r[2] and r[1] <= cy <= r[1] + r[3] for r in rois)
