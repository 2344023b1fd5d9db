"""Reading labelled video clips, shared by the tools that make training data from them.

* :func:`find_video`, :func:`list_videos`: a clip's video by its name, a folder's videos;
* :func:`frames_of`: the frames of a video (all, or the ones wanted), in order;
* :func:`crop_box`: a labelled box as a stored training crop (the ``test/data/real_crops``
  format: grown by :data:`GROW` per side, longer side at most :data:`MAX_SIDE`);
* :func:`interpolate_keyframes`: a sign's hand-labelled keyframe boxes, one per frame.
"""
from __future__ import annotations

from pathlib import Path
from typing import Container, Iterator, Optional, Sequence

import numpy as np

__all__ = ['GROW', 'MAX_SIDE', 'VIDEO_EXT', 'crop_box', 'find_video', 'frames_of',
           'interpolate_keyframes', 'list_videos']

GROW = 0.25       # share of the box size added on each side of a stored crop
MAX_SIDE = 64     # longer side of a stored crop, pixels
VIDEO_EXT = ('.mp4', '.avi', '.mkv', '.mov', '.webm')


def list_videos(folder: Path) -> list[Path]:
    """The videos of ``folder`` (by extension, :data:`VIDEO_EXT`), sorted by name."""
    return sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in VIDEO_EXT) \
        if Path(folder).is_dir() else []


def find_video(folder: Path, clip: str) -> Path:
    """The video of ``clip`` (its file name, with or without the extension) in ``folder``.

    Raises:
        FileNotFoundError: no such video.
    """
    for p in list_videos(folder):
        if clip in (p.name, p.stem):
            return p
    raise FileNotFoundError(f'no video {clip} ({"/".join(VIDEO_EXT)}) in {folder}')


def frames_of(video: Path, wanted: Optional[Container[int]] = None,
              last: Optional[int] = None) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame number, BGR image)`` of ``video`` in order, 0-based as OpenCV reads them.

    Args:
        video: a file OpenCV's ``VideoCapture`` reads.
        wanted: only these frame numbers (None: every frame).
        last: stop after this frame (None: at the end of the video).

    Raises:
        ValueError: the video cannot be opened.
    """
    import cv2
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise ValueError(f'cannot read {video}')
    try:
        k = -1
        while last is None or k < last:
            ok, img = cap.read()
            if not ok:
                return
            k += 1
            if wanted is None or k in wanted:
                yield k, img
    finally:
        cap.release()


def crop_box(img: np.ndarray, x: float, y: float, w: float, h: float) -> np.ndarray:
    """The box grown by GROW on each side, clipped to the image, longer side <= MAX_SIDE."""
    import cv2
    height, width = img.shape[:2]
    x0 = int(round(max(0.0, x - GROW * w)))
    y0 = int(round(max(0.0, y - GROW * h)))
    x1 = int(round(min(float(width), x + w + GROW * w)))
    y1 = int(round(min(float(height), y + h + GROW * h)))
    crop = img[y0:y1, x0:x1]
    scale = MAX_SIDE / max(crop.shape[:2])
    if scale < 1.0:
        size = (max(1, int(round(crop.shape[1] * scale))),
                max(1, int(round(crop.shape[0] * scale))))
        crop = cv2.resize(crop, size, interpolation=cv2.INTER_AREA)
    return crop


def interpolate_keyframes(keys: Sequence[tuple]) -> Iterator[tuple[int, tuple, bool]]:
    """``(frame, (x, y, w, h), visible)`` for every frame from a sign's first keyframe to its
    last: the box linearly interpolated between the two keyframes around the frame.

    ``keys`` are ``(frame, x, y, w, h, visible)`` of one sign, in any order.  A frame between
    two keyframes is visible only when both are; a keyframe is as it was labelled.
    """
    ks = sorted(keys)
    for a, b in zip(ks, ks[1:]):
        for f in range(a[0], b[0]):         # (each keyframe once: the last one below)
            u = (f - a[0]) / max(b[0] - a[0], 1)
            box = tuple(float((1 - u) * a[i] + u * b[i]) for i in range(1, 5))
            yield f, box, bool(a[5] and b[5]) or (f == a[0] and bool(a[5]))
    if ks:
        yield ks[-1][0], tuple(float(v) for v in ks[-1][1:5]), bool(ks[-1][5])
