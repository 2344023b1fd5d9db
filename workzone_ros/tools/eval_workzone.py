"""``workzone-ros evaluate workzone``: the work-zone state against a bag's ground truth.

Usage::

    workzone-ros evaluate workzone BAG [BAG ...] [--signs gt|pipeline] [--drop P]
        [--confuse P] [--spurious R] [--seed N] [--no-odom] [--no-channelizers]
        [--fusion KEY=VALUE ...] [--json OUT] [--report DIR] [--workers N] [--cache DIR]

Every camera frame of a bag, in bag order, becomes one :class:`~workzone_ros.interfaces.Signs`
payload and goes through :class:`workzone_ros.core.fusion.WorkzoneFusion` (the ``fusion``
node's core) with the metres travelled from ``/odom`` (:class:`~workzone_ros.core.odometry.
TravelledDistance`, as the node computes them; ``--no-odom``: none, the fusion works over
time) and the frame's channelizer count.  Where the signs come from:

* ``--signs gt`` (default): ``/groundtruth/signs``, tests the fusion alone.  Each *legible*
  sign (shorter box side >= ``--legible-px``, default 12 = the classifier node's
  ``min_size``, and at least half visible) is a Sign with its class, box, ``distance_m``
  (exact) and ``sign_id`` as track id; a work-zone speed limit carries its value (from the
  ``speed_limit`` event of its sign) once its box is >= 24 px (the digit reader's minimum).
  Noise, seeded per bag by ``--seed`` and the bag's name: ``--drop P`` drops an observation,
  ``--confuse P`` replaces a work-zone sign's class by another work-zone class (a
  ``background`` answer is not published by the classifier node: that is ``--drop``),
  ``--spurious R`` adds per frame with probability R a false work-zone sign (random class,
  a new track id, for 1 to ``--spurious-frames`` frames, default 2: stray classifications;
  a false sign classified alike on ``min_hits`` frames of one track is a sign to the
  fusion).  Channelizers: GT drums and cones whose box is >= 6 px.
* ``--signs pipeline``: the colour detector, the mean-shift tracker and the sign classifier
  of ``workzone_ros.core`` on the bag's images (``workzone_ros.tools.workzone_pipeline``);
  the classifier node's rules (``min_size`` 12 px, half visible, background rejected,
  distance from the apparent size and CameraInfo's focal length, the speed read on
  speed-limit signs).  ``--cache DIR`` stores each bag's pipeline signs (per bag and
  model files) so that reruns of the fusion skip the perception.

Ground truth per frame (from ``/groundtruth/workzone`` and ``/groundtruth/signs``; ``t`` is
bag time, the ego passes a sign at its event's ``t``):

* ``approaching`` from the first frame where a sign of the zone standing before the begin
  (the events up to ``zone_begin``: W20-1, lane closed, speed limit, lane shifts, the R22-1
  itself) is legible (as above), until ``begin_t``;
* ``inside`` from ``begin_t`` until the END ROAD WORK sign is first legible;
* ``leaving`` from then until ``end_t``; ``none`` before and after (the whole bag when the
  bag has no zone).

Figures per bag (every one in ``--json``; ``null`` where it does not apply):

* ``frames``, ``phase_accuracy`` (share of frames whose predicted phase is the truth's;
  ``unknown`` counts as wrong), ``active_accuracy`` (the ``active`` flag against truth
  ``inside``/``leaving``), ``unknown_frames``, ``confusion_phase`` (truth -> predicted ->
  frames);
* ``zone_begin`` / ``zone_end``: ``truth_t``, ``pred_t`` (first frame predicted active;
  first frame after it predicted not active), ``error_s`` and ``error_m`` (predicted minus
  truth, in seconds and odometry metres), ``recognised`` (a prediction within
  ``--tolerance`` s, default 3), ``images`` / ``precision`` / ``recall`` of the event's sign
  (below);
* ``changes``: one entry per driving-condition change (``speed_limit`` value,
  ``lane_shift`` direction, ``lane_closed`` side; the W20-5 + W4-2 pair of one closure is one
  change): ``recognised`` when the state shows the value at a frame between the first
  legible frame of its signs and ``--tolerance`` s after the ego passes its last sign,
  ``delay_s`` (first such frame minus the time the ego passes its first sign: negative =
  known before reaching it), ``images`` (frames where a sign of the change is legible),
  ``precision`` / ``recall`` (Table IV: per frame, raw classifier outputs; a prediction
  matches a legible GT sign at IoU >= 0.5; recall = matched frames with the right class /
  ``images``; precision = those predictions / all predictions of the change's classes that
  match no other GT sign of those classes);
* ``time_to_correct``: per truth phase onset (``approaching``, ``inside``, ``leaving``,
  ``none``), seconds from the onset to the first frame predicted in that phase (null when
  not before the next onset);
* ``phase_changes`` (predicted, after the first ``unknown``), ``truth_changes``,
  ``flicker`` = max(0, predicted - truth);
* ``likelihood_inside`` / ``likelihood_outside``: mean likelihood over truth-active and
  truth-none frames; ``sign_confusion`` (truth class -> predicted class -> frames, IoU >=
  0.5; ``missed`` and ``no sign`` for the unmatched); ``unknown_classes`` and ``resets`` of
  the fusion; ``wall_s``.

``summary`` pools the bags: bounds and changes recognised, mean and max absolute timing
errors, total flicker, frame-weighted phase accuracy.  ``--report DIR`` writes
``DIR/README.md`` with the Table IV and each bag's seed-Fig.-3 timeline PNG
(``workzone_ros.tools.workzone_report``).  A missing or corrupt bag, or a bag without
ground truth, is a one-line error (exit 2).
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from workzone_ros.bagio import BagError
from workzone_ros.core import signs as catalogue
from workzone_ros.core.fusion import ACTIVE_PHASES, FusionConfig, WorkzoneFusion
from workzone_ros.interfaces import Box, GtSigns, GtWorkzone, PayloadError, Sign, Signs, decode
from workzone_ros.tools.eval_tracker import _iou, _xywh

__all__ = ['main', 'evaluate_bag', 'EvalOptions', 'EvalError', 'GtSignSource', 'truth_phases',
           'score', 'legible', 'PHASES_ORDER']

PHASES_ORDER = ('unknown', 'none', 'approaching', 'inside', 'leaving')
SPEED_READ_PX = 24.0          # the digit reader's smallest legible speed-limit box
CHANNELIZER_PX = 6.0          # GT drums / cones at least this big are counted
IOU = 0.5
_TOPICS = ('/groundtruth/workzone', '/groundtruth/signs', '/odom', '/camera/camera_info',
           '/camera/image_raw', '/camera/image_raw/compressed')


class EvalError(Exception):
    """A bag that cannot be evaluated (one line)."""


@dataclass(frozen=True)
class EvalOptions:
    """Everything that changes the result of one bag (picklable for the pool)."""

    signs: str = 'gt'
    drop: float = 0.0
    confuse: float = 0.0
    spurious: float = 0.0
    spurious_frames: int = 2
    seed: int = 0
    odom: bool = True
    channelizers: bool = True
    legible_px: float = 12.0
    tolerance_s: float = 3.0
    keep_frames: bool = False
    color_model: Optional[str] = None
    classifier_model: Optional[str] = None
    cache: Optional[str] = None
    fusion: tuple = ()            # (FusionConfig field, value) overrides


def fusion_config(opts: EvalOptions) -> FusionConfig:
    """The FusionConfig of a run: the defaults, ``--no-channelizers``, ``--fusion K=V``."""
    return FusionConfig(**{'use_channelizers': opts.channelizers, **dict(opts.fusion)})


@dataclass
class Frame:
    """What one camera frame gave and what the truth was."""

    t: float
    odom_m: float
    truth: str = 'none'
    phase: str = 'unknown'
    likelihood: float = 0.0
    speed: Optional[int] = None
    lane_shift: str = 'none'
    lanes_closed: tuple = ()
    pred: list = field(default_factory=list)     # (class_key, (x, y, w, h), track_id)
    gt: list = field(default_factory=list)       # (sign_id, class_key, (x, y, w, h))


def legible(s, min_px: float) -> bool:
    """A GT sign a classifier could read: shorter side >= min_px and half visible."""
    return min(s.box.w, s.box.h) >= min_px and s.visible_fraction >= 0.5




# --- sign sources ---------------------------------------------------------------------------

class GtSignSource:
    """Signs from ``/groundtruth/signs`` with an optional, seeded noise model."""

    name = 'gt'

    def __init__(self, opts: EvalOptions, bag_name: str, speeds: dict[int, int]) -> None:
        import numpy as np
        self.rng = np.random.default_rng([opts.seed, zlib.crc32(bag_name.encode())])
        self.opts, self.speeds = opts, speeds
        self.spurious: list[list] = []            # [sign, frames left]
        self.next_id = 10_000_000
        self.wrong = list(catalogue.WORKZONE_KEYS)

    def __call__(self, gt: GtSigns, image=None, focal=None) -> tuple[list[Sign], Optional[int]]:
        o, out = self.opts, []
        for s in gt.signs:
            if not legible(s, o.legible_px) or (o.drop and self.rng.random() < o.drop):
                continue
            key = s.class_key
            if o.confuse and s.category == 'workzone' and self.rng.random() < o.confuse:
                key = str(self.rng.choice([k for k in self.wrong if k != key]))
            out.append(self._sign(key, s.box, s.sign_id, s.distance_m,
                                  self._speed(s, key)))
        out += self._spurious()
        n = sum(1 for d in gt.distractors if d.kind in ('drum', 'cone')
                and min(d.box.w, d.box.h) >= CHANNELIZER_PX)
        return out, n

    def _speed(self, s, key: str) -> Optional[int]:
        if key != 'work_zone_speed_limit' or min(s.box.w, s.box.h) < SPEED_READ_PX:
            return None
        return self.speeds.get(s.sign_id)

    def _sign(self, key: str, box: Box, track_id: int, distance: float,
              speed: Optional[int]) -> Sign:
        c = catalogue.get(key)
        return Sign(box=box, class_key=key, code=c.code,
                    category=c.category,
                    score=0.9, track_id=int(track_id), speed_limit_mph=speed,
                    speed_limit_confidence=None if speed is None else 0.9,
                    distance_m=round(float(distance), 2), distance_source='lidar')

    def _spurious(self) -> list[Sign]:
        o = self.opts
        if o.spurious and self.rng.random() < o.spurious:
            key = str(self.rng.choice(catalogue.WORKZONE_KEYS))
            box = Box(x=float(self.rng.uniform(0, 600)), y=float(self.rng.uniform(100, 300)),
                      w=20.0, h=20.0)
            self.next_id += 1
            self.spurious.append([self._sign(key, box, self.next_id,
                                             float(self.rng.uniform(30, 100)), None),
                                  int(self.rng.integers(1, o.spurious_frames + 1))])
        out = [s for s, _ in self.spurious]
        for item in self.spurious:
            item[1] -= 1
        self.spurious = [x for x in self.spurious if x[1] > 0]
        return out


def _gt_source(opts: EvalOptions, bag_name: str, gtw: GtWorkzone) -> GtSignSource:
    speeds = {int(e.sign_id): int(e.value) for e in gtw.events
              if e.kind == 'speed_limit' and e.sign_id is not None
              and isinstance(e.value, (int, float))}
    return GtSignSource(opts, bag_name, speeds)


def _pipeline_source(opts: EvalOptions, bag_name: str):
    from workzone_ros.tools.workzone_pipeline import CachedSource, PipelineSource
    if opts.cache:
        return CachedSource(opts, bag_name, opts.cache)
    return PipelineSource(opts)


# --- the run over one bag -------------------------------------------------------------------

def _image(msg) -> Any:
    """BGR numpy image of a sensor_msgs Image / CompressedImage (rosbags message)."""
    import cv2
    import numpy as np
    if hasattr(msg, 'format'):
        img = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise EvalError(f'undecodable compressed image ({msg.format})')
        return img
    if msg.encoding not in ('bgr8', 'rgb8'):
        raise EvalError(f'unsupported image encoding {msg.encoding}')
    img = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)[
        :, :msg.width * 3].reshape(msg.height, msg.width, 3)
    return np.ascontiguousarray(img[..., ::-1] if msg.encoding == 'rgb8' else img)


def _stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def run_bag(bag: str, opts: EvalOptions) -> tuple[GtWorkzone, list[Frame], dict]:
    """Feed every frame of ``bag`` to the fusion; returns (truth, frames, counters).

    Raises:
        EvalError: no ground truth, undecodable payloads or images.
        BagError: a missing or corrupt bag.
    """
    from workzone_ros.bagio import read_messages
    from workzone_ros.core.odometry import TravelledDistance
    fusion = WorkzoneFusion(fusion_config(opts))
    odo = TravelledDistance()
    gtw: Optional[GtWorkzone] = None
    source = _pipeline_source(opts, Path(bag).name) if opts.signs == 'pipeline' else None
    images_too = source is not None and source.needs_images
    t0 = None
    focal: Optional[float] = None
    images: dict[int, Any] = {}
    frames: list[Frame] = []
    fusion_ms: list[float] = []
    topics = list(_TOPICS[:4]) + (list(_TOPICS[4:]) if images_too else [])
    for topic, _, msg in read_messages(bag, topics):
        if topic == '/groundtruth/workzone':
            if gtw is None:
                gtw = _decode(msg.data, GtWorkzone)
                t0 = gtw.header.stamp.to_ns()
                source = source or _gt_source(opts, Path(bag).name, gtw)
        elif topic == '/odom':
            p = msg.pose.pose.position
            odo.update(_stamp_ns(msg) * 1e-9, float(p.x), float(p.y))
        elif topic == '/camera/camera_info':
            focal = float(msg.k[0]) or focal
        elif topic.startswith('/camera/image_raw'):
            images[_stamp_ns(msg)] = _image(msg)
        else:
            if gtw is None:
                raise EvalError('/groundtruth/signs before /groundtruth/workzone (no zone '
                                'ground truth)')
            gt = _decode(msg.data, GtSigns)
            ns = gt.header.stamp.to_ns()
            image = images.pop(ns, None) if images_too else None
            for k in [k for k in images if k < ns]:
                del images[k]
            if images_too and image is None:
                continue
            frames.append(_step(fusion, source, gt, image, focal, (ns - t0) * 1e-9,
                                odo.distance_m, opts, fusion_ms))
    if hasattr(source, 'flush'):
        source.flush()
    if gtw is None or not frames:
        raise EvalError('no /groundtruth/workzone or no camera frames with /groundtruth/'
                        'signs: not a synthetic bag (workzone-ros synth)?')
    stages = {k: list(v) for k, v in getattr(source, 'timings', {}).items() if v}
    stages['fusion'] = fusion_ms
    return gtw, frames, {'unknown_classes': fusion.unknown_classes, 'resets': fusion.resets,
                         '_stage_ms': stages}


def _decode(data, cls):
    try:
        return decode(data, cls)
    except PayloadError as exc:
        raise EvalError(str(exc)) from None


def _step(fusion: WorkzoneFusion, source, gt: GtSigns, image, focal, t: float,
          odom_m: float, opts: EvalOptions, fusion_ms: list) -> Frame:
    """One frame: signs from the source, the fusion's state, what the report needs."""
    signs, channel = source(gt, image, focal)
    t0 = time.perf_counter()
    st = fusion.update(Signs(header=gt.header, signs=signs),
                       odom_distance_m=odom_m if opts.odom else None, channelizers=channel)
    fusion_ms.append((time.perf_counter() - t0) * 1e3)
    f = Frame(t=t, odom_m=odom_m, phase=st.phase, likelihood=st.likelihood,
              speed=st.speed_limit_mph, lane_shift=st.lane_shift,
              lanes_closed=tuple(st.lanes_closed))
    f.pred = [(s.class_key, _xywh(s.box), s.track_id) for s in signs
              if s.category != 'unknown']
    f.gt = [(s.sign_id, s.class_key, _xywh(s.box)) for s in gt.signs
            if legible(s, opts.legible_px)]
    return f


# --- ground truth phases --------------------------------------------------------------------

def _first_legible(frames: list[Frame]) -> dict[int, float]:
    out: dict[int, float] = {}
    for f in frames:
        for sid, _, _ in f.gt:
            out.setdefault(sid, f.t)
    return out


def truth_phases(frames: list[Frame], gtw: GtWorkzone, legible_px: float) -> dict:
    """Set ``Frame.truth`` (module docstring); returns the onsets {phase: t}."""
    onsets: dict[str, Optional[float]] = {}
    if gtw.begin_t is None:
        return onsets
    seen = _first_legible(frames)
    begin = next(e for e in gtw.events if e.kind == 'zone_begin')
    before = [e for e in gtw.events if e.x_m <= begin.x_m and e.sign_id in seen]
    approach = min((seen[e.sign_id] for e in before), default=gtw.begin_t)
    onsets['approaching'] = min(approach, gtw.begin_t)
    onsets['inside'] = gtw.begin_t
    end = next((e for e in gtw.events if e.kind == 'zone_end'), None)
    end_t = gtw.end_t if gtw.end_t is not None else float('inf')
    leave = seen.get(end.sign_id, end_t) if end is not None else end_t
    onsets['leaving'] = max(leave, gtw.begin_t)
    onsets['none'] = end_t
    for f in frames:
        f.truth = ('none' if f.t < onsets['approaching'] or f.t >= end_t
                   else 'approaching' if f.t < onsets['inside']
                   else 'inside' if f.t < onsets['leaving'] else 'leaving')
    return onsets


# --- scoring --------------------------------------------------------------------------------

def _r(v: Optional[float], nd: int = 3) -> Optional[float]:
    return None if v is None else round(float(v), nd)


def _odom_at(frames: list[Frame], t: float) -> float:
    """Odometry metres at bag time ``t`` (linear between frames)."""
    prev = frames[0]
    for f in frames:
        if f.t >= t:
            if f.t == prev.t:
                return f.odom_m
            a = (t - prev.t) / (f.t - prev.t)
            return prev.odom_m + a * (f.odom_m - prev.odom_m)
        prev = f
    return frames[-1].odom_m


def _bounds(frames: list[Frame], gtw: GtWorkzone, tol: float) -> tuple[dict, dict]:
    """zone_begin / zone_end: predicted times, errors, recognised."""
    k_on = next((i for i, f in enumerate(frames) if f.phase in ACTIVE_PHASES), None)
    k_off = None if k_on is None else next(
        (i for i in range(k_on, len(frames)) if frames[i].phase not in ACTIVE_PHASES), None)
    out = []
    for truth, k in ((gtw.begin_t, k_on), (gtw.end_t, k_off)):
        row: dict[str, Any] = {'truth_t': _r(truth), 'pred_t': None, 'error_s': None,
                               'error_m': None, 'recognised': None}
        if truth is not None:
            row['recognised'] = False
            if k is not None:
                p = frames[k].t
                row.update(pred_t=_r(p), error_s=_r(p - truth),
                           error_m=_r(frames[k].odom_m - _odom_at(frames, truth), 2),
                           recognised=abs(p - truth) <= tol)
        out.append(row)
    return out[0], out[1]


def _changes(gtw: GtWorkzone) -> list[dict]:
    """Driving-condition changes; the two signs of one lane closure are one change."""
    out: list[dict] = []
    for e in sorted(gtw.events, key=lambda e: e.t):
        if e.kind not in ('speed_limit', 'lane_shift', 'lane_closed'):
            continue
        if out and e.kind == 'lane_closed' and out[-1]['kind'] == 'lane_closed' \
                and out[-1]['value'] == e.value:
            out[-1]['sign_ids'].append(e.sign_id)
            out[-1]['t_last'] = e.t
            continue
        out.append({'kind': e.kind, 'value': e.value, 'sign_ids': [e.sign_id],
                    't_first': e.t, 't_last': e.t})
    return out


def _shows(f: Frame, kind: str, value) -> bool:
    if kind == 'speed_limit':
        return f.speed == value
    if kind == 'lane_shift':
        return f.lane_shift == value
    return value in f.lanes_closed


def _sign_pr(frames: list[Frame], sign_ids: list) -> dict:
    """Table IV's sign images / precision / recall for the signs of one event."""
    ids = set(sign_ids)
    classes = {c for f in frames for sid, c, _ in f.gt if sid in ids}
    images = tp_frames = tp = fp = 0
    for f in frames:
        mine = [(sid, c, b) for sid, c, b in f.gt if sid in ids]
        others = [b for sid, c, b in f.gt if sid not in ids and c in classes]
        images += len(mine)
        for _, c, b in mine:
            tp_frames += any(pc == c and _iou(pb, b) >= IOU for pc, pb, _ in f.pred)
        for pc, pb, _ in f.pred:
            if pc not in classes:
                continue
            if any(_iou(pb, b) >= IOU for _, _, b in mine):
                tp += 1
            elif not any(_iou(pb, b) >= IOU for b in others):
                fp += 1
    return {'images': images, 'precision': _r(tp / (tp + fp)) if tp + fp else None,
            'recall': _r(tp_frames / images) if images else None,
            'classes': sorted(classes)}


def _change_rows(frames: list[Frame], gtw: GtWorkzone, tol: float) -> list[dict]:
    seen = _first_legible(frames)
    rows = []
    for ch in _changes(gtw):
        onset = min((seen[s] for s in ch['sign_ids'] if s in seen), default=ch['t_first'])
        hit = next((f for f in frames if onset <= f.t <= ch['t_last'] + tol
                    and _shows(f, ch['kind'], ch['value'])), None)
        rows.append({'kind': ch['kind'], 'value': ch['value'], 'sign_ids': ch['sign_ids'],
                     'truth_t': _r(ch['t_first']), 'recognised': hit is not None,
                     'delay_s': None if hit is None else _r(hit.t - ch['t_first']),
                     **_sign_pr(frames, ch['sign_ids'])})
    return rows


def _time_to_correct(frames: list[Frame], onsets: dict) -> dict:
    order = sorted((t, p) for p, t in onsets.items() if t is not None and t != float('inf'))
    out = {}
    for i, (t, p) in enumerate(order):
        nxt = order[i + 1][0] if i + 1 < len(order) else float('inf')
        hit = next((f.t for f in frames if t <= f.t < nxt and f.phase == p), None)
        out[p] = None if hit is None else _r(hit - t)
    return out


def sign_confusion(frames: list[Frame]) -> dict[str, dict[str, int]]:
    """Per-frame truth class -> predicted class counts (IoU >= 0.5, best first).

    A legible GT sign no prediction matches counts as ``missed``; a prediction that
    matches no legible GT sign counts under truth ``no sign``.
    """
    out: dict[str, Counter] = {}
    for f in frames:
        used: set[int] = set()
        for _, c, b in f.gt:
            best, j = max(((_iou(pb, b), i) for i, (_, pb, _) in enumerate(f.pred)
                           if i not in used), default=(0.0, -1))
            if best >= IOU:
                used.add(j)
                out.setdefault(c, Counter())[f.pred[j][0]] += 1
            else:
                out.setdefault(c, Counter())['missed'] += 1
        for i, (pc, _, _) in enumerate(f.pred):
            if i not in used:
                out.setdefault('no sign', Counter())[pc] += 1
    return {k: dict(v) for k, v in sorted(out.items())}


def _changes_count(seq: list[str]) -> int:
    seq = list(seq)
    while seq and seq[0] == 'unknown':
        seq.pop(0)
    return sum(1 for a, b in zip(seq, seq[1:]) if a != b)


def score(frames: list[Frame], gtw: GtWorkzone, tol: float, legible_px: float) -> dict:
    """Every figure of one bag (module docstring)."""
    onsets = truth_phases(frames, gtw, legible_px)
    n = len(frames)
    conf: dict[str, Counter] = {}
    for f in frames:
        conf.setdefault(f.truth, Counter())[f.phase] += 1
    begin, end = _bounds(frames, gtw, tol)
    zone_ids = {e.kind: e.sign_id for e in gtw.events if e.kind in ('zone_begin', 'zone_end')}
    for row, kind in ((begin, 'zone_begin'), (end, 'zone_end')):
        row.update(_sign_pr(frames, [zone_ids[kind]]) if kind in zone_ids
                   else {'images': 0, 'precision': None, 'recall': None, 'classes': []})
    pred_changes = _changes_count([f.phase for f in frames])
    truth_changes = _changes_count([f.truth for f in frames])
    inside = [f.likelihood for f in frames if f.truth in ACTIVE_PHASES]
    outside = [f.likelihood for f in frames if f.truth == 'none']
    return {
        'frames': n, 'scenario': gtw.scenario, 'seed': gtw.seed, 'weather': gtw.weather,
        'phase_accuracy': _r(sum(f.phase == f.truth for f in frames) / n, 4),
        'active_accuracy': _r(sum((f.phase in ACTIVE_PHASES) == (f.truth in ACTIVE_PHASES)
                                  for f in frames) / n, 4),
        'unknown_frames': sum(f.phase == 'unknown' for f in frames),
        'confusion_phase': {t: dict(c) for t, c in sorted(conf.items())},
        'zone_begin': begin, 'zone_end': end,
        'changes': _change_rows(frames, gtw, tol),
        'time_to_correct': _time_to_correct(frames, onsets),
        'onsets': {k: _r(v) for k, v in onsets.items() if v != float('inf')},
        'phase_changes': pred_changes, 'truth_changes': truth_changes,
        'flicker': max(0, pred_changes - truth_changes),
        'likelihood_inside': _r(sum(inside) / len(inside)) if inside else None,
        'likelihood_outside': _r(sum(outside) / len(outside)) if outside else None,
        'sign_confusion': sign_confusion(frames),
    }


def evaluate_bag(bag: str, opts: EvalOptions) -> dict:
    """Run and score one bag; ``{'bag', 'error'}`` instead when it cannot be evaluated."""
    started = time.monotonic()
    try:
        if not Path(bag).exists():
            raise EvalError('no such bag')
        gtw, frames, counters = run_bag(bag, opts)
    except (BagError, EvalError) as exc:
        return {'bag': bag, 'error': ' '.join(str(exc).split())}
    stages = counters.pop('_stage_ms')
    res = {'bag': bag, **score(frames, gtw, opts.tolerance_s, opts.legible_px), **counters,
           'stage_ms': {k: stage_summary(v) for k, v in stages.items()},
           'wall_s': round(time.monotonic() - started, 2)}
    res['_stage_ms'] = stages           # raw times for the pooled figures and the histogram
    if opts.keep_frames:
        res['_frames'] = frames
    return res


def stage_summary(ms: list[float]) -> dict:
    """Frames, p50, p99 and max (ms) of one stage's processing times."""
    if not ms:
        return {'frames': 0, 'p50': None, 'p99': None, 'max': None}
    a = np.asarray(ms, float)
    return {'frames': int(a.size), 'p50': _r(float(np.percentile(a, 50)), 2),
            'p99': _r(float(np.percentile(a, 99)), 2), 'max': _r(float(a.max()), 2)}


# --- pooled figures and printing ------------------------------------------------------------

def pooled_stage_ms(results: list[dict]) -> dict[str, list[float]]:
    """Every bag's per-frame processing times, per stage, in pipeline order."""
    out: dict[str, list[float]] = {}
    for r in results:
        for k, v in r.get('_stage_ms', {}).items():
            out.setdefault(k, []).extend(v)
    return out


def summarise(results: list[dict]) -> dict:
    """Figures pooled over the bags that could be evaluated."""
    ok = [r for r in results if 'error' not in r]
    bounds = [r[k] for r in ok for k in ('zone_begin', 'zone_end') if r[k]['truth_t'] is not None]
    changes = [c for r in ok for c in r['changes']]

    def errs(key: str) -> list[float]:
        return [abs(r[key]['error_s']) for r in ok if r[key]['error_s'] is not None]
    out: dict[str, Any] = {
        'bags': len(ok), 'failed': len(results) - len(ok),
        'bounds_recognised': sum(b['recognised'] for b in bounds), 'bounds': len(bounds),
        'changes_recognised': sum(c['recognised'] for c in changes), 'changes': len(changes),
        'flicker': sum(r['flicker'] for r in ok),
        'frames': sum(r['frames'] for r in ok),
        'phase_accuracy': _r(sum(r['phase_accuracy'] * r['frames'] for r in ok)
                             / max(1, sum(r['frames'] for r in ok)), 4),
        'stage_ms': {k: stage_summary(v) for k, v in pooled_stage_ms(ok).items()},
    }
    for key in ('zone_begin', 'zone_end'):
        e = errs(key)
        out[f'{key}_abs_error_s_mean'] = _r(sum(e) / len(e)) if e else None
        out[f'{key}_abs_error_s_max'] = _r(max(e)) if e else None
        out[f'{key}_within_1s'] = sum(x <= 1.0 for x in e)
    return out


def _mark(v: Optional[bool]) -> str:
    return 'N/A' if v is None else ('o' if v else 'x')


def _fmt(v) -> str:
    return '-' if v is None else (f'{v:.3f}' if isinstance(v, float) else str(v))


def table_iv_rows(r: dict) -> list[tuple[str, str]]:
    """(row label, 'o/images/precision/recall') for Table IV."""
    rows = []
    for key, label in (('zone_begin', 'Workzone begins'), ('zone_end', 'Workzone ends')):
        b = r[key]
        rows.append((label, f"{_mark(b['recognised'])}/{b['images']}/"
                            f"{_fmt(b['precision'])}/{_fmt(b['recall'])}"))
    for c in r['changes']:
        label = {'speed_limit': f"Speed limit {c['value']} mph",
                 'lane_shift': f"Lane shift {c['value']}",
                 'lane_closed': f"Lane closed {c['value']}"}[c['kind']]
        rows.append((label, f"{_mark(c['recognised'])}/{c['images']}/"
                            f"{_fmt(c['precision'])}/{_fmt(c['recall'])}"))
    return rows


def print_bag(r: dict, out=sys.stdout) -> None:
    """A readable block per bag."""
    if 'error' in r:
        print(f"\n== {r['bag']}: ERROR {r['error']}", file=out)
        return
    b, e = r['zone_begin'], r['zone_end']
    print(f"\n== {r['bag']}  ({r['scenario']}, {r['weather']}, {r['frames']} frames, "
          f"{r['wall_s']} s)", file=out)
    print(f"   phase accuracy {r['phase_accuracy']:.3f}  active accuracy "
          f"{r['active_accuracy']:.3f}  flicker {r['flicker']}  likelihood inside/outside "
          f"{_fmt(r['likelihood_inside'])}/{_fmt(r['likelihood_outside'])}", file=out)
    print(f"   begin error {_fmt(b['error_s'])} s ({_fmt(b['error_m'])} m), end error "
          f"{_fmt(e['error_s'])} s ({_fmt(e['error_m'])} m); time to correct "
          + ', '.join(f'{k} {_fmt(v)}' for k, v in r['time_to_correct'].items()), file=out)
    for label, cell in table_iv_rows(r):
        print(f'   {label:<24s} {cell}', file=out)


def print_summary(s: dict, out=sys.stdout) -> None:
    """The pooled figures."""
    print(f"\n== summary: {s['bags']} bags ({s['failed']} failed), {s['frames']} frames", file=out)
    print(f"   zone bounds recognised {s['bounds_recognised']}/{s['bounds']}, driving-condition "
          f"changes {s['changes_recognised']}/{s['changes']}, flicker {s['flicker']}, phase "
          f"accuracy {s['phase_accuracy']}", file=out)
    for key in ('zone_begin', 'zone_end'):
        print(f"   {key}: |error| mean {_fmt(s[key + '_abs_error_s_mean'])} s, max "
              f"{_fmt(s[key + '_abs_error_s_max'])} s, within 1 s: {s[key + '_within_1s']}",
              file=out)
    if s.get('stage_ms'):
        print('   processing per frame (ms, in process) p50/p99: ' + ', '.join(
            f"{k} {_fmt(v['p50'])}/{_fmt(v['p99'])}" for k, v in s['stage_ms'].items()),
            file=out)


# --- CLI ------------------------------------------------------------------------------------

def _unit(text: str) -> float:
    v = float(text)
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f'must be in [0, 1], got {text}')
    return v


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='workzone-ros evaluate workzone', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bags', nargs='+', help='synthetic bags (workzone-ros synth)')
    p.add_argument('--signs', choices=('gt', 'pipeline'), default='gt',
                   help='ground-truth signs (the fusion alone) or the perception pipeline')
    p.add_argument('--drop', type=_unit, default=0.0, help='gt: drop an observation (P)')
    p.add_argument('--confuse', type=_unit, default=0.0, help='gt: wrong class (P)')
    p.add_argument('--spurious', type=_unit, default=0.0,
                   help='gt: a false work-zone sign per frame (P)')
    p.add_argument('--spurious-frames', type=int, default=2,
                   help='gt: a false sign lasts 1 to N frames (default 2)')
    p.add_argument('--seed', type=int, default=0, help='noise seed (default 0)')
    p.add_argument('--no-odom', action='store_true', help='no odometry: the fusion works '
                   'over time at its assumed speed')
    p.add_argument('--no-channelizers', action='store_true',
                   help='fusion without the channelizer evidence')
    p.add_argument('--legible-px', type=float, default=12.0,
                   help='GT signs this big (shorter side, px) are legible (default 12)')
    p.add_argument('--tolerance', type=float, default=3.0,
                   help='an event is recognised within this many seconds (default 3)')
    p.add_argument('--color-model', help='pipeline: colour model (.npz)')
    p.add_argument('--classifier-model', help='pipeline: sign classifier (.npz)')
    p.add_argument('--cache', help="pipeline: keep each bag's signs here (per bag and model "
                   'files); reruns of the fusion skip the perception')
    p.add_argument('--fusion', action='append', default=[], metavar='KEY=VALUE',
                   help='override a FusionConfig field (repeatable), e.g. sigma_m=400')
    p.add_argument('--json', help='write every figure here')
    p.add_argument('--report', help='write DIR/README.md with timelines (PNG)')
    p.add_argument('--workers', type=int, default=1, help='bags in parallel (default 1)')
    p.add_argument('--live', action='store_true', help='through the launcher, every node '
                   'and the player at --rate instead (workzone_ros.tools.live_score)')
    p.add_argument('--rate', type=float, default=1.0, help='--live: replay rate (default 1)')
    return p


def _run_all(bags: list[str], opts: EvalOptions, workers: int) -> list[dict]:
    """Bags in a process pool (results in argument order) with a progress line."""
    started = time.monotonic()
    results: list[dict] = []
    args = [(b, opts) for b in bags]
    if workers <= 1 or len(bags) == 1:
        it = (evaluate_bag(*a) for a in args)
        results = _progress(it, len(bags), started)
    else:
        with mp.get_context('spawn').Pool(min(workers, len(bags))) as pool:
            results = _progress(pool.imap(_evaluate_star, args), len(bags), started)
    return results


def _evaluate_star(args: tuple) -> dict:
    return evaluate_bag(*args)


def _progress(it, n: int, started: float) -> list[dict]:
    out = []
    for k, r in enumerate(it, 1):
        out.append(r)
        state = 'ERROR' if 'error' in r else f"{r['frames']} frames"
        print(f'[{k}/{n}] {Path(r["bag"]).name}: {state} '
              f'({time.monotonic() - started:.0f} s)', file=sys.stderr, flush=True)
    return out


def _overrides(items: list[str]) -> tuple:
    """``KEY=VALUE`` strings as typed FusionConfig overrides (ValueError, one line)."""
    import dataclasses
    kinds = {f.name: type(f.default) for f in dataclasses.fields(FusionConfig)}
    out = []
    for item in items:
        key, sep, text = item.partition('=')
        if not sep or key not in kinds:
            raise ValueError(f'--fusion {item!r}: expected KEY=VALUE with KEY one of '
                             f'{", ".join(kinds)}')
        kind = kinds[key]
        try:
            value = (text.lower() in ('1', 'true', 'yes', 'on')) if kind is bool \
                else kind(float(text)) if kind is int else kind(text)
        except ValueError:
            raise ValueError(f'--fusion {item!r}: {text!r} is not a {kind.__name__}') from None
        out.append((key, value))
    FusionConfig(**dict(out))
    return tuple(out)


def main(argv: Optional[list[str]] = None) -> int:
    """Evaluate the work-zone state on bags; prints Table IV per bag and a summary."""
    args = _parser().parse_args(argv)
    try:
        overrides = _overrides(args.fusion)
    except ValueError as exc:
        print(f'workzone-ros evaluate workzone: {exc}', file=sys.stderr)
        return 2
    opts = EvalOptions(signs=args.signs, drop=args.drop, confuse=args.confuse,
                       spurious=args.spurious, spurious_frames=max(1, args.spurious_frames),
                       seed=args.seed, odom=not args.no_odom,
                       channelizers=not args.no_channelizers, legible_px=args.legible_px,
                       tolerance_s=args.tolerance, keep_frames=bool(args.report),
                       color_model=args.color_model, classifier_model=args.classifier_model,
                       cache=args.cache, fusion=overrides)
    if opts.signs == 'pipeline':
        from workzone_ros.tools.workzone_pipeline import check_available
        problem = check_available(opts)
        if problem:
            print(f'workzone-ros evaluate workzone: {problem}', file=sys.stderr)
            return 2
    if args.live:
        from workzone_ros.tools.live_score import evaluate_live
        results = [evaluate_live(b, args.rate) for b in args.bags]
    else:
        results = _run_all(args.bags, opts, args.workers)
    for r in results if not args.live else ():      # a live run printed its own block
        print_bag(r)
    summary = summarise(results)
    print_summary(summary)
    if args.report:
        from workzone_ros.tools.workzone_report import write_report
        path = write_report(args.report, results, summary, opts, sys.argv[1:] if argv is None
                            else argv)
        print(f'report: {path}')
    for r in results:
        r.pop('_frames', None)
        r.pop('_stage_ms', None)
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({'tool': 'workzone-ros evaluate workzone',
                                   'options': opts.__dict__, 'bags': results,
                                   'summary': summary}, indent=2))
        print(f'figures written to {out}')
    errors = [r for r in results if 'error' in r]
    for r in errors:
        print(f"{r['bag']}: {r['error']}", file=sys.stderr)
    return 2 if errors else 0


if __name__ == '__main__':
    sys.exit(main())
