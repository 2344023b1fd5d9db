"""``workzone-ros real-pixels``: colour-training images and masks from hand-labelled video frames.

``workzone-ros train color`` learns the orange sign colour from ``images/`` + ``masks/``
folders.  Renders alone teach it our simulator's palette; this tool adds real camera pixels.
It reads a crop index (``test/data/real_crops/index.csv``: one row per labelled box with
``class_key, clip, frame, x, y, w, h`` and the sign's ``shape``) and the clips it names, and
writes, for every frame that holds a labelled box:

* ``images/<clip>_<frame>.png``: the frame at its native size;
* ``masks/<clip>_<frame>.png``: 255 on the face of every orange work-zone sign (the shape
  drawn inside its box: a diamond, a rectangle or an octagon), 128 ("ignore") on every
  ``background`` box (cones, drums, vests, trucks: orange things that are not signs, whose
  colour the table must not learn to reject, because a sign of that colour must stay a
  candidate; the classifier rejects them by how they look), 0 elsewhere.

Signs of other colours (STOP, yellow diamonds) are left 0: background for the orange table.

Say which clips trained a model: ``--exclude-clip`` keeps a clip out, so that a colour model
can be measured on a clip it never saw (leave one clip out).
"""
from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path
from typing import Optional

import numpy as np

from workzone_ros.tools.clips import find_video, frames_of

__all__ = ['IGNORE', 'FACE', 'face_polygon', 'frame_mask', 'main']

REPO = Path(__file__).resolve().parents[2]
INDEX = REPO / 'test' / 'data' / 'real_crops' / 'index.csv'
VIDEOS = REPO.parent / 'shared' / 'realdata' / 'us_workzone_video'
FACE = 255
IGNORE = 128


def face_polygon(shape: str, x: float, y: float, w: float, h: float) -> np.ndarray:
    """The sign face drawn inside its box, as an (N, 2) int32 polygon."""
    if shape == 'diamond':
        pts = [(x + w / 2, y), (x + w, y + h / 2), (x + w / 2, y + h), (x, y + h / 2)]
    elif shape == 'octagon':
        a, b = w * 0.29, h * 0.29
        pts = [(x + a, y), (x + w - a, y), (x + w, y + b), (x + w, y + h - b),
               (x + w - a, y + h), (x + a, y + h), (x, y + h - b), (x, y + b)]
    elif shape == 'rectangle':
        pts = [(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
    else:
        raise ValueError(f'unknown sign shape {shape!r} (diamond, rectangle, octagon)')
    return np.round(np.array(pts, np.float64)).astype(np.int32)


def frame_mask(size: tuple[int, int], rows: list[dict], orange: set[str]) -> np.ndarray:
    """The mask of one frame from its index rows (module docstring)."""
    import cv2
    mask = np.zeros((size[1], size[0]), np.uint8)
    for r in rows:                  # ignore first: a sign box overlapping a cone box wins
        if r['class_key'] == 'background':
            x, y, w, h = (int(round(float(r[k]))) for k in 'xywh')
            mask[max(y, 0):y + h, max(x, 0):x + w] = IGNORE
    for r in rows:
        if r['class_key'] in orange:
            poly = face_polygon(r['shape'], *(float(r[k]) for k in 'xywh'))
            cv2.fillPoly(mask, [poly], FACE)
    return mask


def _orange_classes() -> set[str]:
    from workzone_ros.core.signs import CATALOGUE
    keys = {c.key for c in CATALOGUE if c.category == 'workzone' and c.colors[0] == 'orange'}
    return keys | {'other_workzone'}


def _by_frame(index: Path, exclude: set[str], step: int, orange: set[str]) -> dict:
    with open(index) as fh:
        rows = list(csv.DictReader(fh))
    if rows and 'shape' not in rows[0]:
        raise ValueError(f'{index} has no shape column')
    out: dict = defaultdict(lambda: defaultdict(list))
    for n, r in enumerate(rows, 2):
        if r['class_key'] in orange and r['shape'] not in ('diamond', 'rectangle', 'octagon'):
            raise ValueError(f'{index} line {n}: an orange {r["class_key"]} needs its shape '
                             f'(diamond, rectangle or octagon), not {r["shape"]!r}')
        if r['clip'] not in exclude and int(r['frame']) % step == 0:
            out[r['clip']][int(r['frame'])].append(r)
    return out


def write_clip(video: Path, frames: dict, out: Path, orange: set[str]) -> int:
    """Write the labelled frames of one clip; returns how many were written."""
    import cv2
    n = 0
    for k, img in frames_of(video, frames, max(frames)):
        mask = frame_mask((img.shape[1], img.shape[0]), frames[k], orange)
        name = f'{video.stem}_{k:04d}.png'
        cv2.imwrite(str(out / 'images' / name), img)
        cv2.imwrite(str(out / 'masks' / name), mask)
        n += 1
    return n


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point (module docstring)."""
    p = argparse.ArgumentParser(prog='workzone-ros real-pixels', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('-o', '--output', required=True, help='folder for images/ and masks/')
    p.add_argument('--index', type=Path, default=INDEX, help=f'crop index (default {INDEX})')
    p.add_argument('--videos', type=Path, default=VIDEOS, help='folder of the clips')
    p.add_argument('--exclude-clip', nargs='*', default=[], metavar='CLIP',
                   help='clips (names without .mp4) to keep out')
    p.add_argument('--step', type=int, default=3, help='use frames divisible by this (3)')
    args = p.parse_args(argv)
    if args.step < 1:
        p.error('--step must be >= 1')
    orange = _orange_classes()
    try:
        frames = _by_frame(args.index, set(args.exclude_clip), args.step, orange)
    except (OSError, ValueError, KeyError) as exc:
        print(f'workzone-ros real-pixels: {exc}', file=sys.stderr)
        return 2
    out = Path(args.output)
    (out / 'images').mkdir(parents=True, exist_ok=True)
    (out / 'masks').mkdir(parents=True, exist_ok=True)
    for clip, fr in sorted(frames.items()):
        try:
            video = find_video(args.videos, clip)
        except FileNotFoundError as exc:
            print(f'{clip}: {exc}, skipped', file=sys.stderr)
            continue
        n = write_clip(video, fr, out, orange)
        print(f'{clip}: {n} frames', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
