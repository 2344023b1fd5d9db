"""One bag through the work-zone fusion for ``workzone-ros evaluate workzone``: the options of a
run (:class:`EvalOptions`), the per-frame record (:class:`Frame`), where the signs come from
(:class:`GtSignSource` with its noise model, or the perception pipeline) and the run itself
(:func:`run_bag`).  The rules are in the docstring of :mod:`workzone_ros.tools.eval_workzone`.
"""
from __future__ import annotations

import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from workzone_ros.core import signs as catalogue
from workzone_ros.core.fusion import FusionConfig, WorkzoneFusion
from workzone_ros.interfaces import Box, GtSigns, GtWorkzone, PayloadError, Sign, Signs, decode
from workzone_ros.tools.eval_tracker import _xywh

__all__ = ['SPEED_READ_PX', 'CHANNELIZER_PX', 'EvalError', 'EvalOptions', 'fusion_config',
           'Frame', 'legible', 'GtSignSource', 'run_bag']

SPEED_READ_PX = 24.0          # the digit reader's smallest legible speed-limit box
CHANNELIZER_PX = 6.0          # GT drums / cones at least this big are counted
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
    #: ``--signs pipeline``: the stages' boxes and this frame's truth for
    #: :mod:`workzone_ros.tools.workzone_stages` (``dets``, ``tracks`` as the pipeline's
    #: ``last_stages``; ``gt_wz``: (class_key, box) of the legible work-zone signs;
    #: ``gt_other``: the boxes of the other GT signs, illegible or general); None otherwise
    stages: Optional[dict] = None


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
    boxes = getattr(source, 'last_stages', None)
    if boxes is not None:
        wz = [s.category == 'workzone' and legible(s, opts.legible_px) for s in gt.signs]
        f.stages = {**boxes, 'gt_wz': [(s.class_key, _xywh(s.box))
                                       for s, ok in zip(gt.signs, wz) if ok],
                    'gt_other': [_xywh(s.box) for s, ok in zip(gt.signs, wz) if not ok]}
    return f
