"""``workzone-ros make-crops``: classifier training crops from signs labelled in your videos.

The sign classifier learns real signs from crops (``workzone-ros train cnn --data DIR``,
``train classifier --data DIR``) and the colour table learns real pixels from the same labels
(``workzone-ros real-pixels --index DIR/index.csv``).  This tool makes that folder from what a
labeller writes: a few keyframe boxes per sign, read by eye.

``--labels CSV``, one row per keyframe (lines starting with ``#`` are comments)::

    clip,frame,x,y,w,h,visible,sign,class_key,shape
    dashcam_03,120,610,220,18,18,1,1,road_work_ahead,diamond
    dashcam_03,150,640,200,40,40,1,1,road_work_ahead,diamond
    dashcam_03,150,300,260,60,40,1,2,background,

* ``clip``: the video's file name without its extension, in ``--videos``; ``frame`` 0-based,
  as OpenCV reads it; ``x,y,w,h`` the box in the video's pixels;
* ``visible``: 0 when the sign is (mostly) hidden on that keyframe: frames between two
  keyframes are cut only when both are visible;
* ``sign``: which sign of the clip the row belongs to (optional, 1 when absent); boxes are
  interpolated linearly between the keyframes of one sign;
* ``class_key``: a class of ``workzone_ros.core.signs`` or ``background`` (cones, trucks,
  vests: orange things the classifier must reject), the same on every row of a sign;
* ``shape``: the face, ``diamond``, ``rectangle`` or ``octagon`` (optional; ``real-pixels``
  needs it for orange signs).

Every ``--every``-th frame of each sign's range with a box of at least ``--min-side`` px
becomes a crop.  The output is the format of ``test/data/real_crops``: ``<class_key>/
<clip>_<frame>_<n>.png`` (the box grown by 25 % per side, longer side at most 64 px) and
``index.csv`` (``path,class_key,clip,frame,x,y,w,h,source,shape``).

``--index CSV`` instead re-cuts the crops of an existing index (``--check``: compare them with
the stored files and change nothing), e.g. ``--index test/data/real_crops/index.csv -o
test/data/real_crops --check``.

Keep the clips you report on out of training (``train cnn --exclude-clip``).
"""
from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path
from typing import Optional

import numpy as np

from workzone_ros.tools.clips import crop_box, find_video, frames_of, interpolate_keyframes

__all__ = ['INDEX_COLUMNS', 'LabelError', 'read_keyframes', 'index_rows', 'write_crops',
           'main']

INDEX_COLUMNS = ('path', 'class_key', 'clip', 'frame', 'x', 'y', 'w', 'h', 'source', 'shape')
_NEEDED = ('clip', 'frame', 'x', 'y', 'w', 'h', 'visible', 'class_key')
_SHAPES = ('', 'diamond', 'rectangle', 'octagon')


class LabelError(ValueError):
    """A labels file that cannot be used (the message names the file, row and problem)."""


def read_keyframes(path: Path) -> dict:
    """``(clip, sign) -> {'class_key', 'shape', 'keys': [(frame, x, y, w, h, visible)]}``.

    Raises:
        LabelError: a missing column, an unreadable number, an unknown class or shape, a
            box without area, or a sign whose rows name different classes.
        OSError: the file cannot be read.
    """
    with open(path, newline='') as fh:
        lines = [(n, line) for n, line in enumerate(fh, 1) if not line.startswith('#')]
    reader = csv.DictReader(line for _, line in lines)
    missing = [c for c in _NEEDED if c not in (reader.fieldnames or ())]
    if missing:
        raise LabelError(f'{path}: no column {", ".join(missing)} (needs '
                         f'{",".join(_NEEDED)}[,sign][,shape])')
    signs: dict = {}
    for row in reader:
        where = f'{path} line {lines[reader.line_num - 1][0]}'
        key, sign, cls, shape = _keyframe(row, where)
        entry = signs.setdefault((row['clip'], sign),
                                 {'class_key': cls, 'shape': shape, 'keys': []})
        if entry['class_key'] != cls:
            raise LabelError(f'{where}: sign {sign} of {row["clip"]} was '
                             f'{entry["class_key"]!r} on an earlier row, here {cls!r}')
        entry['keys'].append(key)
    return signs


def _keyframe(row: dict, where: str) -> tuple:
    """``((frame, x, y, w, h, visible), sign, class_key, shape)`` of one labels row."""
    from workzone_ros.core.signs import BY_KEY
    try:
        key = (int(row['frame']), *(float(row[k]) for k in 'xywh'), int(row['visible']))
        sign = int(row.get('sign') or 1)
    except (TypeError, ValueError):
        raise LabelError(f'{where}: frame, x, y, w, h, visible and sign must be '
                         f'numbers') from None
    cls, shape = (row['class_key'] or '').strip(), (row.get('shape') or '').strip()
    if cls not in BY_KEY:
        raise LabelError(f'{where}: unknown class_key {cls!r}')
    if shape not in _SHAPES:
        raise LabelError(f'{where}: shape {shape!r} is not one of {_SHAPES[1:]}')
    if key[0] < 0 or key[3] <= 0 or key[4] <= 0:
        raise LabelError(f'{where}: a negative frame or a box without area')
    return key, sign, cls, shape


def index_rows(signs: dict, every: int = 3, min_side: float = 12.0) -> list[dict]:
    """The crop index of keyframe-labelled signs: every ``every``-th frame (frame numbers
    divisible by it) where the sign is visible and its box at least ``min_side`` px on its
    shorter side; ``path`` numbers the crops of a frame."""
    rows: list[dict] = []
    per_frame: dict = defaultdict(int)
    for (clip, _), s in sorted(signs.items()):
        for f, box, visible in interpolate_keyframes(s['keys']):
            if f % every or not visible or min(box[2:]) < min_side:
                continue
            n = per_frame[(clip, f)]
            per_frame[(clip, f)] += 1
            rows.append({'path': f'{s["class_key"]}/{clip}_{f:04d}_{n}.png',
                         'class_key': s['class_key'], 'clip': clip, 'frame': f,
                         **{k: f'{v:.1f}' for k, v in zip('xywh', box)},
                         'source': 'hand', 'shape': s['shape']})
    return sorted(rows, key=lambda r: (r['clip'], int(r['frame']), r['path']))


def _read_index(path: Path) -> list[dict]:
    with open(path, newline='') as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in INDEX_COLUMNS[:8] if c not in (reader.fieldnames or ())]
        if missing:
            raise LabelError(f'{path}: no column {", ".join(missing)}')
        return list(reader)


def write_crops(rows: list[dict], videos: Path, out: Path, check: bool = False) -> tuple:
    """Cut (or, with ``check``, compare) the crops of ``rows``; ``(done, differing)``.

    Raises:
        FileNotFoundError: a clip's video is not in ``videos``.
        LabelError: a labelled frame lies beyond the end of its video.
    """
    import cv2
    by_clip: dict = defaultdict(lambda: defaultdict(list))
    for r in rows:
        by_clip[r['clip']][int(r['frame'])].append(r)
    done, differ = 0, []
    for clip, frames in sorted(by_clip.items()):
        seen = -1
        for k, img in frames_of(find_video(videos, clip), frames, max(frames)):
            seen = k
            for r in frames[k]:
                crop, path = crop_box(img, *(float(r[c]) for c in 'xywh')), out / r['path']
                if check:
                    old = cv2.imread(str(path)) if path.exists() else None
                    if old is None or old.shape != crop.shape or \
                            int(np.abs(old.astype(int) - crop).max()) > 2:
                        differ.append(r['path'])
                else:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(path), crop, [cv2.IMWRITE_PNG_COMPRESSION, 9])
                done += 1
        if seen < max(frames):
            raise LabelError(f'{clip}: the video ends before frame {max(frames)}, which the '
                             f'labels name')
        print(f'{clip}: {sum(len(v) for v in frames.values())} crops', file=sys.stderr,
              flush=True)
    return done, differ


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='workzone-ros make-crops', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--labels', type=Path, help='keyframe boxes of the signs (above)')
    src.add_argument('--index', type=Path, help='an existing crop index to cut again')
    p.add_argument('--videos', type=Path, required=True, help='folder of the clips')
    p.add_argument('-o', '--output', type=Path, required=True,
                   help='folder for <class_key>/ and index.csv')
    p.add_argument('--every', type=int, default=3, help='every this many frames (3)')
    p.add_argument('--min-side', type=float, default=12.0,
                   help="smallest box side, px (12, the classifier node's min_size)")
    p.add_argument('--check', action='store_true',
                   help='with --index: compare with the stored crops, write nothing')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point (module docstring)."""
    p = _parser()
    args = p.parse_args(argv)
    if args.every < 1:
        p.error('--every must be >= 1')
    if args.check and args.index is None:
        p.error('--check compares the crops of an --index')
    try:
        if args.index is not None:
            rows = _read_index(args.index)
        else:
            rows = index_rows(read_keyframes(args.labels), args.every, args.min_side)
        if not rows:
            raise LabelError('no crop to cut: no visible box of at least --min-side px')
        if args.index is None:
            args.output.mkdir(parents=True, exist_ok=True)
            with open(args.output / 'index.csv', 'w', newline='') as fh:
                writer = csv.DictWriter(fh, INDEX_COLUMNS, lineterminator='\n')
                writer.writeheader()
                writer.writerows(rows)
        done, differ = write_crops(rows, args.videos, args.output, args.check)
    except (OSError, ValueError, KeyError) as exc:
        print(f'workzone-ros make-crops: {exc}', file=sys.stderr)
        return 2
    if args.check:
        print(f'{done} crops checked, {len(differ)} differ' +
              ''.join(f'\n  differs: {d}' for d in differ))
        return 1 if differ else 0
    print(f'{done} crops in {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
