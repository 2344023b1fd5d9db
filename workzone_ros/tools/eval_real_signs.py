"""``workzone-ros evaluate real_signs``: detector + tracker + classifier on the real dashcam clips.

Per clip of ``../shared/realdata/us_workzone_video`` (camera only, native size), every frame
goes through the colour detector, the mean-shift tracker and the classifier node's rules
(:class:`workzone_ros.core.recognition.SignRecognizer`), and the published signs are compared
with the hand-made labels (evaluation only, never trained on):

* ``sign_share``: of the frames where the labelled work-zone sign is visible
  (``tools/data/real_sign_boxes.csv``), the share where a work-zone class is reported on a
  box with IoU >= 0.3 with the label (target: >= 0.8);
* ``false_per_frame``: work-zone signs reported per frame in the frames outside every
  ``workzone_sign`` range of ``tools/data/real_clip_ranges.csv`` (target <= 0.05).

The classifier's answers on each frame's tracks go back to the tracker before the next frame
(``MultiTracker.confirm``), as the ``tracker`` node hears ``/workzone/signs``.

Say which data trained the model: a model trained on a clip's crops is not measured on it.
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import Optional

from workzone_ros.core.proposals import MODES
from workzone_ros.core.recognition import PROPOSAL_PRIOR
from workzone_ros.resources import config_path
from workzone_ros.tools.clips import find_video
from workzone_ros.tools.eval_color import REAL_LABELS, load_sign_labels
from workzone_ros.tools.outputs import print_json, write_contact_sheet

__all__ = ['evaluate_clip', 'main']

REAL_DEFAULT = Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata' \
    / 'us_workzone_video'
RANGES = Path(__file__).resolve().parent / 'data' / 'real_clip_ranges.csv'
CLIPS = ('charlotte', 'denver', 'houston', 'minneapolis', 'chicago', 'san_francisco')


def sign_ranges(path: Path = RANGES) -> dict[str, list[tuple[int, int]]]:
    """clip file -> frame ranges where a work-zone sign is in view."""
    out: dict[str, list[tuple[int, int]]] = {}
    with open(path) as fh:
        for row in csv.DictReader(line for line in fh if not line.startswith('#')):
            if row['content'] == 'workzone_sign':
                out.setdefault(row['clip'], []).append((int(row['first_frame']),
                                                        int(row['last_frame'])))
    return out


def _draw(img, labels, dets, items, signs, text: str):
    """One contact-sheet tile: labels (white), proposals (grey), rule detections (green),
    tracks (blue), work-zone signs (orange, with the class) and rejected ones (red)."""
    import cv2
    out = img.copy()

    def rect(b, color, t=1):
        cv2.rectangle(out, (int(b.x), int(b.y)), (int(b.x + b.w), int(b.y + b.h)), color, t)

    for label in labels:
        rect(label, (255, 255, 255), 1)
    for d in dets:
        rect(d.box, (150, 150, 150) if d.proposal else (0, 200, 0))
    for it in items:
        if hasattr(it, 'track_id'):
            rect(it.box, (255, 120, 0))
    for s in signs:
        wz = s.category == 'workzone'
        rect(s.box, (0, 140, 255) if wz else (0, 0, 200), 2 if wz else 1)
        if wz:
            cv2.putText(out, f'{s.class_key} {s.score:.2f}', (int(s.box.x), int(s.box.y) - 3),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 140, 255), 1)
    cv2.putText(out, text, (5, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 2)
    return out


def evaluate_clip(path: Path, model, hfov_deg: float, max_frames: int = 0,
                  proposer=None, track: bool = True, tiles: Optional[list] = None,
                  tile_every: int = 15, rules: str = 'on',
                  labels: Optional[dict] = None, ranges: Optional[dict] = None,
                  prior: float = PROPOSAL_PRIOR, proposals: str = 'auto') -> dict:
    """The figures of one clip (module docstring).

    ``proposer``: a :class:`~workzone_ros.core.proposals.SignProposer` whose candidates are
    added to the detections where ``proposals`` (the node's parameter: ``auto``, ``on`` or
    ``off``) runs them, as the ``color_detector`` node does; ``track`` false classifies the
    detections themselves (the graph without the tracker).  ``tiles``: every
    ``tile_every``-th labelled sign frame is drawn into it (contact sheet).  ``rules``: the
    rule-based detector on, off, or ``auto`` as the node's ``rules`` parameter
    (:func:`~workzone_ros.core.proposals.stage_plan`).  ``labels``: the
    signs, :func:`~workzone_ros.tools.eval_color.load_sign_labels` of a keyframe CSV (None:
    ``tools/data/real_sign_boxes.csv``; a frame with two visible signs counts twice), keyed
    by the clip's file name or its name without the extension.  ``ranges``: the work-zone
    sign ranges, :func:`sign_ranges` of a CSV (None: ``tools/data/real_clip_ranges.csv``).
    ``prior``: the classifier's ``proposal_prior``.

    ``candidate_recall``: of the visible labelled sign frames where the sign is at least 20 px,
    the share where a box given to the classifier (detection, proposal or track) has IoU >= 0.3
    with the label, before any classification.  ``boxes`` / ``sign_boxes``: the rule
    detections and the proposals, and of them those with IoU >= 0.3 with a visible label
    (:func:`proposal_prior`).
    """
    import cv2

    from workzone_ros.core.proposals import detect_frame
    from workzone_ros.core.recognition import RecognitionConfig, SignRecognizer
    from workzone_ros.core.sign_distance import focal_from_fov
    from workzone_ros.core.track import MultiTracker, TrackerConfig
    from workzone_ros.core.track.confirmation import classifier_verdicts
    from workzone_ros.tools.eval_tracker import _ColorDetector
    labels = load_sign_labels() if labels is None else labels
    frames = labels.get(path.name) or labels.get(path.stem, {})
    ranges = sign_ranges() if ranges is None else ranges
    ranges = ranges.get(path.name) or ranges.get(path.stem, [])
    det, tracker = _ColorDetector(None), MultiTracker(TrackerConfig())
    recognizer = SignRecognizer(model, RecognitionConfig(proposal_prior=prior))
    cap = cv2.VideoCapture(str(path))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    n = hits = free = false = k = cands = big = big_hit = 0
    boxes, signs_in = {'rule': 0, 'proposal': 0}, {'rule': 0, 'proposal': 0}
    while not max_frames or k < max_frames:
        ok, img = cap.read()
        if not ok:
            break
        dets = detect_frame(det.det, proposer, img, proposals, rules)[0]
        cands += len(dets)
        shown = [box for box, visible in frames.get(k, ()) if visible]
        for d in dets:
            source = 'proposal' if d.proposal else 'rule'
            boxes[source] += 1
            signs_in[source] += any(d.box.iou(box) >= 0.3 for box in shown)
        items = tracker.step(img, dets, stamp=k / fps) if track else dets
        signs, _ = recognizer.recognize(img, items, focal_from_fov(img.shape[1], hfov_deg))
        if track:      # the answers go back to the tracker, as /workzone/signs to the node
            tracker.confirm(*classifier_verdicts([t.track_id for t in items], signs))
        wz = [s for s in signs if s.category == 'workzone']
        for box in shown:
            n += 1
            hits += any(s.box.iou(box) >= 0.3 for s in wz)
            if max(box.w, box.h) >= 20:
                big += 1
                big_hit += any(d.box.iou(box) >= 0.3 for d in [*dets, *items])
        if tiles is not None and any(m % tile_every == 1 for m in range(n - len(shown) + 1,
                                                                         n + 1)):
            tiles.append(_draw(img, shown, dets, items, signs, f'{path.stem} #{k}'))
        if not any(a <= k <= b for a, b in ranges):
            free += 1
            false += len(wz)
        k += 1
    cap.release()
    return {'frames': k, 'sign_frames': n, 'boxes_per_frame': round(cands / max(k, 1), 2),
            'sign_share': round(hits / n, 3) if n else None,
            'candidate_recall': round(big_hit / big, 3) if big else None,
            'free_frames': free, 'false_per_frame': round(false / free, 3) if free else None,
            'boxes': boxes, 'sign_boxes': signs_in}


def proposal_prior(results: dict) -> Optional[float]:
    """ln(odds that a rule detection is a labelled sign / odds that a proposal is), pooled
    over ``results`` (clip -> :func:`evaluate_clip` figures): the classifier's
    ``proposal_prior`` for this camera and these labels.  None without both kinds of box
    and signs among each."""
    import math
    n = {k: sum(r['boxes'][k] for r in results.values()) for k in ('rule', 'proposal')}
    s = {k: sum(r['sign_boxes'][k] for r in results.values()) for k in ('rule', 'proposal')}
    if any(not 0 < s[k] < n[k] for k in n):
        return None
    odds = {k: s[k] / (n[k] - s[k]) for k in n}
    return round(math.log(odds['rule'] / odds['proposal']), 2)


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; prints one line per clip and the JSON figures."""
    from workzone_ros.core.classifier import DEFAULT_MODEL, ModelError, load_model
    p = argparse.ArgumentParser(prog='workzone-ros evaluate real_signs', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--model', default=str(config_path(DEFAULT_MODEL)))
    p.add_argument('--real', default=str(REAL_DEFAULT), help='folder of the clips')
    p.add_argument('--clips', nargs='*', default=list(CLIPS))
    p.add_argument('--hfov', type=float, default=60.0, help='stated field of view (deg)')
    p.add_argument('--max-frames', type=int, default=0)
    p.add_argument('--proposals', choices=MODES, default='auto',
                   help="the recall-first colour proposals, as color_detector's proposals "
                        "parameter (default auto: on a camera other than the colour model's, "
                        'as the clips are)')
    p.add_argument('--proposals-model', metavar='MODEL', default='',
                   help='colour model with the proposal ranker (default '
                        'config/models/color_proposals.npz)')
    p.add_argument('--max-candidates', type=int, default=12, help='proposals per frame')
    p.add_argument('--sheet', metavar='PNG', help='contact sheet of the labelled sign frames '
                   '(label white, proposals grey, detections green, tracks blue, work-zone '
                   'signs orange with their class, rejected red)')
    p.add_argument('--rules', choices=('auto', 'on', 'off'), default='on',
                   help="the rule-based detector, as color_detector's rules parameter")
    p.add_argument('--no-tracker', action='store_true',
                   help='classify the detections themselves (the graph without the tracker)')
    p.add_argument('--labels', metavar='CSV', default=str(REAL_LABELS),
                   help='keyframe boxes of the signs (default: tools/data/real_sign_boxes.csv; '
                        'tools/data/real_sign_boxes_more.csv holds more signs)')
    p.add_argument('--ranges', metavar='CSV', default=str(RANGES),
                   help='frame ranges of each clip that hold a work-zone sign (content '
                        'workzone_sign), left out of the false signs (default: '
                        'tools/data/real_clip_ranges.csv)')
    p.add_argument('--proposal-prior', type=float, default=PROPOSAL_PRIOR,
                   help="the classifier's proposal_prior (default %(default)s)")
    p.add_argument('--json', metavar='OUT')
    args = p.parse_args(argv)
    try:
        labels = load_sign_labels(Path(args.labels))
        ranges = sign_ranges(Path(args.ranges))
    except (OSError, KeyError, ValueError) as exc:
        print(f'workzone-ros evaluate real_signs: cannot read the labels {args.labels} or '
              f'the ranges {args.ranges}: {exc!r}', file=sys.stderr)
        return 2
    folder = Path(args.real)
    if not folder.is_dir():
        print(f'workzone-ros evaluate real_signs: no such folder: {folder}', file=sys.stderr)
        return 2
    try:
        model = load_model(args.model)
    except ModelError as exc:
        print(f'workzone-ros evaluate real_signs: {exc}', file=sys.stderr)
        return 2
    proposer = None
    if args.proposals != 'off':
        from workzone_ros.core import color_model as cm
        from workzone_ros.core.proposals import ProposalConfig, SignProposer
        ppath = args.proposals_model or str(config_path('models/color_proposals.npz'))
        try:
            proposer = SignProposer(cm.load_model(ppath),
                                    ProposalConfig(max_candidates=args.max_candidates))
        except (cm.ModelError, ValueError) as exc:
            print(f'workzone-ros evaluate real_signs: {exc}', file=sys.stderr)
            return 2
    out = {'model': args.model, 'trained_on': model.metadata.get('sources'),
           'proposals': args.proposals,
           'proposals_model': None if proposer is None else args.proposals_model or 'default',
           'tracker': not args.no_tracker, 'rules': args.rules,
           'proposal_prior': args.proposal_prior, 'clips': {}}
    tiles: list = []
    for name in args.clips:
        try:
            path = find_video(folder, name)
        except FileNotFoundError as exc:
            print(f'{name}: {exc}, skipped', file=sys.stderr)
            continue
        r = evaluate_clip(path, model, args.hfov, args.max_frames, proposer,
                          not args.no_tracker, tiles if args.sheet else None,
                          rules=args.rules, labels=labels, ranges=ranges,
                          prior=args.proposal_prior, proposals=args.proposals)
        out['clips'][name] = r
        print(f"{name:14s} sign frames {r['sign_frames']:4d} share {r['sign_share']}  "
              f"candidate recall {r['candidate_recall']}  boxes/frame {r['boxes_per_frame']}  "
              f"false work-zone signs / frame {r['false_per_frame']} over "
              f"{r['free_frames']} frames", file=sys.stderr, flush=True)
    out['measured_proposal_prior'] = proposal_prior(out['clips'])
    if out['measured_proposal_prior'] is not None:
        print(f"proposal_prior measured on these clips' labels: "
              f"{out['measured_proposal_prior']}", file=sys.stderr)
    if args.sheet and write_contact_sheet(tiles, args.sheet, scale=0.5):
        print(f'contact sheet: {args.sheet}', file=sys.stderr)
    print_json(out, args.json, default=str)
    return 0


if __name__ == '__main__':
    sys.exit(main())
