"""``workzone-ros mine-background``: hard negatives for the sign classifier from real video.

The recall-first colour proposals (:mod:`workzone_ros.core.proposals`) fire on brick, dirt,
foliage, cones, vests and trucks: every such firing is a crop the classifier must reject.
This tool runs the proposals over the clips and keeps, as ``background``, every candidate
that is not a sign:

* frames inside a labelled work-zone sign range (``--ranges``, by eye) are skipped, so an
  unlabelled sign is never mined as background;
* a candidate overlapping a labelled sign box of the crop index (``--index``, any class, the
  box interpolated between labelled frames) is skipped.

It writes crops in the format of ``test/data/real_crops`` (the box grown by 25 % per side,
longer side at most 64 px, ``index.csv`` with ``path,class_key,clip,frame,x,y,w,h,source``),
so ``workzone-ros train classifier --data DIR`` and ``--exclude-clip`` read them as they read
the hand-labelled crops.  Keep the clips you report on out (``--exclude-clip``).
"""
from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path
from typing import Optional

from workzone_ros.tools.clips import crop_box, frames_of, list_videos

__all__ = ['mine_clip', 'main']

REPO = Path(__file__).resolve().parents[2]
INDEX = REPO / 'test' / 'data' / 'real_crops' / 'index.csv'
RANGES = Path(__file__).resolve().parent / 'data' / 'real_clip_ranges.csv'
VIDEOS = REPO.parent / 'shared' / 'realdata' / 'us_workzone_video'
def _sign_boxes(index: Path) -> dict:
    """clip -> frame -> labelled sign boxes, each held over the 3 frames around its label."""
    out: dict = defaultdict(lambda: defaultdict(list))
    with open(index) as fh:
        for r in csv.DictReader(fh):
            if r['class_key'] == 'background':
                continue
            box = tuple(float(r[k]) for k in 'xywh')
            for f in range(int(r['frame']) - 3, int(r['frame']) + 4):
                out[r['clip']][f].append(box)
    return out


def _sign_ranges(path: Path) -> dict:
    out: dict = defaultdict(list)
    with open(path) as fh:
        for r in csv.DictReader(line for line in fh if not line.startswith('#')):
            if r['content'] == 'workzone_sign':
                out[r['clip'].removesuffix('.mp4')].append(
                    (int(r['first_frame']), int(r['last_frame'])))
    return out


def mine_clip(video: Path, proposer, signs: dict, ranges: list, step: int, min_size: int,
              out: Path, writer) -> int:
    """Write one clip's background crops; returns how many."""
    import cv2

    from workzone_ros.core.proposals import candidate_labels
    n = 0
    for k, img in frames_of(video):
        if k % step or any(a <= k <= b for a, b in ranges):
            continue
        props = [p for p in proposer.propose(img) if max(p.box[2:]) >= min_size]
        hit = candidate_labels([p.box for p in props], signs.get(k, []), iou=0.05)
        for j, (p, h) in enumerate(zip(props, hit)):
            if h:
                continue
            name = f'background/{video.stem}_{k:04d}_{j}.png'
            cv2.imwrite(str(out / name), crop_box(img, *p.box))
            writer.writerow([name, 'background', video.stem, k,
                             *(f'{v:.1f}' for v in p.box), 'proposal', ''])
            n += 1
    return n


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point (module docstring)."""
    from workzone_ros.core import color_model as cm
    from workzone_ros.core.proposals import ProposalConfig, SignProposer
    from workzone_ros.resources import config_path
    p = argparse.ArgumentParser(prog='workzone-ros mine-background', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('-o', '--output', required=True, help='folder for background/ and index.csv')
    p.add_argument('--model', default=str(config_path('models/color_proposals.npz')),
                   help='colour model with the proposal ranker')
    p.add_argument('--index', type=Path, default=INDEX, help='labelled crops (their sign boxes)')
    p.add_argument('--ranges', type=Path, default=RANGES, help='work-zone sign frame ranges')
    p.add_argument('--videos', type=Path, default=VIDEOS, help='folder of the clips')
    p.add_argument('--exclude-clip', nargs='*', default=[], metavar='CLIP')
    p.add_argument('--step', type=int, default=6, help='every this many frames (6)')
    p.add_argument('--min-size', type=int, default=16, help='smallest candidate, px (16)')
    p.add_argument('--max-candidates', type=int, default=12, help='proposals per frame (12)')
    args = p.parse_args(argv)
    if args.step < 1:
        p.error('--step must be >= 1')
    try:
        proposer = SignProposer(cm.load_model(args.model),
                                ProposalConfig(max_candidates=args.max_candidates))
        signs, ranges = _sign_boxes(args.index), _sign_ranges(args.ranges)
    except (cm.ModelError, OSError, KeyError, ValueError) as exc:
        print(f'workzone-ros mine-background: {exc}', file=sys.stderr)
        return 2
    out = Path(args.output)
    (out / 'background').mkdir(parents=True, exist_ok=True)
    videos = [v for v in list_videos(args.videos) if v.stem not in args.exclude_clip]
    if not videos:
        print(f'workzone-ros mine-background: no clips in {args.videos}', file=sys.stderr)
        return 2
    with open(out / 'index.csv', 'w', newline='') as fh:
        writer = csv.writer(fh, lineterminator='\n')
        writer.writerow(['path', 'class_key', 'clip', 'frame', 'x', 'y', 'w', 'h', 'source',
                         'shape'])
        for v in videos:
            n = mine_clip(v, proposer, signs[v.stem], ranges.get(v.stem, []), args.step,
                          args.min_size, out, writer)
            print(f'{v.stem}: {n} background crops', file=sys.stderr, flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
