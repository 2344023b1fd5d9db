"""Seed 001 Table II on synthetic bags: detection only vs detection + tracking, and peers.

``python -m workzone_ros.tools.eval_tracker BAG [BAG ...] [--json OUT] [--overlay PNG]``
(the lead wires ``workzone-ros evaluate tracker`` to :func:`main`).

For every camera frame of each bag the detector runs once (the colour detector core,
``workzone_ros.core.detection.ColorDetector``; ``--detector gt`` replaces it with ground-truth
boxes with simulated misses and jitter), and the same detections feed several trackers in
lockstep, all from the same starts on the same frames:

* ``detection_only``: seed 001's baseline (detections are the output);
* ``meanshift``: our tracker (``TrackerConfig()`` defaults);
* ``meanshift_seed``: seed 001's exact rule (plain ``sqrt(t_u / c_u)`` weights, scale by the
  best Bhattacharyya coefficient alone);
* ``meanshift_no_guard``: ours without the regulatory two-colour guard (whole-box model);
* ``camshift``: OpenCV's ``cv2.CamShift`` on a hue back-projection (same track life).

Quantities (seed 001, IV and Table II), per bag and per configuration:

* evaluable signs: work-zone signs (``category == 'workzone'``) at least ``--min-size`` px on
  both sides and at least half visible;
* ``tracked_frames``: sign-frames from the first frame where the detector found the sign
  (IoU >= tau) onward -- "the frames which were executed on the tracking"; precision and
  recall are computed on these only, for every configuration alike;
* ``precision`` / ``recall`` (area-based, seed 001: Area(o n g) / Area(o) and / Area(g)) of
  the best output box with IoU > tau, averaged over matched sign-frames; ``match_rate`` is
  the share of tracked frames with such a box;
* ``missed_by_detector`` / ``covered``: tracked sign-frames with no matching detection, and
  those of them that a ``tracking`` output matched (also as distinct signs);
* ``false_tracking``: ``tracking`` outputs that overlap no work-zone sign (IoU < 0.3 with
  every one, whatever its size), of which ``on_drums``: overlapping a GT drum;
* ``ms_per_track_frame``: p50 / p99 localisation time per track and frame.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any, Optional

import numpy as np

__all__ = ['main', 'CONFIGS', 'evaluate_bag', 'area_pr']

TAU = 0.5


def _configs():
    from workzone_ros.core.tracking import TrackerConfig
    ours = TrackerConfig()
    return {
        'detection_only': replace(ours, mode='detection_only'),
        'meanshift': ours,
        'meanshift_seed': replace(ours, background_weighting=False, surround_weight=0.0),
        'meanshift_no_guard': replace(ours, anchor_on_color=False),
        'camshift': replace(ours, method='camshift'),
    }


CONFIGS = ('detection_only', 'meanshift', 'meanshift_seed', 'meanshift_no_guard', 'camshift')


def _xywh(b) -> tuple[float, float, float, float]:
    return (float(b.x), float(b.y), float(b.w), float(b.h))


def _iou(a, b) -> float:
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def area_pr(o, g) -> tuple[float, float]:
    """Seed 001's area-based precision and recall of output box ``o`` for truth ``g``."""
    iw = min(o[0] + o[2], g[0] + g[2]) - max(o[0], g[0])
    ih = min(o[1] + o[3], g[1] + g[3]) - max(o[1], g[1])
    inter = max(0.0, iw) * max(0.0, ih)
    return inter / max(o[2] * o[3], 1e-9), inter / max(g[2] * g[3], 1e-9)


# --- detectors ------------------------------------------------------------------------------

class _ColorDetector:
    name = 'color'

    def __init__(self, model_path: Optional[str]) -> None:
        from workzone_ros.core.color_model import default_model, load_model
        from workzone_ros.core.detection import ColorDetector, DetectorConfig
        if model_path:
            model = load_model(model_path)
            self.name = f'color (learned model {model_path})'
        else:
            model = default_model()
            self.name = 'color (default_model(): seed 004 HSV orange range, no trained model)'
        self.det = ColorDetector(model, DetectorConfig(colors=('orange',)))

    def __call__(self, frame, gt):
        return self.det.detect(frame)


class _GtDetector:
    """Ground-truth boxes of evaluable work-zone signs, with misses (in bursts) and jitter."""

    def __init__(self, miss: float, jitter: float, seed: int, min_size: float) -> None:
        self.rng = np.random.default_rng(seed)
        self.miss, self.jitter, self.min_size = miss, jitter, min_size
        self.missing: dict[int, int] = {}
        self.name = f'gt (miss {miss:.0%} in bursts of 1-4 frames, jitter {jitter:.0%})'

    def __call__(self, frame, gt):
        from workzone_ros.interfaces import Box, Detection
        out = []
        for s in gt.signs:
            if s.category != 'workzone' or min(s.box.w, s.box.h) < self.min_size:
                continue
            left = self.missing.get(s.sign_id, 0)
            if left > 0:
                self.missing[s.sign_id] = left - 1
                continue
            if self.rng.random() < self.miss / 2.5:
                self.missing[s.sign_id] = int(self.rng.integers(0, 4))
                continue
            j = self.rng.normal(0, self.jitter, 4)
            b = s.box
            out.append(Detection(box=Box(x=b.x + j[0] * b.w, y=b.y + j[1] * b.h,
                                         w=b.w * (1 + j[2]), h=b.h * (1 + j[3])),
                                 confidence=0.9))
        return out


# --- the run --------------------------------------------------------------------------------

def _frames(bag: str):
    """(image BGR, GtSigns) pairs by exact stamp, in order."""
    from workzone_ros.bagio import read_messages
    from workzone_ros.interfaces import GtSigns, decode
    images: dict[int, Any] = {}
    gts: dict[int, Any] = {}
    for topic, _, msg in read_messages(bag, ['/camera/image_raw', '/groundtruth/signs']):
        if topic == '/camera/image_raw':
            ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            if msg.encoding not in ('bgr8', 'rgb8'):
                raise SystemExit(f'{bag}: unsupported image encoding {msg.encoding}')
            img = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)[
                :, :msg.width * 3].reshape(msg.height, msg.width, 3)
            if msg.encoding == 'rgb8':
                img = img[..., ::-1]
            images[ns] = np.ascontiguousarray(img)
        else:
            g = decode(msg.data, GtSigns)
            ns = g.header.stamp.to_ns()
            gts[ns] = g
        if ns in images and ns in gts:
            yield ns, images.pop(ns), gts.pop(ns)
            for k in [k for k in images if k < ns]:
                del images[k]
            for k in [k for k in gts if k < ns]:
                del gts[k]


def evaluate_bag(bag: str, detector, min_size: float, max_frames: int = 0,
                 overlay: Optional[list] = None) -> dict:
    """Run every configuration on one bag; returns the per-configuration figures."""
    from workzone_ros.core.tracking import MultiTracker
    cfgs = _configs()
    trackers = {k: MultiTracker(c) for k, c in cfgs.items()}
    started: set[int] = set()              # sign ids the detector has found once
    acc = {k: defaultdict(float) for k in cfgs}
    covered_ids = {k: set() for k in cfgs}
    missed_ids: set[int] = set()
    false_ids = {k: set() for k in cfgs}
    drum_ids = {k: set() for k in cfgs}
    times = {k: [] for k in cfgs}
    reg = {k: defaultdict(float) for k in cfgs}
    n_frames = 0
    det_drum_fp = 0
    weather = ''
    for ns, frame, gt in _frames(bag):
        n_frames += 1
        weather = gt.weather
        dets = detector(frame, gt)
        det_boxes = [_xywh(d.box) for d in dets]
        wz = [s for s in gt.signs if s.category == 'workzone']
        evaluable = [s for s in wz if min(s.box.w, s.box.h) >= min_size
                     and s.visible_fraction >= 0.5]
        drums = [_xywh(d.box) for d in gt.distractors if d.kind == 'drum']
        for b in det_boxes:
            if all(_iou(b, _xywh(s.box)) < 0.3 for s in wz) and \
                    any(_iou(b, d) >= 0.3 for d in drums):
                det_drum_fp += 1
        det_hit = {}
        for s in evaluable:
            g = _xywh(s.box)
            det_hit[s.sign_id] = any(_iou(b, g) >= TAU for b in det_boxes)
            if det_hit[s.sign_id]:
                started.add(s.sign_id)
        frame_out = {}
        for name, tracker in trackers.items():
            out = tracker.step(frame, dets)
            frame_out[name] = out
            times[name] += tracker.last_localise_s
            a = acc[name]
            boxes = [(_xywh(t.box), t.source, t.track_id) for t in out]
            for s in evaluable:
                if s.sign_id not in started:
                    continue
                g = _xywh(s.box)
                best, bo, bsrc = 0.0, None, None
                for b, src, _ in boxes:
                    v = _iou(b, g)
                    if v > best:
                        best, bo, bsrc = v, b, src
                a['tracked_frames'] += 1
                two = s.class_key in ('work_zone_begin', 'work_zone_speed_limit')
                if two:
                    reg[name]['frames'] += 1
                if best > TAU:
                    p, r = area_pr(bo, g)
                    a['matched'] += 1
                    a['precision_sum'] += p
                    a['recall_sum'] += r
                    if two:
                        reg[name]['matched'] += 1
                        reg[name]['precision_sum'] += p
                        reg[name]['recall_sum'] += r
                if not det_hit[s.sign_id]:
                    a['missed_by_detector'] += 1
                    if name == 'meanshift':
                        missed_ids.add(s.sign_id)
                    if any(src == 'tracking' and _iou(b, g) > TAU for b, src, _ in boxes):
                        a['covered'] += 1
                        covered_ids[name].add(s.sign_id)
            for b, src, tid in boxes:
                if src != 'tracking':
                    continue
                a['tracking_outputs'] += 1
                if all(_iou(b, _xywh(s.box)) < 0.3 for s in wz):
                    a['false_tracking'] += 1
                    false_ids[name].add(tid)
                    if any(_iou(b, d) >= 0.3 or _ioa(d, b) >= 0.5 for d in drums):
                        a['false_tracking_on_drums'] += 1
                        drum_ids[name].add(tid)
        if overlay is not None:
            overlay.append((ns, frame, gt, dets, frame_out['meanshift']))
        if max_frames and n_frames >= max_frames:
            break
    res: dict[str, Any] = {'bag': bag, 'frames': n_frames, 'weather': weather,
                           'detector_false_alarms_on_drums': det_drum_fp,
                           'signs_missed_by_detector': len(missed_ids)}
    for name in cfgs:
        a = acc[name]
        m = max(a['matched'], 1)
        t = np.array(times[name]) * 1e3
        r = reg[name]
        res[name] = {
            'tracked_frames': int(a['tracked_frames']),
            'match_rate': _r(a['matched'] / max(a['tracked_frames'], 1)),
            'precision': _r(a['precision_sum'] / m),
            'recall': _r(a['recall_sum'] / m),
            'missed_by_detector': int(a['missed_by_detector']),
            'covered': int(a['covered']),
            'covered_fraction': _r(a['covered'] / max(a['missed_by_detector'], 1)),
            'covered_signs': len(covered_ids[name]),
            'tracking_outputs': int(a['tracking_outputs']),
            'false_tracking': int(a['false_tracking']),
            'false_tracks': len(false_ids[name]),
            'false_tracking_on_drums': int(a['false_tracking_on_drums']),
            'false_tracks_on_drums': len(drum_ids[name]),
            'two_colour_frames': int(r['frames']),
            'two_colour_match_rate': _r(r['matched'] / max(r['frames'], 1)),
            'two_colour_precision': _r(r['precision_sum'] / max(r['matched'], 1)),
            'two_colour_recall': _r(r['recall_sum'] / max(r['matched'], 1)),
        }
        if t.size:
            res[name]['ms_per_track_frame_p50'] = _r(float(np.percentile(t, 50)))
            res[name]['ms_per_track_frame_p99'] = _r(float(np.percentile(t, 99)))
            res[name]['track_frames_timed'] = int(t.size)
    return res


def _ioa(a, b) -> float:
    """Area of a n b over the area of b."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    return iw * ih / max(b[2] * b[3], 1e-9)


def _r(v: float) -> float:
    return round(float(v), 4)


# --- overlay --------------------------------------------------------------------------------

def write_overlay(path: str, frames: list, n: int = 8) -> Optional[str]:
    """A strip of frames with GT (yellow), detections (red) and track boxes with ids (blue).

    Picks ``n`` frames spread over those where a track runs on its own; crops each around
    the tracks and scales it to 320 x 240.
    """
    import cv2
    pick = [f for f in frames if any(t.source == 'tracking' for t in f[4])]
    if not pick:
        return None
    idx = np.linspace(0, len(pick) - 1, min(n, len(pick))).round().astype(int)
    tiles = []
    for i in idx:
        ns, frame, gt, dets, out = pick[i]
        img = frame.copy()
        for s in gt.signs:
            if s.category == 'workzone':
                x, y, w, h = (int(round(v)) for v in _xywh(s.box))
                _dotted(img, (x, y), (x + w, y + h), (0, 255, 255))
        for d in dets:
            x, y, w, h = (int(round(v)) for v in _xywh(d.box))
            cv2.rectangle(img, (x - 1, y - 1), (x + w + 1, y + h + 1), (0, 0, 255), 1)
        for t in out:
            x, y, w, h = (int(round(v)) for v in _xywh(t.box))
            col = (255, 80, 0) if t.source == 'tracking' else (0, 0, 255)
            cv2.rectangle(img, (x, y), (x + w, y + h), col, 2)
            cv2.putText(img, f'{t.track_id}{"T" if t.source == "tracking" else "D"}',
                        (x, max(10, y - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, col, 1,
                        cv2.LINE_AA)
        tb = [_xywh(t.box) for t in out if t.source == 'tracking']
        cx = np.mean([b[0] + b[2] / 2 for b in tb])
        cy = np.mean([b[1] + b[3] / 2 for b in tb])
        side = max(160, int(3 * max(max(b[2], b[3]) for b in tb)))
        hw, hh = side, int(side * 0.75)
        x0 = int(min(max(cx - hw / 2, 0), img.shape[1] - hw)) if hw < img.shape[1] else 0
        y0 = int(min(max(cy - hh / 2, 0), img.shape[0] - hh)) if hh < img.shape[0] else 0
        crop = img[y0:y0 + hh, x0:x0 + hw]
        tile = cv2.resize(crop, (320, 240), interpolation=cv2.INTER_AREA)
        cv2.putText(tile, f't={ns / 1e9 % 1000:.2f}s', (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
    while len(tiles) % 4:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[i:i + 4]) for i in range(0, len(tiles), 4)]
    strip = np.vstack(rows)
    cv2.imwrite(path, strip)
    return path


def _dotted(img, p0, p1, col):
    import cv2
    x0, y0 = p0
    x1, y1 = p1
    for x in range(x0, x1 + 1, 4):
        cv2.line(img, (x, y0), (min(x + 1, x1), y0), col, 1)
        cv2.line(img, (x, y1), (min(x + 1, x1), y1), col, 1)
    for y in range(y0, y1 + 1, 4):
        cv2.line(img, (x0, y), (x0, min(y + 1, y1)), col, 1)
        cv2.line(img, (x1, y), (x1, min(y + 1, y1)), col, 1)


# --- CLI ------------------------------------------------------------------------------------

def main(argv: Optional[list[str]] = None) -> int:
    """Evaluate the tracker on synthetic bags; prints a table and optionally writes JSON."""
    p = argparse.ArgumentParser(prog='workzone-ros evaluate tracker', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bags', nargs='+', help='synthetic bag directories (workzone-ros synth)')
    p.add_argument('--detector', choices=('color', 'gt'), default='color',
                   help='colour detector core (default) or GT boxes with simulated misses')
    p.add_argument('--color-model', default=None, help='trained colour model (.npz)')
    p.add_argument('--miss', type=float, default=0.3, help='gt detector: miss rate')
    p.add_argument('--jitter', type=float, default=0.03, help='gt detector: box jitter')
    p.add_argument('--min-size', type=float, default=12.0,
                   help='evaluable signs: smallest side in px (default 12)')
    p.add_argument('--max-frames', type=int, default=0, help='stop after N frames per bag')
    p.add_argument('--json', help='write the figures here')
    p.add_argument('--overlay', help='write a tracking overlay strip PNG (first bag)')
    args = p.parse_args(argv)
    import cv2
    cv2.setNumThreads(1)
    results = []
    for k, bag in enumerate(args.bags):
        if not Path(bag).exists():
            print(f'{bag}: no such bag', file=sys.stderr)
            return 2
        if args.detector == 'color':
            try:
                det = _ColorDetector(args.color_model)
            except Exception as exc:  # noqa: BLE001 - fall back and say so
                print(f'colour detector unavailable ({exc}); using GT boxes', file=sys.stderr)
                det = _GtDetector(args.miss, args.jitter, k, args.min_size)
        else:
            det = _GtDetector(args.miss, args.jitter, k, args.min_size)
        frames: Optional[list] = [] if args.overlay and k == 0 else None
        res = evaluate_bag(bag, det, args.min_size, args.max_frames, frames)
        res['detector'] = det.name
        results.append(res)
        _print(res)
        if frames:
            out = write_overlay(args.overlay, frames)
            print(f'overlay: {out}')
            frames.clear()
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, 'w') as fh:
            json.dump(results, fh, indent=2)
        print(f'figures written to {args.json}')
    return 0


def _print(res: dict) -> None:
    print(f"\n== {res['bag']}  ({res['frames']} frames, {res['weather']}, detector "
          f"{res['detector']})")
    print(f"   detector false alarms on drums: {res['detector_false_alarms_on_drums']}; "
          f"signs the detector missed at least once: {res['signs_missed_by_detector']}")
    cols = ('tracked_frames', 'match_rate', 'precision', 'recall', 'missed_by_detector',
            'covered', 'covered_fraction', 'false_tracking', 'false_tracks_on_drums',
            'two_colour_match_rate', 'two_colour_recall', 'ms_per_track_frame_p50')
    print('   ' + 'config'.ljust(20) + ''.join(c[:14].rjust(15) for c in cols))
    for name in CONFIGS:
        r = res[name]
        print('   ' + name.ljust(20) + ''.join(str(r.get(c, '-')).rjust(15) for c in cols))


if __name__ == '__main__':
    sys.exit(main())
