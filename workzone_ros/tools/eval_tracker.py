"""Lee et al. Table II on synthetic bags: detection only vs detection + tracking, and peers.

``python -m workzone_ros.tools.eval_tracker BAG [BAG ...] [--json OUT] [--overlay PNG]``
(the lead wires ``workzone-ros evaluate tracker`` to :func:`main`).

For every camera frame of each bag the detector runs once (the colour detector core,
``workzone_ros.core.detect.ColorDetector``; ``--detector gt`` replaces it with ground-truth
boxes with simulated misses and jitter), and the same detections feed several trackers in
lockstep, all from the same starts on the same frames:

* ``detection_only``: Lee et al.'s baseline (detections are the output);
* ``meanshift``: our tracker (``TrackerConfig()`` defaults: fusion of tracked and detected
  boxes with an agreeing complete detection's box preferred, shrinking scales, drift guards,
  no tracking output for targets like their surroundings, with white bands or not more
  saturated than their surroundings' median and more colourful (chroma) than them
  (sign-likeness; then one detection suffices to run on its own), containment duplicates
  (orange-top tracks) removed);
* ``meanshift_overwrite``: ours with Lee et al.'s association (the detection overwrites);
* ``meanshift_seed``: Lee et al.'s exact rule (``tracking.seed_config``: plain
  ``sqrt(t_u / c_u)`` weights, five only-larger kernels, best Bhattacharyya coefficient,
  previous centre as start, overwrite, no drift guards; the two-colour guard stays);
* ``meanshift_no_guard``: ours without the regulatory two-colour guard (whole-box model);
* ``camshift``: OpenCV's ``cv2.CamShift`` on a hue back-projection (our track life).

Quantities (Lee et al., IV and Table II; tau = 0.5; see :func:`evaluate_bag`):

* evaluable signs: work-zone signs (``category == 'workzone'``) at least ``--min-size`` px on
  both sides and at least half visible;
* ``run`` sign-frames: from the first frame where a detection matched the sign (IoU >= tau)
  on -- "the frames which were executed on the tracking"; everything is counted on these;
* ``misses``: run sign-frames with no detection at IoU >= tau; ``covered``: those where an
  output of the configuration (any source) has IoU >= tau (also as distinct signs);
* ``precision`` / ``recall`` (area-based, Lee et al.: Area(o n g) / Area(o) and / Area(g)) of
  the best output box with IoU >= tau, averaged over matched run sign-frames; ``match``
  is the share of run sign-frames with such a box;
* false outputs: boxes overlapping no work-zone sign (IoU < 0.3 with each), on drums/cones
  (GT distractors ``drum``/``cone``) or on other non-signs; ``ftrk.*`` are the ``tracking``
  outputs among them (what the tracker adds; ``.ids`` distinct tracks), ``fout.*`` all;
* ``ms.p50``: p50 per track and frame of the localisation (plus the fusion scoring on
  frames where a detection is fused).

Detections can be cached (``--det-cache``) per bag and model file (size, mtime).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any, Optional

import numpy as np

from workzone_ros.bagio import BagError
from workzone_ros.resources import config_path
from workzone_ros.tools.eval_color import REALDATA as _REALDATA

__all__ = ['main', 'CONFIGS', 'evaluate_bag', 'evaluate_real', 'area_pr']

TAU = 0.5
DEFAULT_MODEL = str(config_path('models/color_orange.npz'))


def _configs():
    from workzone_ros.core.track import TrackerConfig, seed_config
    ours = TrackerConfig()
    return {
        'detection_only': replace(ours, mode='detection_only'),
        'meanshift': ours,
        'meanshift_overwrite': replace(ours, association='overwrite'),
        'meanshift_seed': seed_config(ours),
        'meanshift_no_guard': replace(ours, anchor_on_color=False),
        'camshift': replace(ours, method='camshift'),
    }


CONFIGS = ('detection_only', 'meanshift', 'meanshift_overwrite', 'meanshift_seed',
           'meanshift_no_guard', 'camshift')


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
    """Lee et al.'s area-based precision and recall of output box ``o`` for truth ``g``."""
    iw = min(o[0] + o[2], g[0] + g[2]) - max(o[0], g[0])
    ih = min(o[1] + o[3], g[1] + g[3]) - max(o[1], g[1])
    inter = max(0.0, iw) * max(0.0, ih)
    return inter / max(o[2] * o[3], 1e-9), inter / max(g[2] * g[3], 1e-9)


# --- detectors ------------------------------------------------------------------------------

class _ColorDetector:
    """The colour detector core as the ``color_detector`` node builds it (orange only)."""

    name = 'color'

    def __init__(self, model_path: Optional[str]) -> None:
        from workzone_ros.core.color_model import default_model, load_model
        from workzone_ros.core.detect import ColorDetector, DetectorConfig
        path = model_path or DEFAULT_MODEL
        if model_path or os.path.exists(path):
            model = load_model(path)
            st = os.stat(path)
            self.model_file = {'path': path, 'size': st.st_size,
                               'mtime': time.strftime('%Y-%m-%d %H:%M:%S',
                                                      time.localtime(st.st_mtime))}
            self.name = f"color (model {path}, {st.st_size} B, {self.model_file['mtime']})"
            self.key = f'{st.st_size}_{int(st.st_mtime)}'
        else:
            model = default_model()
            self.model_file = None
            self.name = 'color (default_model(): Cahail et al. HSV orange range, no trained model)'
            self.key = 'default'
        bs = tuple(float(v) for v in model.extras.get('box_scale', (1.0, 1.0)))
        self.det = ColorDetector(model, DetectorConfig(colors=('orange',), border_scale=bs))

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
    """(image BGR, GtSigns) pairs by exact stamp, in order (raw or JPEG-compressed images)."""
    from workzone_ros.bagio import read_messages
    from workzone_ros.interfaces import GtSigns, decode
    images: dict[int, Any] = {}
    gts: dict[int, Any] = {}
    topics = ['/camera/image_raw', '/camera/image_raw/compressed', '/groundtruth/signs']
    for topic, _, msg in read_messages(bag, topics):
        if topic == '/camera/image_raw/compressed':
            import cv2
            ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            img = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR)
            if img is None:
                raise SystemExit(f'{bag}: undecodable compressed image ({msg.format})')
            images[ns] = img
        elif topic == '/camera/image_raw':
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


class _CachedDetector:
    """Detections of a bag stored once per (bag, detector, model file): reruns of the
    trackers do not rerun the detector.  The cache is a JSON lines file of Detections."""

    def __init__(self, inner, path: str) -> None:
        from workzone_ros.interfaces import Detections, decode
        self.inner, self.path = inner, path
        self.name = inner.name + ' [cached]'
        self.model_file = getattr(inner, 'model_file', None)
        self.stored: dict[int, Any] = {}
        self.new: list[str] = []
        if os.path.exists(path):
            with open(path) as fh:
                for line in fh:
                    d = decode(line, Detections)
                    self.stored[d.header.stamp.to_ns()] = list(d.detections)

    def __call__(self, frame, gt):
        from workzone_ros.interfaces import Detections, encode
        ns = gt.header.stamp.to_ns()
        if ns in self.stored:
            return self.stored[ns]
        dets = self.inner(frame, gt)
        self.new.append(encode(Detections(header=gt.header, detections=list(dets))))
        return dets

    def flush(self) -> None:
        if self.new:
            with open(self.path, 'a') as fh:
                fh.write('\n'.join(self.new) + '\n')
            self.new.clear()


DRUM_KINDS = ('drum', 'cone')


class _FrameTruth:
    """One frame's ground truth as :func:`evaluate_bag` scores it: the work-zone sign boxes,
    the evaluable signs and the drum and cone boxes."""

    def __init__(self, gt, min_size: float) -> None:
        wz = [s for s in gt.signs if s.category == 'workzone']
        self.wz_boxes = [_xywh(s.box) for s in wz]
        self.evaluable = [s for s in wz if min(s.box.w, s.box.h) >= min_size
                          and s.visible_fraction >= 0.5]
        self.drums = [_xywh(d.box) for d in gt.distractors if d.kind in DRUM_KINDS]

    def false_kind(self, b) -> Optional[str]:
        """None for a box on a work-zone sign, else ``drums`` or ``other``."""
        if any(_iou(b, g) >= 0.3 for g in self.wz_boxes):
            return None
        if any(_iou(b, d) >= 0.3 or _ioa(d, b) >= 0.5 for d in self.drums):
            return 'drums'
        return 'other'


class _BagTally:
    """The counts of :func:`evaluate_bag` over one bag, per configuration."""

    def __init__(self, cfgs: dict) -> None:
        self.started: set[int] = set()              # sign ids the detector has found once
        self.acc = {k: defaultdict(float) for k in cfgs}
        self.ids = {k: defaultdict(set) for k in cfgs}
        self.missed_ids: set[int] = set()
        self.times: dict[str, list] = {k: [] for k in cfgs}
        self.reg = {k: defaultdict(float) for k in cfgs}
        self.det_false: defaultdict = defaultdict(int)

    def detections(self, det_boxes: list, truth: _FrameTruth) -> dict[int, bool]:
        """Count the detector's false alarms and start the signs it found; returns whether
        a detection matched each evaluable sign (by sign id)."""
        for b in det_boxes:
            fk = truth.false_kind(b)
            if fk:
                self.det_false[fk] += 1
        det_hit = {}
        for s in truth.evaluable:
            g = _xywh(s.box)
            det_hit[s.sign_id] = any(_iou(b, g) >= TAU for b in det_boxes)
            if det_hit[s.sign_id]:
                self.started.add(s.sign_id)
        return det_hit

    def outputs(self, name: str, out: list, truth: _FrameTruth, det_hit: dict[int, bool],
                det_boxes: list, trace: Optional[list], n_frame: int) -> None:
        """Count configuration ``name``'s outputs ``out`` of one frame."""
        boxes = [(_xywh(t.box), t.source, t.track_id) for t in out]
        for s in truth.evaluable:
            if s.sign_id not in self.started:
                continue
            best = self._sign(name, s, boxes, det_hit[s.sign_id])
            if trace is not None:
                g = _xywh(s.box)
                dbest = max((_iou(b, g) for b in det_boxes), default=0.0)
                trace.append((n_frame, name, s.sign_id, s.class_key, dbest, best,
                              min(s.box.w, s.box.h)))
        self._false(name, boxes, truth)

    def _sign(self, name: str, s, boxes: list, det_hit: bool) -> float:
        """Count one run sign-frame; returns the best output IoU with the sign."""
        a, reg, ids = self.acc[name], self.reg[name], self.ids[name]
        g = _xywh(s.box)
        best, bo = 0.0, None
        for b, src, _ in boxes:
            v = _iou(b, g)
            if v > best:
                best, bo = v, b
        a['tracked_frames'] += 1
        two = s.class_key in ('work_zone_begin', 'work_zone_speed_limit')
        if two:
            reg['frames'] += 1
        if best >= TAU:
            p, r = area_pr(bo, g)
            a['matched'] += 1
            a['precision_sum'] += p
            a['recall_sum'] += r
            if two:
                reg['matched'] += 1
                reg['precision_sum'] += p
                reg['recall_sum'] += r
        if not det_hit:
            a['missed_by_detector'] += 1
            self.missed_ids.add(s.sign_id)
            ids['missed'].add(s.sign_id)
            if best >= TAU:
                a['covered'] += 1
                ids['covered'].add(s.sign_id)
        return best

    def _false(self, name: str, boxes: list, truth: _FrameTruth) -> None:
        """Count the outputs on no work-zone sign (all, and tracking-only)."""
        a, ids = self.acc[name], self.ids[name]
        for b, src, tid in boxes:
            if src == 'tracking':
                a['tracking_outputs'] += 1
            fk = truth.false_kind(b)
            if fk is None:
                continue
            a[f'false_{fk}'] += 1
            ids[f'false_{fk}'].add(tid)
            if src == 'tracking':
                a[f'false_tracking_{fk}'] += 1
                ids[f'false_tracking_{fk}'].add(tid)

    def figures(self, name: str) -> dict:
        """Configuration ``name``'s figures over the bag."""
        a = self.acc[name]
        m = max(a['matched'], 1)
        t = np.array(self.times[name]) * 1e3
        r = self.reg[name]
        i = self.ids[name]
        out = {
            'tracked_frames': int(a['tracked_frames']),
            'match_rate': _r(a['matched'] / max(a['tracked_frames'], 1)),
            'precision': _r(a['precision_sum'] / m),
            'recall': _r(a['recall_sum'] / m),
            'missed_by_detector': int(a['missed_by_detector']),
            'covered': int(a['covered']),
            'covered_fraction': _r(a['covered'] / max(a['missed_by_detector'], 1)),
            'covered_signs': len(i['covered']),
            'missed_signs': len(i['missed']),
            'tracking_outputs': int(a['tracking_outputs']),
            'false_on_drums': int(a['false_drums']),
            'false_on_other': int(a['false_other']),
            'false_tracking_on_drums': int(a['false_tracking_drums']),
            'false_tracking_on_other': int(a['false_tracking_other']),
            'false_tracks_on_drums': len(i['false_tracking_drums'] - {0}),
            'false_tracks_on_other': len(i['false_tracking_other'] - {0}),
            'two_colour_frames': int(r['frames']),
            'two_colour_match_rate': _r(r['matched'] / max(r['frames'], 1)),
            'two_colour_precision': _r(r['precision_sum'] / max(r['matched'], 1)),
            'two_colour_recall': _r(r['recall_sum'] / max(r['matched'], 1)),
        }
        if t.size:
            out['ms_per_track_frame_p50'] = _r(float(np.percentile(t, 50)))
            out['ms_per_track_frame_p99'] = _r(float(np.percentile(t, 99)))
            out['track_frames_timed'] = int(t.size)
        return out


def evaluate_bag(bag: str, detector, min_size: float, max_frames: int = 0,
                 overlay: Optional[list] = None, configs: Optional[dict] = None,
                 trace: Optional[list] = None) -> dict:
    """Run every configuration on one bag; returns the per-configuration figures.

    Definitions (Lee et al., IV and Table II; tau = 0.5):

    * a sign-frame is *run* from the first frame where a detection matched the sign
      (IoU >= tau) on ("the frames which were executed on the tracking");
    * a *detector miss* is a run sign-frame with no detection at IoU >= tau;
    * it is *covered* when an output of the configuration (a track box, whatever its
      source) matches it at IoU >= tau;
    * precision / recall (area-based) of the best output with IoU >= tau, averaged over
      the matched run sign-frames;
    * a *false output* overlaps no work-zone sign (IoU < 0.3 with each, whatever its size);
      it is *on drums* when it overlaps a GT drum or cone (IoU >= 0.3, or >= half of the
      drum inside it), else *on other non-signs* (vehicles, general signs, background).
      Counted for all outputs and for ``tracking`` outputs only (what the tracker adds),
      as frames and as distinct track ids.
    """
    from workzone_ros.core.track import MultiTracker
    cfgs = configs or _configs()
    trackers = {k: MultiTracker(c) for k, c in cfgs.items()}
    tally = _BagTally(cfgs)
    n_frames = 0
    weather = ''
    for ns, frame, gt in _frames(bag):
        n_frames += 1
        weather = gt.weather
        dets = detector(frame, gt)
        det_boxes = [_xywh(d.box) for d in dets]
        truth = _FrameTruth(gt, min_size)
        det_hit = tally.detections(det_boxes, truth)
        frame_out = {}
        for name, tracker in trackers.items():
            out = tracker.step(frame, dets, stamp=ns * 1e-9)
            frame_out[name] = out
            tally.times[name] += tracker.last_localise_s
            tally.outputs(name, out, truth, det_hit, det_boxes, trace, n_frames)
        if overlay is not None:
            overlay.append((ns, frame, gt, dets, frame_out.get('meanshift', [])))
        if max_frames and n_frames >= max_frames:
            break
    if hasattr(detector, 'flush'):
        detector.flush()
    res: dict[str, Any] = {'bag': bag, 'frames': n_frames, 'weather': weather,
                           'detector_false_on_drums': tally.det_false['drums'],
                           'detector_false_on_other': tally.det_false['other'],
                           'signs_missed_by_detector': len(tally.missed_ids)}
    for name in cfgs:
        res[name] = tally.figures(name)
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
    p.add_argument('bags', nargs='*', help='synthetic bag directories (workzone-ros synth)')
    p.add_argument('--real', nargs='?', default=None,
                   const=os.environ.get('WORKZONE_REALDATA', str(_REALDATA)).rstrip('/')
                   + '/us_workzone_video',
                   help='also the real dashcam clips in this folder (default '
                        '../shared/realdata/us_workzone_video)')
    p.add_argument('--detector', choices=('color', 'gt'), default='color',
                   help='colour detector core (default) or GT boxes with simulated misses')
    p.add_argument('--color-model', default=None, help='trained colour model (.npz)')
    p.add_argument('--miss', type=float, default=0.3, help='gt detector: miss rate')
    p.add_argument('--jitter', type=float, default=0.03, help='gt detector: box jitter')
    p.add_argument('--min-size', type=float, default=12.0,
                   help='evaluable signs: smallest side in px (default 12)')
    p.add_argument('--max-frames', type=int, default=0, help='stop after N frames per bag')
    p.add_argument('--json', help='write the figures here')
    p.add_argument('--overlay', help="write a tracking overlay strip PNG per bag (a bag's "
                   'name is appended when there are several)')
    p.add_argument('--det-cache', default=None,
                   help='directory for cached detections (one file per bag and model file)')
    p.add_argument('--configs', default=','.join(CONFIGS),
                   help=f'comma-separated configurations (default {",".join(CONFIGS)})')
    args = p.parse_args(argv)
    chosen = [c.strip() for c in args.configs.split(',') if c.strip()]
    all_cfgs = _configs()
    bad = [c for c in chosen if c not in all_cfgs]
    if bad:
        print(f'unknown configurations {bad}; choose from {list(all_cfgs)}', file=sys.stderr)
        return 2
    cfgs = {c: all_cfgs[c] for c in chosen}
    if not args.bags and not args.real:
        print('give synthetic bags and/or --real', file=sys.stderr)
        return 2
    if args.real and not Path(args.real).is_dir():
        print(f'{args.real}: no such folder (the real clips)', file=sys.stderr)
        return 2
    import cv2
    cv2.setNumThreads(1)
    results: list = []
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
        if args.det_cache and args.detector == 'color' and isinstance(det, _ColorDetector):
            os.makedirs(args.det_cache, exist_ok=True)
            det = _CachedDetector(det, os.path.join(
                args.det_cache, f'{Path(bag).resolve().name}_{det.key}.jsonl'))
        frames: Optional[list] = [] if args.overlay else None
        try:
            res = evaluate_bag(bag, det, args.min_size, args.max_frames, frames, cfgs)
        except BagError as exc:
            print(f'{bag}: {exc}', file=sys.stderr)
            return 2
        res['detector'] = det.name
        res['model_file'] = getattr(det, 'model_file', None)
        results.append(res)
        _print(res, list(cfgs))
        if frames:
            path = args.overlay
            if len(args.bags) > 1:
                root, ext = os.path.splitext(args.overlay)
                path = f'{root}_{Path(bag).name}{ext or ".png"}'
            out = write_overlay(path, frames)
            print(f'overlay: {out}')
            frames.clear()
    real = None
    if args.real:
        real = evaluate_real(Path(args.real), args.color_model, cfgs, args.max_frames)
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, 'w') as fh:
            json.dump(results if real is None else {'synthetic': results, 'real': real},
                      fh, indent=2)
        print(f'figures written to {args.json}')
    return 0


def evaluate_real(folder: Path, model_path: Optional[str], cfgs: dict,
                  max_frames: int = 0) -> dict:
    """The trackers on the real dashcam clips (camera only, native size, 30 fps stamps).

    Per clip and configuration, with the hand-made approximate sign boxes of
    ``evaluate color --real`` (evaluation only): the share of the visible labelled sign
    frames where an output box has IoU >= 0.3 with the label (``sign_share``); of the frames
    where the detector missed the sign, the share an output covers (``covered`` of
    ``misses``); outputs per frame in the README's sign-free range (``false_per_frame``) and
    those of them that are tracking-only (``false_tracking_per_frame``: cones, drums,
    vests and trucks are in that range).
    """
    import cv2

    from workzone_ros.core.track import MultiTracker
    from workzone_ros.tools.eval_color import REAL_CLIPS, load_real_labels
    labels = load_real_labels()
    out: dict = {}
    for clip, (_, (f0, f1)) in REAL_CLIPS.items():
        path = folder / clip
        if not path.exists():
            out[clip] = {'skipped': f'{path} not found'}
            continue
        det = _ColorDetector(model_path)
        trackers = {name: MultiTracker(cfg) for name, cfg in cfgs.items()}
        lab = labels.get(clip, {})
        res = {name: defaultdict(int) for name in cfgs}
        cap = cv2.VideoCapture(str(path))
        fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
        k = -1
        while not max_frames or k + 1 < max_frames:
            ok, img = cap.read()
            if not ok:
                break
            k += 1
            dets = [d for d in det(img, None) if d.color == 'orange']
            label = lab.get(k)
            det_hit = bool(label and label[1]
                           and any(d.box.iou(label[0]) >= 0.3 for d in dets))
            for name, tracker in trackers.items():
                outs = tracker.step(img, dets, stamp=k / fps)
                r = res[name]
                if label and label[1]:
                    hit = any(t.box.iou(label[0]) >= 0.3 for t in outs)
                    r['sign_frames'] += 1
                    r['sign_hits'] += hit
                    if not det_hit:
                        r['misses'] += 1
                        r['covered'] += hit
                elif f0 <= k <= f1:
                    r['free_frames'] += 1
                    r['false'] += len(outs)
                    r['false_tracking'] += sum(1 for t in outs if t.source == 'tracking')
        cap.release()
        clip_out = {}
        for name, r in res.items():
            n, free = r['sign_frames'], max(r['free_frames'], 1)
            clip_out[name] = {
                'sign_frames': n, 'sign_share': _r(r['sign_hits'] / n) if n else None,
                'misses': r['misses'], 'covered': r['covered'],
                'false_per_frame': _r(r['false'] / free),
                'false_tracking_per_frame': _r(r['false_tracking'] / free)}
        out[clip] = clip_out
        print(f'\n== {clip} (real, {k + 1} frames; approximate hand-made labels)')
        print(f"   {'config':22s} {'sign share':>10s} {'covered':>9s} {'false/fr':>9s} "
              f"{'trk-only false/fr':>18s}")
        for name, r in clip_out.items():
            share = '-' if r['sign_share'] is None else f"{r['sign_share']:.3f}"
            print(f"   {name:22s} {share:>10s} {r['covered']:>4d}/{r['misses']:<4d} "
                  f"{r['false_per_frame']:>9.3f} {r['false_tracking_per_frame']:>18.3f}")
    return out


def _print(res: dict, names: Optional[list] = None) -> None:
    print(f"\n== {res['bag']}  ({res['frames']} frames, {res['weather']}, detector "
          f"{res['detector']})")
    print(f"   detector false alarms: on drums/cones {res['detector_false_on_drums']}, on "
          f"other non-signs {res['detector_false_on_other']}; signs the detector missed at "
          f"least once: {res['signs_missed_by_detector']}")
    cols = (('tracked_frames', 'run'), ('match_rate', 'match'), ('precision', 'prec'),
            ('recall', 'rec'), ('missed_by_detector', 'misses'), ('covered', 'covered'),
            ('covered_signs', 'cov.signs'), ('false_tracking_on_drums', 'ftrk.drum'),
            ('false_tracks_on_drums', 'ftrk.drum.ids'), ('false_tracking_on_other', 'ftrk.oth'),
            ('false_tracks_on_other', 'ftrk.oth.ids'), ('false_on_drums', 'fout.drum'),
            ('false_on_other', 'fout.oth'), ('two_colour_match_rate', '2col.match'),
            ('two_colour_recall', '2col.rec'), ('ms_per_track_frame_p50', 'ms.p50'))
    print('   ' + 'config'.ljust(20) + ''.join(c[1].rjust(13) for c in cols))
    for name in names or CONFIGS:
        r = res[name]
        print('   ' + name.ljust(20) + ''.join(str(r.get(c[0], '-')).rjust(13) for c in cols))


if __name__ == '__main__':
    sys.exit(main())
