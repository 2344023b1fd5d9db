"""Per-stage accuracy of ``workzone-ros evaluate workzone --signs pipeline``.

The in-process pipeline (:mod:`workzone_ros.tools.workzone_pipeline`) records per frame the
colour detector's boxes, the published track boxes and the classifier's answer for each
track (``Frame.stages``); the bag's ``/groundtruth/signs`` gives the truth of the same
frame.  A sign is *legible* by the evaluator's rule (``--legible-px``, half visible); only
legible **work-zone** signs are to be found (the detector looks for orange).  Matching is
one to one, best IoU first, at IoU >= 0.5 (``eval_color.match_frame``, the Table I
matcher of ``evaluate color``).  Per bag and pooled over bags (sums of the counts):

* **detection** (Seo et al. Table I form): ``precision`` = matched detections / (detections
  - ``ignored``), where ``ignored`` are the unmatched detections at IoU >= 0.5 on a GT sign
  that is not a legible work-zone sign (a sign too small or hidden to count, or a general
  sign: neither right nor wrong); ``recall`` = matched legible signs / legible signs (sign
  frames); ``false_per_frame`` = detections overlapping no ground-truth sign of any kind
  (legible or not, work-zone or general) at IoU >= 0.3, per frame;
* **tracking**: ``coverage`` = legible sign frames matched by a published track box /
  legible sign frames; ``off_sign_per_frame`` = track boxes overlapping no ground-truth sign
  of any kind at IoU >= 0.3, per frame;
* **classification** (Table III form), on the track boxes matched to a legible sign:
  ``accuracy`` = boxes given the sign's own class / matched boxes (``unknown``, not
  classified, and ``background``, answer not published, are wrong answers);
  ``macro_precision`` / ``macro_recall`` = the mean over the true classes present of
  precision (boxes of the class given it / boxes given it; 0 when no box was given it) and
  recall (boxes of the class given it / boxes of the class); ``confusion`` truth -> answer
  -> boxes; ``background_as_workzone_per_frame`` = track boxes on no sign (as above) given
  a work-zone class, per frame;
* **lidar**: not run in process (``workzone-ros evaluate lidar``).

``--signs gt`` has no stages: the key is null there.
"""
from __future__ import annotations

from collections import Counter
from typing import Optional, Sequence

from workzone_ros.core import signs as catalogue
from workzone_ros.core.track.boxes import box_iou as _iou

__all__ = ['IOU', 'FALSE_IOU', 'LIDAR_NOTE', 'match', 'frame_counts', 'stage_figures',
           'pool_stages', 'stage_lines', 'report_lines']

IOU = 0.5            # a detection / track box matches a legible sign
FALSE_IOU = 0.3      # a box overlapping no GT sign this much is on no sign
LIDAR_NOTE = 'not run by the in-process pipeline: workzone-ros evaluate lidar'
_COUNTS = ('frames', 'detections', 'signs', 'det_matched', 'det_ignored', 'det_false',
           'track_boxes',
           'track_matched', 'track_off_sign', 'background_as_workzone')


def match(boxes: Sequence, gts: Sequence, tau: float = IOU) -> list[tuple[int, int]]:
    """One-to-one (box index, gt index) pairs at IoU >= tau, best IoU first (``(x, y, w,
    h)`` boxes); ``eval_color.match_frame``, whose test is IoU > tau."""
    from workzone_ros.interfaces import Box
    from workzone_ros.tools.eval_color import match_frame

    def box(b):
        return Box(x=float(b[0]), y=float(b[1]), w=float(b[2]), h=float(b[3]))
    pairs = match_frame([box(b) for b in boxes], [box(g) for g in gts], tau - 1e-9)
    return [(i, j) for i, j, *_ in pairs]


def _on_no_sign(b, gt_all: Sequence) -> bool:
    return not any(_iou(b, g) >= FALSE_IOU for g in gt_all)


def _ignored(dets: list, matched: set, others: Sequence) -> int:
    return sum(1 for i, b in enumerate(dets) if i not in matched
               and any(_iou(b, g) >= IOU for g in others))


def frame_counts(st: dict, counts: Counter, confusion: dict) -> None:
    """Add one frame's ``Frame.stages`` to the counts and the (truth -> answer) confusion."""
    gts = [tuple(b) for _, b in st['gt_wz']]
    dets = [tuple(b) for b in st['dets']]
    tracks = [(tuple(b), c) for b, c in st['tracks']]
    counts['frames'] += 1
    counts['signs'] += len(gts)
    counts['detections'] += len(dets)
    gt_all = gts + [tuple(b) for b in st['gt_other']]
    matched = {i for i, _ in match(dets, gts)}
    counts['det_matched'] += len(matched)
    counts['det_ignored'] += _ignored(dets, matched, st['gt_other'])
    counts['det_false'] += sum(_on_no_sign(b, gt_all) for b in dets)
    counts['track_boxes'] += len(tracks)
    pairs = match([b for b, _ in tracks], gts)
    counts['track_matched'] += len(pairs)
    for i, j in pairs:
        row = confusion.setdefault(st['gt_wz'][j][0], {})
        row[tracks[i][1]] = row.get(tracks[i][1], 0) + 1
    for b, c in tracks:
        if _on_no_sign(b, gt_all):
            counts['track_off_sign'] += 1
            counts['background_as_workzone'] += c in catalogue.WORKZONE_KEYS


def _ratio(a: int, b: int) -> Optional[float]:
    return round(a / b, 4) if b else None


def _classification(confusion: dict, counts: Counter) -> dict:
    given: Counter = Counter()
    for row in confusion.values():
        given.update(row)
    per_class = {}
    for c, row in sorted(confusion.items()):
        n, ok = sum(row.values()), row.get(c, 0)
        per_class[c] = {'boxes': n, 'given': given[c], 'correct': ok,
                        'precision': round(ok / given[c], 4) if given[c] else 0.0,
                        'recall': _ratio(ok, n)}
    boxes = sum(given.values())
    correct = sum(v['correct'] for v in per_class.values())
    k = len(per_class)
    return {'boxes': boxes, 'correct': correct, 'accuracy': _ratio(correct, boxes),
            'macro_precision': round(sum(v['precision'] for v in per_class.values()) / k, 4)
            if k else None,
            'macro_recall': round(sum(v['recall'] for v in per_class.values()) / k, 4)
            if k else None,
            'classes': per_class, 'confusion': {c: dict(sorted(r.items()))
                                                for c, r in sorted(confusion.items())},
            'background_boxes': counts['track_off_sign'],
            'background_as_workzone': counts['background_as_workzone'],
            'background_as_workzone_per_frame': _ratio(counts['background_as_workzone'],
                                                       counts['frames'])}


def _figures(counts: Counter, confusion: dict) -> dict:
    c = counts
    return {
        'frames': c['frames'], 'lidar': LIDAR_NOTE,
        'detection': {'detections': c['detections'], 'signs': c['signs'],
                      'matched': c['det_matched'], 'ignored': c['det_ignored'],
                      'precision': _ratio(c['det_matched'],
                                          c['detections'] - c['det_ignored']),
                      'recall': _ratio(c['det_matched'], c['signs']),
                      'false': c['det_false'],
                      'false_per_frame': _ratio(c['det_false'], c['frames'])},
        'tracking': {'track_boxes': c['track_boxes'], 'signs': c['signs'],
                     'covered': c['track_matched'],
                     'coverage': _ratio(c['track_matched'], c['signs']),
                     'off_sign': c['track_off_sign'],
                     'off_sign_per_frame': _ratio(c['track_off_sign'], c['frames'])},
        'classification': _classification(confusion, c),
        'counts': {k: c[k] for k in _COUNTS},
    }


def stage_figures(frames: Sequence) -> Optional[dict]:
    """The figures of one bag (module docstring); None when no frame has stages."""
    counts: Counter = Counter()
    confusion: dict = {}
    for f in frames:
        if f.stages is not None:
            frame_counts(f.stages, counts, confusion)
    return _figures(counts, confusion) if counts['frames'] else None


def pool_stages(per_bag: Sequence[Optional[dict]]) -> Optional[dict]:
    """The figures over bags: their counts and confusions summed; None without stages."""
    counts: Counter = Counter()
    confusion: dict = {}
    for s in per_bag:
        if not s:
            continue
        counts.update(s['counts'])
        for t, row in s['classification']['confusion'].items():
            mine = confusion.setdefault(t, {})
            for p, n in row.items():
                mine[p] = mine.get(p, 0) + n
    return _figures(counts, confusion) if counts['frames'] else None


def _f(v) -> str:
    return '-' if v is None else f'{v:.3f}'


def stage_lines(s: Optional[dict]) -> list[str]:
    """A few console lines of one bag's or the pooled stage figures."""
    if not s:
        return ['stages: n/a (--signs gt: no detector, tracker or classifier)']
    d, t, c = s['detection'], s['tracking'], s['classification']
    return [f"detection (Table I): precision {_f(d['precision'])} recall {_f(d['recall'])} "
            f"({d['matched']}/{d['signs']} legible sign frames; {d['ignored']} on illegible "
            f"or general signs ignored), false {_f(d['false_per_frame'])}/frame",
            f"tracking: coverage {_f(t['coverage'])}, off-sign boxes "
            f"{_f(t['off_sign_per_frame'])}/frame",
            f"classification (Table III): accuracy {_f(c['accuracy'])} ({c['correct']}/"
            f"{c['boxes']}), macro P/R {_f(c['macro_precision'])}/{_f(c['macro_recall'])}, "
            f"background as work zone {_f(c['background_as_workzone_per_frame'])}/frame",
            f'LiDAR: {LIDAR_NOTE}']


def report_lines(results: Sequence[dict], pooled: Optional[dict]) -> list[str]:
    """The Markdown section of the ``--report``."""
    head = ['## Per-stage accuracy', '']
    if not pooled:
        return head + ['n/a: `--signs gt` runs no detector, tracker or classifier.', '']
    rows = [(r['bag'].rstrip('/').split('/')[-1], r.get('stages')) for r in results
            if 'error' not in r] + [('**pooled**', pooled)]
    lines = head + [
        'Against the legible ground-truth work-zone signs of each frame (IoU >= 0.5, one to '
        'one; "on no sign" = IoU < 0.3 with every GT sign). Definitions: '
        '`workzone_ros.tools.workzone_stages`.', '',
        '| bag | frames | det. precision | det. recall | false det./frame | track coverage '
        '| off-sign tracks/frame | class. accuracy | macro P | macro R | background as '
        'work zone/frame |', '|---|' + '---|' * 10]
    for name, s in rows:
        if not s:
            continue
        d, t, c = s['detection'], s['tracking'], s['classification']
        lines.append(f"| {name} | {s['frames']} | {_f(d['precision'])} | {_f(d['recall'])} | "
                     f"{_f(d['false_per_frame'])} | {_f(t['coverage'])} | "
                     f"{_f(t['off_sign_per_frame'])} | {_f(c['accuracy'])} | "
                     f"{_f(c['macro_precision'])} | {_f(c['macro_recall'])} | "
                     f"{_f(c['background_as_workzone_per_frame'])} |")
    lines += ['', f'LiDAR: {LIDAR_NOTE.split(": ")[0]} (`workzone-ros evaluate lidar`).', '']
    conf = pooled['classification']['confusion']
    if conf:
        cols = sorted({p for row in conf.values() for p in row})
        lines += ['Classification of the matched track boxes (pooled, truth \\ answer):', '',
                  '| truth \\ answer | ' + ' | '.join(cols) + ' |',
                  '|---|' + '---|' * len(cols)]
        lines += [f'| {t} | ' + ' | '.join(str(row.get(p, '')) for p in cols) + ' |'
                  for t, row in conf.items()]
        lines.append('')
    return lines
