"""The hand-drawn sequences of the ``test_tracking*`` modules (and of
``test_track_confirmation.py``, through ``test_tracking``): an orange diamond with a black
border and a legend (or an orange-top / white-bottom regulatory box) on a textured
background, moved and scaled along a known path.  Positions are continuous image coordinates
(pixel j covers [j, j + 1))."""
from __future__ import annotations

import cv2
import numpy as np

from workzone_ros.interfaces import Box, Detection
from workzone_ros.tools.bench_tracker import textured_background

W, H = 640, 480
ORANGE = (0, 110, 245)
BLACK = (20, 20, 20)
WHITE = (235, 238, 238)


def background(seed: int = 0) -> np.ndarray:
    """Muted, blurred colour texture with pixel noise (road / vegetation / sky like)."""
    return textured_background(np.random.default_rng(seed), W, H)


_MASTER = 512


def _face(kind: str, text: str) -> tuple[np.ndarray, np.ndarray]:
    """Master sign face (BGR, alpha) drawn once at 512 px: the sign scales as one piece."""
    n = _MASTER
    img = np.zeros((n if kind == 'diamond' else int(1.5 * n), n, 3), np.uint8)
    alpha = np.zeros(img.shape[:2], np.uint8)
    h = img.shape[0]
    font = cv2.FONT_HERSHEY_SIMPLEX
    if kind == 'diamond':
        pts = np.array([[n / 2, 0], [n, n / 2], [n / 2, n], [0, n / 2]], np.int32)
        cv2.fillConvexPoly(alpha, pts, 255)
        cv2.fillConvexPoly(img, pts, ORANGE)
        cv2.polylines(img, [pts], True, BLACK, 22)
        lines = [(text, n / 2)]
    else:             # regulatory: orange top 30 %, white bottom
        alpha[:] = 255
        img[:] = WHITE
        img[:int(0.3 * h)] = ORANGE
        cv2.rectangle(img, (0, 0), (n - 1, h - 1), BLACK, 22)
        lines = [('WORK', 0.16 * h), ('BEGINS', 0.65 * h)]
    for t, yy in lines:
        (tw, th), _ = cv2.getTextSize(t, font, 3.0, 14)
        cv2.putText(img, t, (int(n / 2 - tw / 2), int(yy + th / 2)), font, 3.0, BLACK, 14,
                    cv2.LINE_AA)
    return img, alpha


_FACES: dict = {}


def _paste(img, kind, text, cx, cy, width):
    """Composite the face scaled to ``width`` px, centred at continuous (cx, cy)."""
    if (kind, text) not in _FACES:
        _FACES[kind, text] = _face(kind, text)
    face, alpha = _FACES[kind, text]
    n = max(4, int(round(width)))
    k = n / _MASTER
    m = max(4, int(round(face.shape[0] * k)))
    f = cv2.resize(face, (n, m), interpolation=cv2.INTER_AREA)
    a = cv2.resize(alpha, (n, m), interpolation=cv2.INTER_AREA)
    # Sub-pixel placement: face pixel centre u + 0.5 goes to cx + (u + 0.5 - n / 2).
    tx, ty = cx - n / 2, cy - m / 2
    M = np.float32([[1, 0, tx], [0, 1, ty]])
    fw = cv2.warpAffine(f, M, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR)
    aw = cv2.warpAffine(a, M, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR)
    aw = (aw.astype(np.float32) / 255)[..., None]
    img[:] = (img * (1 - aw) + fw * aw).astype(np.uint8)
    return (cx - n / 2, cy - m / 2, float(n), float(m))


def draw_diamond(img, cx, cy, size, text='WORK'):
    """Orange diamond sign (black border, legend) centred at (cx, cy); returns its box."""
    return _paste(img, 'diamond', text, cx, cy, size)


def draw_regulatory(img, cx, cy, width):
    """Orange-top / white-bottom rectangle (W x 1.5 W) centred at (cx, cy); returns its box."""
    return _paste(img, 'regulatory', '', cx, cy, width)


def det(box, conf=0.9, kind='warning'):
    return Detection(box=Box(x=box[0], y=box[1], w=box[2], h=box[3]), confidence=conf,
                     kind=kind)


def center(b):
    return (b.x + b.w / 2, b.y + b.h / 2) if isinstance(b, Box) else \
        (b[0] + b[2] / 2, b[1] + b[3] / 2)


#: The hand-drawn paths grow about 2 % per frame at 40-90 px: an approach several times slower
#: than the motion cue's minimum (``min_approach_speed``, a camera at 15 fps approaching at
#: 10 m/s or more); tests of localisation and track life run without the cue.
SLOW = dict(min_approach_speed=0.0)


def path(i):
    """A sign drifting right and up, accelerating outward and growing 2 % per frame."""
    return 300 + 3 * i + 0.05 * i * i, 200 - 1.0 * i, 40 * 1.02 ** i


def _banded(img, box, bands):
    """Horizontal colour bands (top to bottom) filling ``box``; returns the box."""
    x, y, w, h = (int(v) for v in box)
    k = len(bands)
    for j, col in enumerate(bands):
        img[y + j * h // k:y + (j + 1) * h // k, x:x + w] = col
    return (float(x), float(y), float(w), float(h))
