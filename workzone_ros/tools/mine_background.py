"""``workzone-ros mine-background``: hard negatives for the sign classifier from real video.

The recall-first colour proposals (:mod:`workzone_ros.core.proposals`) fire on brick, dirt,
foliage, cones, vests and trucks: every such firing is a crop the classifier must reject.
This tool runs the proposals over the clips and keeps, as ``background``, every candidate
that is not a sign:

* frames inside a labelled work-zone sign range (``--ranges``, by eye) are skipped, so an
  unlabelled sign is never mined as background;
* a candidate overlapping a labelled sign box of the crop index (``--index``, any class, the
  box interpolated between labelled frames) is skipped.

With ``--labels CSV ...`` (keyframe boxes of every sign in the clips, the format of
``tools/data/real_sign_boxes.csv``; the shipped ``real_sign_boxes.csv``,
``real_sign_boxes_more.csv`` and ``real_general_sign_boxes.csv`` with the crop index label
every sign of the six clips a proposal can take) the frames inside
the ranges are mined too, away from those boxes (each held ``HOLD`` frames before and after
its labels: a sign entering or leaving the frame is often unlabelled there): the negatives in
a sign's own scene (a yellow regulatory sign beside it, the brick behind it, the drums after
it) that the ranges left out.

With ``--general-red`` it also keeps the general sign detector's red candidates (the boxes
its CNN mode hands the classifier as possible STOP, YIELD or DO NOT ENTER signs: drums,
cones, red cars, brick), in every frame outside the ``--red-ranges`` (frames where a red or
orange sign a candidate could be is in view, by eye) and not on a labelled sign box: the
negatives that teach the classifier's red classes what is not a red sign.

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
RED_RANGES = Path(__file__).resolve().parent / 'data' / 'red_sign_frames.csv'
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


#: frames before and after each labelled box that it still keeps candidates out: a sign
#: entering or leaving the frame is often left unlabelled on its first and last frames
HOLD = 12


def _add_labelled_boxes(signs: dict, paths: list, hold: int = HOLD) -> None:
    """Add the boxes of keyframe label files (every frame, interpolated, each held ``hold``
    frames either side) to ``signs``."""
    from workzone_ros.tools.eval_color import load_sign_labels
    for path in paths:
        for clip, frames in load_sign_labels(Path(path)).items():
            for k, boxes in frames.items():
                for f in range(k - hold, k + hold + 1):
                    signs[clip.removesuffix('.mp4')][f] += [(b.x, b.y, b.w, b.h)
                                                            for b, _ in boxes]


def _sign_ranges(path: Path, content: str = 'workzone_sign') -> dict:
    """clip -> [(first, last)] frame ranges of ``content`` in a ranges file."""
    out: dict = defaultdict(list)
    with open(path) as fh:
        rows = csv.DictReader(line for line in fh if not line.startswith('#'))
        need = {'clip', 'first_frame', 'last_frame', 'content'}
        if not need <= set(rows.fieldnames or ()):
            raise ValueError(f'{path}: a ranges file needs the columns {sorted(need)}')
        for r in rows:
            if r['content'] == content:
                out[r['clip'].removesuffix('.mp4')].append(
                    (int(r['first_frame']), int(r['last_frame'])))
    return out


def mine_clip(video: Path, proposer, signs: dict, ranges: list, step: int, min_size: int,
              out: Path, writer, general=None, red_ranges: tuple = ()) -> int:
    """Write one clip's background crops (and, with a ``general`` sign detector, its red
    candidates outside ``red_ranges``); returns how many."""
    n = 0
    for k, img in frames_of(video):
        if k % step:
            continue
        if not any(a <= k <= b for a, b in ranges):
            boxes = [p.box for p in proposer.propose(img)]
            n += _keep(img, video.stem, k, boxes, signs.get(k, []), min_size, 'proposal',
                       out, writer)
        if general is not None and not any(a <= k <= b for a, b in red_ranges):
            boxes = [b for b, c in general.candidate_boxes(img) if c == 'red']
            n += _keep(img, video.stem, k, boxes, signs.get(k, []), min_size, 'general_red',
                       out, writer)
    return n


def _keep(img, clip: str, k: int, boxes: list, signs: list, min_size: int, source: str,
          out: Path, writer) -> int:
    """Write the ``boxes`` at least ``min_size`` px that touch no labelled sign box as
    background crops of frame ``k``; returns how many."""
    import cv2

    boxes = [b for b in boxes if max(b[2:]) >= min_size]
    n = 0
    for j, box in enumerate(boxes):
        if any(_on_sign(box, sign) for sign in signs):
            continue
        name = f'background/{clip}_{k:04d}_{source}_{j}.png'
        cv2.imwrite(str(out / name), crop_box(img, *box))
        writer.writerow([name, 'background', clip, k, *(f'{v:.1f}' for v in box), source, ''])
        n += 1
    return n


def _on_sign(box: tuple, sign: tuple) -> bool:
    """Whether a candidate box touches a labelled sign box: IoU 0.05 or more, a tenth of the
    candidate inside the sign (a piece of its face or legend) or half the sign inside the
    candidate (a flagger holding a small paddle)."""
    x0, y0 = max(box[0], sign[0]), max(box[1], sign[1])
    x1 = min(box[0] + box[2], sign[0] + sign[2])
    y1 = min(box[1] + box[3], sign[1] + sign[3])
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    area, sign_area = box[2] * box[3], sign[2] * sign[3]
    union = area + sign_area - inter
    return (inter >= 0.1 * area or inter >= 0.5 * sign_area
            or (union > 0 and inter >= 0.05 * union))


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
    p.add_argument('--labels', type=Path, nargs='+', metavar='CSV',
                   help='keyframe boxes of every sign (real_sign_boxes.csv format): mine '
                        'inside the ranges too, away from these boxes')
    p.add_argument('--videos', type=Path, default=VIDEOS, help='folder of the clips')
    p.add_argument('--exclude-clip', nargs='*', default=[], metavar='CLIP')
    p.add_argument('--step', type=int, default=6, help='every this many frames (6)')
    p.add_argument('--min-size', type=int, default=16, help='smallest candidate, px (16)')
    p.add_argument('--max-candidates', type=int, default=12, help='proposals per frame (12)')
    p.add_argument('--general-red', action='store_true',
                   help="also keep the general sign detector's red candidates")
    p.add_argument('--red-ranges', type=Path, default=RED_RANGES,
                   help='frames where a red or orange sign is in view (red_sign rows)')
    args = p.parse_args(argv)
    if args.step < 1:
        p.error('--step must be >= 1')
    try:
        proposer = SignProposer(cm.load_model(args.model),
                                ProposalConfig(max_candidates=args.max_candidates))
        signs, ranges = _sign_boxes(args.index), _sign_ranges(args.ranges)
        if args.labels:
            ranges = {}
            _add_labelled_boxes(signs, args.labels)
        red = _sign_ranges(args.red_ranges, 'red_sign') if args.general_red else {}
        general = _general_detector() if args.general_red else None
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
                          args.min_size, out, writer, general, tuple(red.get(v.stem, ())))
            print(f'{v.stem}: {n} background crops', file=sys.stderr, flush=True)
    return 0


def _general_detector():
    """The general sign detector in its CNN mode (its candidates need no classifier)."""
    from workzone_ros.core.general import GeneralSignDetector
    return GeneralSignDetector()


if __name__ == '__main__':
    sys.exit(main())
