#!/usr/bin/env python3
"""Regenerate the real sign / background crops of this folder from the dashcam clips.

Not part of the package: a helper that makes the crops in ``<class_key>/`` reproducible from
``index.csv`` (one row per crop: ``path,class_key,clip,frame,x,y,w,h,source``, the box in
native 722x406 pixels) and the clips of ``../shared/realdata/us_workzone_video`` (see
README.md here).  Each crop is the box grown by 25 % of its size on every side, clipped to
the image, shrunk (INTER_AREA) so its longer side is at most 64 px, and written as PNG.

Usage (from the repository root)::

    python test/data/real_crops/make_crops.py            # write every crop of index.csv
    python test/data/real_crops/make_crops.py --check    # compare with the stored crops
    python test/data/real_crops/make_crops.py --video-dir /elsewhere/us_workzone_video

Exits 0 (with a message) when the clips are absent, as on a user's machine.
"""
from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from workzone_ros.tools.mine_background import crop_box

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
VIDEO_DIR = REPO.parent / 'shared' / 'realdata' / 'us_workzone_video'


def read_index(path: Path) -> list[dict]:
    with open(path, newline='') as fh:
        return list(csv.DictReader(fh))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--video-dir', type=Path, default=VIDEO_DIR)
    ap.add_argument('--index', type=Path, default=HERE / 'index.csv')
    ap.add_argument('--check', action='store_true',
                    help='do not write; report crops that differ from the stored PNGs')
    args = ap.parse_args(argv)
    if not args.video_dir.is_dir():
        print(f'{args.video_dir} not found: nothing to do (the clips are test data of the '
              f'development machine only)')
        return 0
    rows = read_index(args.index)
    by_clip: dict[str, dict[int, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        by_clip[r['clip']][int(r['frame'])].append(r)
    written = differ = 0
    for clip, frames in sorted(by_clip.items()):
        cap = cv2.VideoCapture(str(args.video_dir / f'{clip}.mp4'))
        if not cap.isOpened():
            print(f'cannot open {clip}.mp4', file=sys.stderr)
            return 1
        last, k = max(frames), -1
        while k < last:
            ok, img = cap.read()
            if not ok:
                print(f'{clip}: ends at frame {k}, index wants {last}', file=sys.stderr)
                return 1
            k += 1
            for r in frames.get(k, ()):
                crop = crop_box(img, *(float(r[c]) for c in 'xywh'))
                out = HERE / r['path']
                if args.check:
                    old = cv2.imread(str(out)) if out.exists() else None
                    if old is None or old.shape != crop.shape or \
                            int(np.abs(old.astype(int) - crop).max()) > 2:
                        differ += 1
                        print(f'differs: {r["path"]}')
                else:
                    out.parent.mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(out), crop, [cv2.IMWRITE_PNG_COMPRESSION, 9])
                    written += 1
        cap.release()
    if args.check:
        print(f'{len(rows)} crops checked, {differ} differ')
        return 1 if differ else 0
    print(f'{written} crops written under {HERE}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
