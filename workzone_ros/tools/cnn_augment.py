"""Camera-like degradation of training crops for ``workzone-ros train cnn``.

A training crop is re-cut as the detector cuts a frame (``_window``), brought to the size the
object had in the frame, and degraded like a phone camera's frame (:func:`augment`); rendered
signs are also pasted on real background crops (:func:`composite`: the simulator's sign art,
:func:`cutout`: the render cut along its outline).  ``train_cnn``'s module docstring says what
each step is for.
"""
from __future__ import annotations

import math
from typing import Optional

import cv2
import numpy as np

from workzone_ros.sim.weather import CAMERA_JPEG, jpeg_degrade

__all__ = ['RUN_MARGIN', 'augment', 'composite', 'cutout']

#: The margin and squaring of ``classify_boxes`` (the node's default margin).
RUN_MARGIN = 0.1

def _window(crop: np.ndarray, box, rng: np.random.Generator, keep_top: bool = False
            ) -> np.ndarray:
    """A detector-like, run-time-like square cut around the object (see module doc); with
    ``keep_top`` its top edge is never cut off."""
    H, W = crop.shape[:2]
    if box is None:
        box = (0.1 * W / 1.2, 0.1 * H / 1.2, W / 1.2, H / 1.2)
    x, y, w, h = box
    side = max(w, h, 2.0) * (1 + 2 * RUN_MARGIN) * math.exp(rng.uniform(-0.15, 0.35))
    cx = x + w / 2 + rng.uniform(-0.12, 0.12) * side
    cy = y + h / 2 + rng.uniform(-0.12, 0.12) * side
    x0, y0 = int(round(cx - side / 2)), int(round(cy - side / 2))
    if keep_top:
        y0 = min(y0, int(math.floor(y)))
    n = max(2, int(round(side)))
    x1, y1 = x0 + n, y0 + n
    if rng.random() < 0.5:                   # clip to what exists (an image border)
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
        if (cx1 - cx0) * (cy1 - cy0) >= 0.55 * n * n and cx1 - cx0 >= 3 and cy1 - cy0 >= 3:
            return crop[cy0:cy1, cx0:cx1]
    pad = max(0, -x0, -y0, x1 - W, y1 - H)
    if pad:
        crop = cv2.copyMakeBorder(crop, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        x0, y0, x1, y1 = x0 + pad, y0 + pad, x1 + pad, y1 + pad
    return crop[y0:y1, x0:x1]


def _resize(img: np.ndarray, w: int, h: int) -> np.ndarray:
    interp = cv2.INTER_AREA if img.shape[1] >= w and img.shape[0] >= h else cv2.INTER_LINEAR
    return cv2.resize(img, (w, h), interpolation=interp)


def augment(crop: np.ndarray, box, rng: np.random.Generator, scale: float = 1.0,
            texture: Optional[np.ndarray] = None, min_side: float = 0.0,
            keep_top: bool = False) -> np.ndarray:
    """One camera-like variant of a training crop (BGR ``uint8``, about the size the object
    had in the frame or smaller; the network's input resize then enlarges it smoothly, as
    at run time).

    Args:
        crop: the stored crop.
        box: the object's box in it (``None``: the whole crop).
        rng: randomness.
        scale: frame pixels per crop pixel; a render of a small sign stored enlarged (with
            blocky pixels) is first brought back to its size in the frame.
        texture: another crop, pasted as an occluder sometimes.
        min_side: never shrink the object's box below this (px): the node publishes
            smaller boxes as ``unknown`` and never classifies them.
        keep_top: neither the framing nor the occluder hides the object's top (a class
            told from another by its top: the WORK ZONE plaque above a speed-limit panel;
            hidden, the crop would be the other class under this one's label).
    """
    crop, box = _to_frame_scale(crop, box, scale)
    if rng.random() < 0.4:          # a tilted post, camera roll, a sign seen at an angle
        crop = _tilt(crop, rng)
    win = _window(crop, box, rng, keep_top)
    img = _distance_resize(win, box, rng, min_side).astype(np.float32)
    img = _colour_jitter(img, rng)
    # occlusion from a border
    if rng.random() < 0.25:
        _occlude(img, rng, texture, keep_top)
    img = _optics(img, rng)
    return jpeg_degrade(np.clip(img, 0, 255).astype(np.uint8), rng, *CAMERA_JPEG)


def _to_frame_scale(crop: np.ndarray, box, scale: float) -> tuple[np.ndarray, object]:
    """:func:`augment`'s crop and box brought back to their size in the frame (``scale``:
    frame pixels per crop pixel; unchanged from 0.95 up)."""
    if scale < 0.95:
        h, w = crop.shape[:2]
        nw, nh = max(4, int(round(w * scale))), max(4, int(round(h * scale)))
        crop = cv2.resize(crop, (nw, nh), interpolation=cv2.INTER_AREA)
        if box is not None:
            box = (box[0] * nw / w, box[1] * nh / h, box[2] * nw / w, box[3] * nh / h)
    return crop, box


def _tilt(crop: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """:func:`augment`'s rotation (+-12 deg) and horizontal squeeze of the whole crop."""
    H, W = crop.shape[:2]
    M = cv2.getRotationMatrix2D((W / 2, H / 2), rng.uniform(-12, 12), 1.0)
    M[0, :2] *= rng.uniform(0.75, 1.08)
    M[0, 2] = W / 2 - M[0, 0] * W / 2 - M[0, 1] * H / 2
    return cv2.warpAffine(crop, M, (W, H), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)


def _distance_resize(win: np.ndarray, box, rng: np.random.Generator,
                     min_side: float) -> np.ndarray:
    """:func:`augment`'s window at a random distance (the object's box at least
    ``min_side`` px), or sometimes at 70-130 px."""
    h0, w0 = win.shape[:2]
    # as seen from farther away (never closer: that would invent detail), or, sometimes, a
    # close sign: the run-time path of big crops
    s = min(1.0, max(8.0 / max(h0, w0), math.exp(rng.uniform(math.log(0.5), 0.0))))
    if min_side and box is not None:
        s = min(1.0, max(s, min_side / max(1.0, min(box[2], box[3]))))
    if rng.random() < 0.08:
        s = rng.uniform(70, 130) / max(h0, w0)
    return _resize(win, max(3, int(round(w0 * s))), max(3, int(round(h0 * s))))


def _colour_jitter(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """:func:`augment`'s colour changes of ``img`` (float32; scaled in place)."""
    # colour: white balance, exposure, gamma, contrast, saturation, haze
    img *= np.exp(rng.normal(0, 0.10, 3)).astype(np.float32)
    img *= float(math.exp(rng.uniform(-0.55, 0.4)))
    img = np.clip(img, 0, 255)
    img = 255.0 * (img / 255.0) ** float(math.exp(rng.uniform(-0.35, 0.35)))
    mean = img.mean()
    img = mean + (img - mean) * float(rng.uniform(0.6, 1.15))
    grey = img.mean(axis=2, keepdims=True)
    img = grey + (img - grey) * float(rng.uniform(0.45, 1.35))
    if rng.random() < 0.5:                   # sheeting and lighting hue, +-6 deg
        hsv = cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_BGR2HSV)
        hsv[..., 0] = ((hsv[..., 0].astype(int) + int(rng.integers(-3, 4))) % 180)
        img = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR).astype(np.float32)
    if rng.random() < 0.2:
        haze = rng.uniform(120, 230) * np.exp(rng.normal(0, 0.05, 3))
        a = rng.uniform(0.1, 0.4)
        img = img * (1 - a) + haze.astype(np.float32) * a
    return img


def _occlude(img: np.ndarray, rng: np.random.Generator, texture: Optional[np.ndarray],
             keep_top: bool = False) -> None:
    """:func:`augment`'s occluder (``texture`` or noisy flat colour) over 10-35 % of
    ``img`` from a random side (not the top with ``keep_top``), in place."""
    h, w = img.shape[:2]
    side = int(rng.integers(3 if keep_top else 4))
    depth = rng.uniform(0.1, 0.35)
    if texture is not None and rng.random() < 0.5:
        fill = _resize(texture, w, h).astype(np.float32)
    else:
        fill = np.empty_like(img)
        fill[:] = rng.uniform(0, 255, 3)
        fill += rng.normal(0, rng.uniform(2, 25), fill.shape)
    if side == 0:
        d = max(1, int(round(depth * w)))
        img[:, :d] = fill[:, :d]
    elif side == 1:
        d = max(1, int(round(depth * w)))
        img[:, w - d:] = fill[:, w - d:]
    elif side == 2:
        d = max(1, int(round(depth * h)))
        img[h - d:] = fill[h - d:]
    else:
        d = max(1, int(round(depth * h)))
        img[:d] = fill[:d]


def _optics(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """:func:`augment`'s optics and sensor: a Gaussian blur (45 % of the crops) and noise.

    No motion blur: a 3-5 px linear motion blur on 15 % of the crops, trained without each
    real clip on three seeds, did not help on the real clips (docs/classifier.md)."""
    if rng.random() < 0.45:
        sigma = rng.uniform(0.3, 1.0)
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    img += rng.normal(0, rng.uniform(0, 7), img.shape).astype(np.float32)
    return img


def composite(key: str, backdrop: np.ndarray, rng: np.random.Generator
              ) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The simulator's art of sign ``key`` pasted on part of a background crop.

    The renders show signs before grass, sky and asphalt only, so a network learns that a
    busy real backdrop (houses, brick, trees, traffic) means ``background``; pasted on the
    training clips' own background crops, the signs come with real surroundings.  The
    canvas is 16-64 px (the sign at that size in the frame, drawn anti-aliased by
    ``signart``), the face 45-80 % of it, off-centre, often on a post, in a random orange
    sheeting; returns the canvas and the face's box.
    """
    from workzone_ros.sim import signart
    n = int(rng.integers(20, 65))
    canvas = _resize(_backdrop_part(backdrop, rng), n, n).astype(np.float32)
    speed = int(rng.choice([25, 35, 45, 55, 65])) if 'speed' in key else None
    variants = signart.VARIANTS.get(key)
    variant = str(rng.choice(variants)) if variants else None
    orange = signart.sheeting_orange(int(rng.integers(8)), 7)
    side = max(12, int(round(n * rng.uniform(0.45, 0.8) / 2)) * 2)  # few cached sizes
    face = signart.sign_face(key, side, speed, variant, orange)
    h, w = face.shape[:2]
    if h > n or w > n:
        face = cv2.resize(face, (min(w, n), min(h, n)), interpolation=cv2.INTER_AREA)
        h, w = face.shape[:2]
    x = int(np.clip((n - w) / 2 + rng.uniform(-0.1, 0.1) * n, 0, n - w))
    y = int(np.clip((n - h) / 2 + rng.uniform(-0.1, 0.1) * n, 0, n - h))
    if rng.random() < 0.6 and y + h < n:            # a post below the face
        pw = max(1, int(round(w * 0.06)))
        grey = rng.uniform(60, 170)
        canvas[y + h:, x + w // 2 - pw // 2:x + w // 2 - pw // 2 + pw] = grey
    # sheeting under daylight: a tint, a light gradient across the face, grain
    art = face.astype(np.float32)
    gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
    light = 1.0 + rng.uniform(-0.25, 0.25) * (gx / w - 0.5) + rng.uniform(-0.25, 0.25) * (
        gy / h - 0.5)
    art[..., :3] *= light[..., None] * np.exp(rng.normal(0, 0.06, 3)).astype(np.float32)
    art[..., :3] += rng.normal(0, rng.uniform(0, 8), (h, w, 3)) * art[..., 3:] / 255.0
    canvas[y:y + h, x:x + w] = signart.over(art, canvas[y:y + h, x:x + w])
    return np.clip(canvas, 0, 255).astype(np.uint8), (float(x), float(y), float(w), float(h))


def _backdrop_part(backdrop: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random window of ``backdrop``, 50-100 % of its size on both sides."""
    H, W = backdrop.shape[:2]
    f = rng.uniform(0.5, 1.0)
    w, h = max(4, int(W * f)), max(4, int(H * f))
    x0, y0 = int(rng.integers(0, W - w + 1)), int(rng.integers(0, H - h + 1))
    return backdrop[y0:y0 + h, x0:x0 + w]


def transplant(crop: np.ndarray, box, backdrop: np.ndarray,
               rng: np.random.Generator) -> tuple[np.ndarray, tuple]:
    """A real sign's box (its face with the corners of its own surroundings) cut from
    ``crop`` and put on part of another real background crop, 1.4-2.2 times its size, a
    little off-centre; returns the canvas (at the crop's pixel scale) and the box.

    A real sign seen only before its own clip's houses or brick teaches a network that the
    sign is that street; on other clips' backgrounds the sign itself is what stays the same.
    """
    H, W = crop.shape[:2]
    x, y = (max(0, int(round(v))) for v in box[:2])
    w = max(2, min(int(round(box[2])), W - x))
    h = max(2, min(int(round(box[3])), H - y))
    f = rng.uniform(1.4, 2.2)
    cw, ch = int(round(w * f)), int(round(h * f))
    canvas = cv2.resize(_backdrop_part(backdrop, rng), (cw, ch))
    px = int(np.clip((cw - w) / 2 + rng.uniform(-0.15, 0.15) * cw, 0, cw - w))
    py = int(np.clip((ch - h) / 2 + rng.uniform(-0.15, 0.15) * ch, 0, ch - h))
    canvas[py:py + h, px:px + w] = crop[y:y + h, x:x + w]
    return canvas, (float(px), float(py), float(w), float(h))


def cutout(key: str, crop: np.ndarray, box, scale: float, backdrop: np.ndarray,
           rng: np.random.Generator) -> tuple[np.ndarray, tuple]:
    """A rendered sign cut out along its outline (the class's shape in its box) and put
    before part of a background crop, at the size it had in the frame; returns the canvas
    and the box.  The renderer's sheeting and light, with real surroundings."""
    from workzone_ros.core import signs
    from workzone_ros.sim import signart
    if scale < 0.95:
        h, w = crop.shape[:2]
        nw, nh = max(4, int(round(w * scale))), max(4, int(round(h * scale)))
        crop = cv2.resize(crop, (nw, nh), interpolation=cv2.INTER_AREA)
        box = (box[0] * nw / w, box[1] * nh / h, box[2] * nw / w, box[3] * nh / h)
    # the render on a canvas with room around it (renders are cut tight to the sign)
    ch, cw = crop.shape[:2]
    m = int(round(0.25 * max(ch, cw)))
    H, W = ch + 2 * m, cw + 2 * m
    x, y, w, h = box[0] + m, box[1] + m, box[2], box[3]
    poly = signart.outline(signs.get(key).shape, w, h) + (x, y)
    mask = np.zeros((H, W), np.uint8)
    cv2.fillPoly(mask, [np.round(poly * 16).astype(np.int32)], 255, cv2.LINE_AA, shift=4)
    mask[:m] = mask[m + ch:] = 0
    mask[:, :m] = mask[:, m + cw:] = 0
    a = (mask.astype(np.float32) / 255.0)[..., None]
    crop = cv2.copyMakeBorder(crop, m, m, m, m, cv2.BORDER_CONSTANT)
    canvas = _resize(_backdrop_part(backdrop, rng), W, H).astype(np.float32)
    if rng.random() < 0.6 and y + h < H:            # a post below the face
        pw = max(1, int(round(w * 0.06)))
        px = int(round(x + w / 2 - pw / 2))
        canvas[int(y + h):, max(0, px):max(0, px + pw)] = rng.uniform(60, 170)
    out = canvas * (1 - a) + crop.astype(np.float32) * a
    return np.clip(out, 0, 255).astype(np.uint8), (x, y, w, h)
