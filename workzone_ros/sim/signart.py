"""Procedural sign art for the synthetic camera: no downloaded images.

Every catalogue class (core/signs.py) is drawn with OpenCV primitives into a BGRA image of the
face's bounding rectangle; alpha is 0 outside the shape (diamond, octagon, triangle,
rectangle, square).  Legends and symbols are exaggerated (thick strokes, few large words) so a
person can tell every class apart at 64 px, and mirrored variants (``*_left`` / ``*_right``)
are exact mirror images of each other.  Faces are drawn 4x supersampled and cached per
(key, size, speed value, variant, sheeting colour): they are static.

Orange sheeting varies per sign (:func:`sheeting_orange`): real work-zone signs are more
yellow- or red-orange, paler and darker (weathered, faded) than the MUTCD colour, so each sign
gets its own orange drawn from (sign id, salt), with the legend, border and layout unchanged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from workzone_ros.core import signs

__all__ = [
    'ORANGE', 'YELLOW', 'RED', 'GREEN', 'WHITE', 'BLACK', 'OTHER_VARIANTS', 'WARNING_VARIANTS',
    'VARIANTS', 'MIRROR_PAIRS',
    'face_aspect', 'face_size', 'sign_face', 'outline', 'drum_texture', 'ORANGE_HSV',
    'ORANGE_VARIATION', 'sheeting_orange', 'uses_orange', 'over',
]

# Sheeting colours (BGR).  MUTCD fluorescent orange, yellow, red, green, white, black.
ORANGE = (0, 110, 245)
YELLOW = (10, 205, 250)
RED = (40, 35, 195)
GREEN = (60, 110, 0)
WHITE = (238, 240, 240)
BLACK = (22, 22, 22)
#: ORANGE in OpenCV HSV (H 0-180): (13, 255, 245).
ORANGE_HSV = tuple(int(v) for v in cv2.cvtColor(np.uint8([[ORANGE]]), cv2.COLOR_BGR2HSV)[0, 0])
#: Per-sign orange variation: hue offset (+-, OpenCV units), saturation and value scales.
#: Real clips (charlotte, denver) measure H 12-16, S 200-225 on the orange of the diamonds.
ORANGE_VARIATION = {'hue': 4, 'saturation': (0.70, 1.0), 'value': (0.80, 1.03)}

#: Variants of ``other_workzone`` (W20-7 flagger, W20-4 one lane road, W21-5 shoulder work).
OTHER_VARIANTS = ('flagger', 'one_lane', 'shoulder_work')
#: Symbols of the yellow ``warning_diamond`` (W1-2 curve, W3-1 stop ahead: a red octagon,
#: W3-3 signal ahead: red, yellow and green lamps, W2-1 cross road).
WARNING_VARIANTS = ('curve', 'stop_ahead', 'signal_ahead', 'cross_road')
#: The classes drawn in several variants; the first is the default.
VARIANTS = {'other_workzone': OTHER_VARIANTS, 'warning_diamond': WARNING_VARIANTS}
#: Class pairs whose faces are mirror images (left, right).
MIRROR_PAIRS = (('lane_shift_left', 'lane_shift_right'), ('left_lane_ends', 'right_lane_ends'))

_SS = 4   # supersampling factor
#: A diamond's black border line: its middle this share of the side in from the outline,
#: half its width (normal to the edge) this share of the side.
_BORDER_INSET = 0.035
_BORDER_HALF_WIDTH = 0.015
_FONT = cv2.FONT_HERSHEY_DUPLEX
_FONT_BOLD = cv2.FONT_HERSHEY_TRIPLEX


def uses_orange(class_key: str) -> bool:
    """True for classes drawn with orange sheeting (the orange work-zone faces)."""
    return class_key != 'background' and 'orange' in signs.get(class_key).colors


def sheeting_orange(sign_id: int, salt: int = 0) -> tuple[int, int, int]:
    """The orange (BGR) of one sign's sheeting: hue, saturation and value jittered.

    Hue moves by an integer in [-4, 4] OpenCV units around :data:`ORANGE_HSV` (towards
    yellow-orange or red-orange), saturation is scaled by 0.70-1.0 and value by 0.80-1.03
    (faded and weathered sheeting), all drawn from ``(sign_id, salt)`` so a sign keeps its
    colour in every frame and run.  Quantised (hue integer, saturation and value in steps of
    8) so the face cache stays small.

    Args:
        sign_id: the sign's object id.
        salt: e.g. the scene seed, so the same id differs between random scenarios.

    Returns:
        A BGR tuple of ints.
    """
    rng = np.random.default_rng([abs(int(salt)), abs(int(sign_id)), 0x0a4e])
    v = ORANGE_VARIATION
    dh = int(rng.integers(-v['hue'], v['hue'] + 1))
    sat = ORANGE_HSV[1] * float(rng.uniform(*v['saturation']))
    val = ORANGE_HSV[2] * float(rng.uniform(*v['value']))
    hsv = np.uint8([[[ORANGE_HSV[0] + dh, min(255, 8 * round(sat / 8)),
                      min(255, 8 * round(val / 8))]]])
    return tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])


def face_aspect(class_key: str) -> float:
    """Width / height of the face's bounding rectangle for ``class_key``."""
    c = signs.get(class_key)
    if c.shape == 'diamond' or c.width_m <= 0:
        return 1.0
    return c.width_m / c.height_m


def face_size(class_key: str, size_px: int) -> tuple[int, int]:
    """(width, height) in pixels of the art for ``class_key``: the longer side is ``size_px``."""
    a = face_aspect(class_key)
    if a >= 1.0:
        return int(size_px), max(2, int(round(size_px / a)))
    return max(2, int(round(size_px * a))), int(size_px)


def outline(shape: str, w: float, h: float) -> np.ndarray:
    """Outline polygon (N, 2) of ``shape`` inside a ``w`` x ``h`` rectangle (pixel units).

    Args:
        shape: catalogue shape (``diamond``, ``octagon``, ``triangle``, ``rectangle``,
            ``square``).
        w: rectangle width.
        h: rectangle height.

    Returns:
        Float polygon vertices in drawing order.
    """
    if shape == 'diamond':
        return np.array([[w / 2, 0], [w, h / 2], [w / 2, h], [0, h / 2]], float)
    if shape == 'octagon':
        a, b = w * (1 - 1 / np.sqrt(2)) / 2, h * (1 - 1 / np.sqrt(2)) / 2
        return np.array([[a, 0], [w - a, 0], [w, b], [w, h - b], [w - a, h], [a, h],
                         [0, h - b], [0, b]], float)
    if shape == 'triangle':       # inverted (yield)
        return np.array([[0, 0], [w, 0], [w / 2, h]], float)
    return np.array([[0, 0], [w, 0], [w, h], [0, h]], float)


def _poly(img: np.ndarray, pts, color, thickness: int = -1) -> None:
    p = np.round(np.asarray(pts, float) * 16).astype(np.int32)
    if thickness < 0:
        cv2.fillPoly(img, [p], color, cv2.LINE_AA, shift=4)
    else:
        cv2.polylines(img, [p], True, color, thickness, cv2.LINE_AA, shift=4)


def _inset(poly: np.ndarray, frac: float, w: float, h: float) -> np.ndarray:
    """Shrink ``poly`` towards the rectangle centre by ``frac`` of the smaller side."""
    c = np.array([w / 2, h / 2])
    m = min(w, h)
    scale = np.array([(w - 2 * frac * m) / w, (h - 2 * frac * m) / h])
    return c + (poly - c) * scale


def _text(img: np.ndarray, text: str, center: tuple[float, float], box: tuple[float, float],
          color, weight: float = 0.16, font: int = _FONT) -> None:
    """Draw ``text`` centred at ``center``, as large as fits ``box`` (w, h), thick strokes.

    ``weight`` is the stroke thickness as a fraction of the text height.
    """
    bw, bh = box
    (tw, th), _ = cv2.getTextSize(text, font, 1.0, 1)
    scale = min(bw / tw, bh / th)
    thick = max(1, int(round(weight * th * scale)))
    (tw, th), _ = cv2.getTextSize(text, font, scale, thick)
    scale *= min(bw / tw, bh / th, 1.0)
    (tw, th), _ = cv2.getTextSize(text, font, scale, thick)
    org = (int(round(center[0] - tw / 2)), int(round(center[1] + th / 2)))
    cv2.putText(img, text, org, font, scale, color, thick, cv2.LINE_AA)


def _lines(img, lines, cx, top, bottom, widths, color, weight=0.17, font=_FONT,
           heights=None) -> None:
    """Stack text lines between ``top`` and ``bottom`` (relative heights optional)."""
    n = len(lines)
    heights = heights or [1.0] * n
    total = float(sum(heights))
    gap = 0.22
    unit = (bottom - top) / (total + gap * (n - 1))
    y = top
    for text, w, hh in zip(lines, widths, heights):
        _text(img, text, (cx, y + unit * hh / 2), (w, unit * hh), color, weight, font)
        y += unit * (hh + gap)


def _arrow_path(img, pts, color, stroke: float, head: float) -> None:
    """Thick poly-line along ``pts`` (N, 2) ending in a filled arrow head."""
    pts = np.asarray(pts, float)
    d = pts[-1] - pts[-2]
    d /= np.linalg.norm(d)
    n = np.array([-d[1], d[0]])
    base = pts[-1] - d * head * 0.9
    body = np.vstack([pts[:-1], base])
    p = np.round(body * 16).astype(np.int32)
    cv2.polylines(img, [p], False, color, int(stroke), cv2.LINE_AA, shift=4)
    tip = pts[-1]
    _poly(img, [tip, base + n * head * 0.75, base - n * head * 0.75], color)


def _smooth_shift(x0: float, x1: float, y0: float, y1: float, n: int = 24) -> np.ndarray:
    """Cosine S-curve from (x0, y0) to (x1, y1) (y decreasing upwards in the image)."""
    u = np.linspace(0.0, 1.0, n)
    x = x0 + (x1 - x0) * (1 - np.cos(np.pi * u)) / 2
    y = y0 + (y1 - y0) * u
    return np.column_stack([x, y])


# ------------------------------------------------------------------ symbols (unit = size S)
def _sym_reverse_curve(img, S: float, direction: int, color) -> None:
    """W1-4L/R: an arrow that shifts one lane to the left (-1) or right (+1)."""
    st = 0.085 * S
    x0, x1 = 0.5 - 0.13 * direction, 0.5 + 0.13 * direction
    pts = np.vstack([[[x0, 0.80]], _smooth_shift(x0, x1, 0.64, 0.36), [[x1, 0.20]]]) * S
    _arrow_path(img, pts, color, st, 0.13 * S)


def _sym_double_reverse(img, S: float, color) -> None:
    """W1-4 (lane shift, direction unknown): an arrow that shifts out and back (zig-zag)."""
    st = 0.075 * S
    a = np.vstack([[[0.44, 0.82]], _smooth_shift(0.44, 0.60, 0.72, 0.52, 14),
                   _smooth_shift(0.60, 0.44, 0.50, 0.32, 14), [[0.44, 0.18]]])
    _arrow_path(img, a * S, color, st, 0.12 * S)
    # Second, parallel curve line (two lanes shifting together) to set it apart from L/R.
    b = np.vstack([[[0.30, 0.80]], _smooth_shift(0.30, 0.46, 0.72, 0.52, 14),
                   _smooth_shift(0.46, 0.30, 0.50, 0.32, 14), [[0.30, 0.22]]]) * S
    b[:, 0] += 0.28 * S
    cv2.polylines(img, [np.round(b * 16).astype(np.int32)], False, color, int(0.05 * S),
                  cv2.LINE_AA, shift=4)


def _sym_lane_ends(img, S: float, side: int, color) -> None:
    """W4-2L (side=-1: left lane ends, merge right) / W4-2R (side=+1), mirror images."""
    st = 0.075 * S

    def mx(x: float) -> float:
        return x if side < 0 else 1.0 - x

    straight = np.array([[mx(0.64), 0.80], [mx(0.64), 0.20]]) * S
    ending = np.array([[mx(0.30), 0.80], [mx(0.30), 0.56], [mx(0.52), 0.34],
                       [mx(0.52), 0.20]]) * S
    for line in (straight, ending):
        cv2.polylines(img, [np.round(line * 16).astype(np.int32)], False, color, int(st),
                      cv2.LINE_AA, shift=4)
    # Broken lane line between the two lanes, ending where the lane ends.
    for y0, y1 in ((0.80, 0.71), (0.65, 0.56)):
        seg = np.array([[mx(0.47), y0], [mx(0.47), y1]]) * S
        cv2.polylines(img, [np.round(seg * 16).astype(np.int32)], False, color,
                      int(0.05 * S), cv2.LINE_AA, shift=4)


def _sym_curve(img, S: float, color) -> None:
    """W1-2 curve to the right (yellow general warning)."""
    u = np.linspace(0, 1, 20)
    x = 0.40 + 0.18 * (1 - np.cos(u * np.pi / 2))
    y = 0.80 - 0.50 * np.sin(u * np.pi / 2)
    pts = np.column_stack([x, y])
    pts = np.vstack([pts, [[0.62, 0.24]]]) * S
    _arrow_path(img, pts, color, 0.09 * S, 0.14 * S)


def _sym_warning(f: '_Face') -> None:
    """The yellow warning diamond's symbol in its variant (:data:`WARNING_VARIANTS`)."""
    img, S = f.img, f.S
    if f.variant == 'stop_ahead':              # W3-1: an octagon, an arrow up to it
        t = np.arange(8) * np.pi / 4 + np.pi / 8
        ring = np.column_stack([np.cos(t), np.sin(t)])
        _poly(img, (np.array([0.5, 0.40]) + 0.19 * ring) * S, WHITE)
        _poly(img, (np.array([0.5, 0.40]) + 0.165 * ring) * S, RED)
        _arrow_path(img, np.array([[0.5, 0.84], [0.5, 0.62]]) * S, BLACK, 0.07 * S, 0.11 * S)
    elif f.variant == 'signal_ahead':          # W3-3: a signal head, three lamps
        _poly(img, np.array([[0.40, 0.20], [0.60, 0.20], [0.60, 0.80], [0.40, 0.80]]) * S,
              BLACK)
        for y, lamp in ((0.31, RED), (0.50, (0, 190, 245)), (0.69, (90, 170, 0))):
            cv2.circle(img, (int(0.5 * S * 16), int(y * S * 16)), int(0.065 * S * 16), lamp,
                       -1, cv2.LINE_AA, shift=4)
    elif f.variant == 'cross_road':            # W2-1: a cross
        for a, b in (([0.44, 0.20], [0.56, 0.80]), ([0.20, 0.44], [0.80, 0.56])):
            _poly(img, np.array([a, [b[0], a[1]], b, [a[0], b[1]]]) * S, BLACK)
    else:                                      # W1-2: a curve
        _sym_curve(img, S, BLACK)


def _sym_flagger(img, S: float, color) -> None:
    """W20-7 flagger symbol: a person holding a flag on a staff (thick strokes)."""
    def L(p, q, t):
        cv2.line(img, tuple(int(v * S * 16) for v in p), tuple(int(v * S * 16) for v in q),
                 color, max(1, int(t * S)), cv2.LINE_AA, shift=4)
    cv2.circle(img, (int(0.46 * S * 16), int(0.27 * S * 16)), int(0.055 * S * 16), color, -1,
               cv2.LINE_AA, shift=4)
    L((0.46, 0.36), (0.46, 0.58), 0.09)          # body
    L((0.46, 0.58), (0.38, 0.80), 0.07)          # legs
    L((0.46, 0.58), (0.54, 0.80), 0.07)
    L((0.46, 0.40), (0.64, 0.48), 0.055)         # arm to the staff
    L((0.64, 0.30), (0.64, 0.74), 0.03)          # staff
    _poly(img, np.array([[0.64, 0.30], [0.78, 0.34], [0.64, 0.42]]) * S, color)   # flag


# ------------------------------------------------------------------ faces
@dataclass(frozen=True)
class _Face:
    """One face being drawn: the class, its supersampled canvas (W x H, one pixel more each
    way, see :func:`_draw`), outline polygon and drawing parameters."""
    key: str
    W: int
    H: int
    speed: int
    variant: str
    orange: tuple[int, int, int]
    img: np.ndarray
    poly: np.ndarray

    @property
    def S(self) -> float:
        """The smaller side: the unit of the symbols."""
        return float(min(self.W, self.H))

    @property
    def cx(self) -> float:
        """The horizontal centre."""
        return self.W / 2


# --- diamonds (orange work-zone warnings, the yellow general warning)
def _paint_diamond(f: _Face) -> None:
    """Diamond sheeting, its black border line, then the class's legend or symbol."""
    bg = YELLOW if f.key == 'warning_diamond' else f.orange
    _poly(f.img, f.poly, bg)
    # the border line (its middle at 0.035 of the side in from the outline, 0.03 of the
    # side wide) as the face's margin and face filled over black: exact to the
    # catalogue (a thick anti-aliased polyline, its width a whole number of pixels,
    # came out 9-25 % wider and its face that much smaller)
    half = _BORDER_HALF_WIDTH * math.sqrt(2.0)     # across a 45 deg edge, per side
    _poly(f.img, _inset(f.poly, _BORDER_INSET - half, f.W, f.H), BLACK)
    _poly(f.img, _inset(f.poly, _BORDER_INSET + half, f.W, f.H), bg)
    legend = _DIAMOND_LEGENDS.get(f.key)
    if legend is not None:
        legend(f)


def _legend_road_work_ahead(f: _Face) -> None:
    """W20-1 ROAD WORK AHEAD."""
    W, H = f.W, f.H
    _lines(f.img, ['ROAD', 'WORK', 'AHEAD'], f.cx, 0.28 * H, 0.72 * H,
           [0.40 * W, 0.54 * W, 0.42 * W], BLACK, 0.2, _FONT_BOLD)


def _legend_lane_closed_ahead(f: _Face) -> None:
    """W20-5L/R LEFT / RIGHT LANE CLOSED AHEAD (the side word largest)."""
    W, H = f.W, f.H
    first = 'LEFT' if f.key.startswith('left') else 'RIGHT'
    _lines(f.img, [first, 'LANE', 'CLOSED', 'AHEAD'], f.cx, 0.20 * H, 0.78 * H,
           [0.40 * W, 0.50 * W, 0.56 * W, 0.34 * W], BLACK, 0.2, _FONT_BOLD,
           heights=[1.9, 1.0, 1.0, 0.9])


def _legend_other_workzone(f: _Face) -> None:
    """``other_workzone`` in its variant: ONE LANE ROAD AHEAD, SHOULDER WORK or flagger."""
    W, H = f.W, f.H
    if f.variant == 'one_lane':
        _lines(f.img, ['ONE', 'LANE', 'ROAD', 'AHEAD'], f.cx, 0.22 * H, 0.78 * H,
               [0.30 * W, 0.46 * W, 0.46 * W, 0.34 * W], BLACK, 0.2, _FONT_BOLD)
    elif f.variant == 'shoulder_work':
        _lines(f.img, ['SHOULDER', 'WORK'], f.cx, 0.36 * H, 0.64 * H,
               [0.66 * W, 0.46 * W], BLACK, 0.2, _FONT_BOLD)
    else:
        _sym_flagger(f.img, f.S, BLACK)


#: Legend or symbol of each diamond class, drawn over the sheeting and border.
_DIAMOND_LEGENDS = {
    'road_work_ahead': _legend_road_work_ahead,
    'left_lane_closed_ahead': _legend_lane_closed_ahead,
    'right_lane_closed_ahead': _legend_lane_closed_ahead,
    'lane_shift_left': lambda f: _sym_reverse_curve(f.img, f.S, -1, BLACK),
    'lane_shift_right': lambda f: _sym_reverse_curve(f.img, f.S, +1, BLACK),
    'lane_shift': lambda f: _sym_double_reverse(f.img, f.S, BLACK),
    'left_lane_ends': lambda f: _sym_lane_ends(f.img, f.S, -1, BLACK),
    'right_lane_ends': lambda f: _sym_lane_ends(f.img, f.S, +1, BLACK),
    'warning_diamond': _sym_warning,
    'other_workzone': _legend_other_workzone,
}


# --- red regulatory faces
def _paint_stop(f: _Face) -> None:
    """R1-1 octagon: white rim, red face, STOP."""
    W, H = f.W, f.H
    _poly(f.img, f.poly, WHITE)
    _poly(f.img, _inset(f.poly, 0.045, W, H), RED)
    _text(f.img, 'STOP', (f.cx, H / 2), (0.80 * W, 0.36 * H), WHITE, 0.2, _FONT_BOLD)


def _paint_yield(f: _Face) -> None:
    """R1-2 inverted triangle: red rim, white centre, YIELD."""
    W, H = f.W, f.H
    _poly(f.img, f.poly, RED)
    inner = np.array([[0.25 * W, 0.13 * H], [0.75 * W, 0.13 * H], [0.5 * W, 0.70 * H]])
    _poly(f.img, inner, WHITE)
    _text(f.img, 'YIELD', (f.cx, 0.29 * H), (0.34 * W, 0.13 * H), RED, 0.2, _FONT_BOLD)


def _paint_do_not_enter(f: _Face) -> None:
    """R5-1 square: red disc with a white bar, DO NOT / ENTER."""
    img, H, S, cx = f.img, f.H, f.S, f.cx
    _poly(img, f.poly, WHITE)
    r = 0.44 * S
    cv2.circle(img, (int(cx * 16), int(H / 2 * 16)), int(r * 16), RED, -1, cv2.LINE_AA,
               shift=4)
    cv2.rectangle(img, (int(cx - 0.34 * S), int(H / 2 - 0.075 * S)),
                  (int(cx + 0.34 * S), int(H / 2 + 0.075 * S)), WHITE, -1, cv2.LINE_AA)
    _text(img, 'DO NOT', (cx, H / 2 - 0.22 * S), (0.44 * S, 0.11 * S), WHITE, 0.2)
    _text(img, 'ENTER', (cx, H / 2 + 0.22 * S), (0.40 * S, 0.11 * S), WHITE, 0.2)


# --- rectangular work-zone and speed faces
def _paint_work_zone_begin(f: _Face) -> None:
    """WORK ZONE on an orange top third, BEGINS on white below."""
    img, W, H, S, cx = f.img, f.W, f.H, f.S, f.cx
    _poly(img, f.poly, WHITE)
    cv2.rectangle(img, (0, 0), (W, int(H / 3)), f.orange, -1)
    b = max(2, int(0.03 * S))
    cv2.rectangle(img, (b, b), (W - b, H - b), BLACK, b, cv2.LINE_AA)
    cv2.line(img, (0, int(H / 3)), (W, int(H / 3)), BLACK, b)
    _lines(img, ['WORK', 'ZONE'], cx, 0.05 * H, 0.29 * H, [0.6 * W, 0.6 * W], BLACK,
           0.2, _FONT_BOLD)
    _text(img, 'BEGINS', (cx, 0.66 * H), (0.84 * W, 0.26 * H), BLACK, 0.2, _FONT_BOLD)


def _paint_work_zone_speed_limit(f: _Face) -> None:
    """WORK ZONE on an orange top quarter over a SPEED LIMIT face with the speed."""
    img, W, H, S, cx = f.img, f.W, f.H, f.S, f.cx
    _poly(img, f.poly, WHITE)
    top = int(0.25 * H)
    cv2.rectangle(img, (0, 0), (W, top), f.orange, -1)
    b = max(2, int(0.03 * S))
    cv2.rectangle(img, (b, b), (W - b, top - b), BLACK, b, cv2.LINE_AA)
    cv2.rectangle(img, (b, top + b), (W - b, H - b), BLACK, b, cv2.LINE_AA)
    _lines(img, ['WORK', 'ZONE'], cx, 0.035 * H, 0.215 * H, [0.6 * W, 0.6 * W], BLACK,
           0.2, _FONT_BOLD)
    _lines(img, ['SPEED', 'LIMIT'], cx, 0.31 * H, 0.53 * H, [0.74 * W, 0.66 * W], BLACK,
           0.18)
    _text(img, str(f.speed), (cx, 0.75 * H), (0.80 * W, 0.30 * H), BLACK, 0.17, _FONT)


def _paint_end_road_work(f: _Face) -> None:
    """G20-2 END ROAD WORK: black legend and border on orange."""
    img, W, H, S = f.img, f.W, f.H, f.S
    _poly(img, f.poly, f.orange)
    b = max(2, int(0.035 * S))
    cv2.rectangle(img, (b, b), (W - b, H - b), BLACK, b, cv2.LINE_AA)
    _lines(img, ['END', 'ROAD WORK'], f.cx, 0.17 * H, 0.83 * H, [0.36 * W, 0.84 * W],
           BLACK, 0.2, _FONT_BOLD)


def _paint_speed_limit(f: _Face) -> None:
    """R2-1 SPEED LIMIT and the speed, black on white."""
    img, W, H, S, cx = f.img, f.W, f.H, f.S, f.cx
    _poly(img, f.poly, WHITE)
    b = max(2, int(0.03 * S))
    cv2.rectangle(img, (2 * b, 2 * b), (W - 2 * b, H - 2 * b), BLACK, b,
                  cv2.LINE_AA)
    _lines(img, ['SPEED', 'LIMIT'], cx, 0.12 * H, 0.42 * H, [0.76 * W, 0.70 * W], BLACK,
           0.18)
    _text(img, str(f.speed), (cx, 0.68 * H), (0.76 * W, 0.36 * H), BLACK, 0.17, _FONT)


# --- green guide faces
def _paint_guide(f: _Face) -> None:
    """Green guide sign: EXIT 12 / HARRISBURG over an up arrow, white on green."""
    img, W, H, S = f.img, f.W, f.H, f.S
    _poly(img, f.poly, GREEN)
    b = max(2, int(0.035 * S))
    cv2.rectangle(img, (2 * b, 2 * b), (W - 2 * b, H - 2 * b), WHITE, b,
                  cv2.LINE_AA)
    _lines(img, ['EXIT 12', 'HARRISBURG'], f.cx, 0.2 * H, 0.62 * H, [0.40 * W, 0.84 * W],
           WHITE, 0.18)
    _arrow_path(img, np.array([[0.5 * W, 0.92 * H], [0.5 * W, 0.70 * H]]), WHITE,
                0.07 * H, 0.12 * H)


def _paint_mile_marker(f: _Face) -> None:
    """D10-1 mile marker: MILE over the mile's digits stacked vertically, white on green."""
    img, W, H, cx = f.img, f.W, f.H, f.cx
    _poly(img, f.poly, GREEN)
    b = max(2, int(0.05 * W))
    cv2.rectangle(img, (b, b), (W - b, H - b), WHITE, b, cv2.LINE_AA)
    _text(img, 'MILE', (cx, 0.17 * H), (0.76 * W, 0.12 * H), WHITE, 0.22)
    digits = str(f.speed)
    n = len(digits)
    top, bottom = 0.30 * H, 0.92 * H
    step = (bottom - top) / n
    for i, ch in enumerate(digits):
        _text(img, ch, (cx, top + step * (i + 0.5)), (0.62 * W, 0.78 * step), WHITE, 0.2)


#: Painter of each face, by catalogue shape (tried first) or by class.
_SHAPE_PAINTERS = {'diamond': _paint_diamond, 'octagon': _paint_stop, 'triangle': _paint_yield}
_CLASS_PAINTERS = {
    'do_not_enter': _paint_do_not_enter,
    'work_zone_begin': _paint_work_zone_begin,
    'work_zone_speed_limit': _paint_work_zone_speed_limit,
    'end_road_work': _paint_end_road_work,
    'speed_limit': _paint_speed_limit,
    'guide': _paint_guide,
    'mile_marker': _paint_mile_marker,
}


def _draw(key: str, W: int, H: int, speed: int, variant: str,
          orange: tuple[int, int, int] = ORANGE) -> np.ndarray:
    """Supersampled BGRA art of class ``key`` in a ``W`` x ``H`` rectangle (``orange`` its
    sheeting colour), alpha 0 outside the shape."""
    # one pixel more than the face: OpenCV puts a pixel's centre at its integer coordinate,
    # so the face's rectangle [0, W] x [0, H] reaches half a pixel into the last row and
    # column (:func:`_downsample` takes half of them)
    img = np.zeros((H + 1, W + 1, 3), np.uint8)
    mask = np.zeros((H + 1, W + 1), np.uint8)
    shape = signs.get(key).shape
    poly = outline(shape, W, H)
    _poly(mask, poly, 255)
    paint = _SHAPE_PAINTERS.get(shape) or _CLASS_PAINTERS.get(key)
    if paint is None:
        raise signs.UnknownSignError(f'no art for sign class {key!r}')
    paint(_Face(key, W, H, speed, variant, orange, img, poly))
    img[mask == 0] = 0
    return np.dstack([img, mask])


@lru_cache(maxsize=1024)
def _cached(key: str, size_px: int, speed: int, variant: str,
            orange: tuple[int, int, int] = ORANGE) -> np.ndarray:
    mirror = {right: left for left, right in MIRROR_PAIRS}
    if key in mirror:           # exact mirror image of the left variant
        face = np.ascontiguousarray(_cached(mirror[key], size_px, speed, variant,
                                            orange)[:, ::-1])
        face.flags.writeable = False
        return face
    W, H = face_size(key, size_px)
    face = _downsample(_draw(key, W * _SS, H * _SS, speed, variant, orange), _SS)
    face.flags.writeable = False
    return face


def _downsample(big: np.ndarray, f: int) -> np.ndarray:
    """The face at 1 / ``f`` of the supersampled drawing ``big`` ((f H + 1, f W + 1, C),
    drawn in OpenCV's coordinates, where pixel ``k`` spans ``[k - 0.5, k + 0.5]``): output
    pixel ``j`` is the mean over the drawing's ``[f j, f (j + 1)]``, the pixels at both
    ends taking half.  A plain ``f`` x ``f`` area resize of an (f H, f W) drawing took
    ``[f j - 0.5, f (j + 1) - 0.5]``: it shifted the art half a drawing pixel right and down
    and cut its right and bottom tips (a diamond's centroid 0.25 face pixels off its
    rectangle's centre, the box labels drawn from it so much smaller than the outline on
    those sides, a mirrored class shifted the other way)."""
    k = np.ones(f + 1, np.float32)
    k[0] = k[-1] = 0.5
    k /= f
    blurred = cv2.sepFilter2D(big.astype(np.float32), -1, k, k, anchor=(0, 0),
                              borderType=cv2.BORDER_CONSTANT)
    out = blurred[:-1:f, :-1:f]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def over(face: np.ndarray, background) -> np.ndarray:
    """``face`` (premultiplied BGRA art, as :func:`sign_face` returns it, or a warp of it)
    composited over ``background`` (an image of its size or a grey level): float32 BGR,
    ``background * (1 - alpha) + colour``."""
    alpha = face[..., 3:].astype(np.float32) / 255.0
    return background * (1 - alpha) + face[..., :3]


def sign_face(class_key: str, size_px: int = 256, speed_value: int | None = None,
              variant: str | None = None,
              orange: tuple[int, int, int] | None = None) -> np.ndarray:
    """Procedural art of one catalogue class.

    Args:
        class_key: catalogue key (``road_work_ahead``, ``stop``, ...; not ``background``).
        size_px: pixels of the longer side of the face's bounding rectangle.
        speed_value: number on speed-limit faces (default 45 for the work-zone limit, 65 for
            the general limit) or the mile of a mile marker (default 123).
        variant: for the classes of :data:`VARIANTS` (``other_workzone``,
            ``warning_diamond``) one of their variants (default the first); ignored for the
            others.
        orange: BGR of the orange sheeting (e.g. :func:`sheeting_orange`); default
            :data:`ORANGE`.  Ignored for classes without orange.

    Returns:
        Read-only BGRA uint8 image (H, W, 4) of the bounding rectangle; alpha is 0 outside
        the sign shape.  The colour is premultiplied by alpha (drawn anti-aliased over
        black): composite as ``background * (1 - alpha) + colour``.  Cached: the same
        arguments return the same array.

    Raises:
        UnknownSignError: ``class_key`` is not a drawable catalogue class.
    """
    if class_key == 'background':
        raise signs.UnknownSignError('background has no sign art')
    signs.get(class_key)
    if speed_value is None:
        speed_value = {'work_zone_speed_limit': 45, 'speed_limit': 65,
                       'mile_marker': 123}.get(class_key, 0)
    known = VARIANTS.get(class_key)
    if not known:
        variant = ''
    elif variant is None:
        variant = known[0]
    elif variant not in known:
        raise ValueError(f'unknown {class_key} variant {variant!r}; known: {known}')
    if orange is None or not uses_orange(class_key):
        orange = ORANGE
    return _cached(class_key, int(max(8, size_px)), int(speed_value), variant,
                   tuple(int(c) for c in orange))


@lru_cache(maxsize=4)
def drum_texture(width_px: int = 64, height_px: int = 96) -> np.ndarray:
    """BGR texture of a channelizing drum unrolled: orange with two white retro bands.

    Returns:
        Read-only uint8 image (height_px, width_px, 3).
    """
    tex = np.empty((height_px, width_px, 3), np.uint8)
    tex[:] = ORANGE
    for z0, z1 in ((0.18, 0.30), (0.48, 0.60)):
        tex[int(z0 * height_px):int(z1 * height_px)] = WHITE
    tex.flags.writeable = False
    return tex
