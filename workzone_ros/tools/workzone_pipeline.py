"""``--signs pipeline`` of ``workzone-ros evaluate workzone``: signs from the camera image.

The chain the nodes run, in process and in frame order, from ``workzone_ros.core``:

* the colour detector (``core.detect.ColorDetector`` with the trained orange model,
  ``config/models/color_orange.npz``, as ``evaluate tracker`` builds it), and on the frames
  of any camera other than that model's the recall-first proposals beside it and the
  detector measured lean (``core.proposals`` with ``config/models/color_proposals.npz``, as
  the node's defaults ``proposals: auto``, ``lean_beside_proposals: true``);
* the mean-shift tracker (``core.track.MultiTracker``, ``TrackerConfig()`` defaults), told
  the classifier's answers on each frame's tracks before the next frame
  (``MultiTracker.confirm``, as the ``tracker`` node hears ``/workzone/signs``);
* the sign classifier (``core.classifier.load_model``, ``classify_boxes``) with the
  classifier node's rules: boxes under 12 px on a side or less than half inside the image
  are ``unknown`` (never guessed), ``background`` answers are not published, a work-zone
  speed limit's value is read with ``core.digits.read_speed_limit`` on its crop, and the
  distance comes from the apparent size and CameraInfo's focal length
  (``core.sign_distance.estimate_distance``; no LiDAR ROIs here);
* the general signs of the whole frame on every third frame (``core.general.
  GeneralSignDetector``, as the classifier node's ``general_signs: true`` and
  ``general_every: 3``; ``opts.general_signs = False`` leaves them out).

Each frame's channelizer count is the colour detector's (``ColorDetector.channelizers``:
the blobs it rejected as banded drums or cones, one per place), as the ``color_detector``
node publishes it in ``Detections.channelizers``.  The modules are imported lazily:
:func:`check_available` says in one line what is missing.

After each frame ``last_stages`` holds what the stages gave (for
:mod:`workzone_ros.tools.workzone_stages`): ``dets``, the colour detector's boxes, and
``tracks``, the published track boxes, each with the classifier's answer for it (its class,
``unknown`` when it was not classified, ``background`` when the answer was not published).
Boxes are ``(x, y, w, h)``.

:class:`CachedSource` (``--cache DIR``) stores a bag's Signs once per bag and model files
(JSON lines of ``Signs`` payloads): reruns of the fusion then skip the perception and the
images.
"""
from __future__ import annotations

import json
import os
import time
from collections import defaultdict
from pathlib import Path
from typing import Optional

from workzone_ros.interfaces import GtSigns, Sign, Signs, decode, encode
from workzone_ros.resources import config_path

__all__ = ['PipelineSource', 'CachedSource', 'check_available', 'MIN_SIZE', 'MIN_VISIBLE',
           'MARGIN']

MIN_SIZE = 12           # classifier node: min_size
MIN_VISIBLE = 0.5       # classifier node: min_visible
MARGIN = 0.1            # classifier node: margin
GENERAL_EVERY = 3       # classifier node: general_every
PROPOSALS_MODEL = str(config_path('models/color_proposals.npz'))
# 2: frames carry the colour detector's channelizer count; 3: general signs; 4: general
# signs every GENERAL_EVERY-th frame; 5: the classifier's answers confirm tracks;
# 6: the stages' boxes (``last_stages``); 7: the proposals on another camera's frames
_CACHE_VERSION = 7


def _classifier_path(opts) -> str:
    from workzone_ros.core import classifier
    from workzone_ros.resources import config_path
    return opts.classifier_model or str(config_path(classifier.DEFAULT_MODEL))


def check_available(opts) -> str:
    """'' when the pipeline can run, else one line saying what is missing."""
    for mod in ('detect', 'track', 'classifier', 'digits', 'sign_distance', 'features'):
        try:
            __import__(f'workzone_ros.core.{mod}')
        except ImportError as exc:
            return f'--signs pipeline needs workzone_ros.core.{mod} ({exc})'
    path = _classifier_path(opts)
    if not os.path.isfile(path):
        return (f'--signs pipeline: no sign classifier at {path} (train one with '
                "'workzone-ros train classifier' or pass --classifier-model)")
    return ''


def _file_key(path: str) -> str:
    st = os.stat(path)
    return f'{st.st_size}_{int(st.st_mtime)}'


class CachedSource:
    """The pipeline's Signs of one bag, computed once and stored in ``folder``.

    The file is named after the bag and the colour and classifier model files (size and
    mtime), and written only when a bag was run to its end.  ``needs_images`` is False when
    the bag is cached: the caller does not decode images then.
    """

    name = 'pipeline'

    def __init__(self, opts, bag_name: str, folder: str) -> None:
        from workzone_ros.tools.eval_tracker import DEFAULT_MODEL
        color = opts.color_model or DEFAULT_MODEL
        key = '_'.join([f'v{_CACHE_VERSION}'] + [_file_key(p) if os.path.exists(p) else 'none'
                                                 for p in (color, _classifier_path(opts),
                                                           PROPOSALS_MODEL)])
        self.path = Path(folder) / f'{bag_name}_{key}.jsonl'
        self.opts = opts
        self.stored: dict[int, tuple[Signs, Optional[int], Optional[dict]]] = {}
        self.new: list[str] = []
        self.inner: Optional[PipelineSource] = None
        #: the stages' boxes of the last frame (as :class:`PipelineSource`), stored or computed
        self.last_stages: Optional[dict] = None
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                row = json.loads(line)
                signs = decode(json.dumps(row['signs']), Signs)
                self.stored[signs.header.stamp.to_ns()] = (signs, row['channelizers'],
                                                           row.get('stages'))
        self.needs_images = not self.stored

    def __call__(self, gt: GtSigns, image, focal: Optional[float]
                 ) -> tuple[list[Sign], Optional[int]]:
        """The stored signs of this frame, else the pipeline's (remembered for flush)."""
        ns = gt.header.stamp.to_ns()
        if ns in self.stored:
            signs, channel, self.last_stages = self.stored[ns]
            return list(signs.signs), channel
        if self.inner is None:
            self.inner = PipelineSource(self.opts)
        out, channel = self.inner(gt, image, focal)
        self.last_stages = getattr(self.inner, 'last_stages', None)
        self.new.append(json.dumps({'channelizers': channel, 'signs': json.loads(
            encode(Signs(header=gt.header, signs=out))), 'stages': self.last_stages}))
        return out, channel

    @property
    def timings(self) -> dict[str, list[float]]:
        """Per-stage times of the frames computed in this run (none for cached frames)."""
        return self.inner.timings if self.inner is not None else {}

    def flush(self) -> None:
        """Write the computed frames (the whole bag) to the cache file."""
        if self.new:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_suffix('.tmp')
            tmp.write_text('\n'.join(self.new) + '\n')
            tmp.replace(self.path)
            self.new = []


class PipelineSource:
    """Detector + tracker + classifier on each frame (module docstring)."""

    name = 'pipeline'
    needs_images = True

    def __init__(self, opts) -> None:
        from workzone_ros.core.classifier import load_model
        from workzone_ros.core.recognition import RecognitionConfig, SignRecognizer
        from workzone_ros.core.track import MultiTracker, TrackerConfig
        from workzone_ros.tools.eval_tracker import _ColorDetector
        self.detector = _ColorDetector(opts.color_model)
        from workzone_ros.core.color_model import load_model as load_color
        from workzone_ros.core.proposals import SignProposer
        self.proposer = SignProposer(load_color(PROPOSALS_MODEL))
        self.tracker = MultiTracker(TrackerConfig())
        self.model = load_model(_classifier_path(opts))
        self.recognizer = SignRecognizer(self.model, RecognitionConfig(
            margin=MARGIN, min_size=MIN_SIZE, min_visible=MIN_VISIBLE))
        #: processing time per stage and frame (ms): detector, tracker, classifier, general
        self.timings: dict[str, list[float]] = defaultdict(list)
        self.general = None
        if getattr(opts, 'general_signs', True):
            from workzone_ros.core.general import GeneralSignDetector
            self.general = GeneralSignDetector.sharing(self.model)
        #: general signs on every n-th frame, as the classifier node's ``general_every``
        self.general_every = int(getattr(opts, 'general_every', GENERAL_EVERY))
        self._frames = 0
        #: the stages' boxes of the last frame (module docstring)
        self.last_stages: Optional[dict] = None

    def __call__(self, gt: GtSigns, image, focal: Optional[float]
                 ) -> tuple[list[Sign], Optional[int]]:
        """Signs of one frame (the classifier node's output) and its channelizer count."""
        t0 = time.perf_counter()
        dets = self._detect(image, gt)
        t1 = time.perf_counter()
        found = getattr(self.detector.det, 'channelizers', None)
        channel = None if found is None else len(found)
        tracks = self.tracker.step(image, dets, stamp=gt.header.stamp.to_ns() * 1e-9)
        t2 = time.perf_counter()
        self.timings['color_detector'].append((t1 - t0) * 1e3)
        self.timings['tracker'].append((t2 - t1) * 1e3)
        signs = self.classify(image, tracks, focal)
        # the classifier's answers go back to the tracker, as /workzone/signs to the node
        from workzone_ros.core.track.confirmation import classifier_verdicts
        self.tracker.confirm(*classifier_verdicts([t.track_id for t in tracks], signs))
        self.last_stages = _stage_boxes(dets, tracks, signs)
        return signs, channel

    def _detect(self, image, gt) -> list:
        """The colour detector node's detections of this frame: on a camera other than the
        colour model's, the rules measured lean and the proposals beside them."""
        from workzone_ros.core.proposals import detect_frame
        det = getattr(self.detector, 'det', None)
        if det is None:                         # a stand-in detector: no camera to judge
            return self.detector(image, gt)
        return detect_frame(det, self.proposer, image)[0]

    def classify(self, frame, items, focal: Optional[float]) -> list[Sign]:
        """As ``nodes/classifier.py`` (the same ``core.recognition`` rules), no LiDAR."""
        t0 = time.perf_counter()
        signs = self.recognizer.recognize(frame, items, focal)[0]
        t1 = time.perf_counter()
        self.timings['classifier'].append((t1 - t0) * 1e3)
        self._frames += 1
        if self.general is None or self._frames % self.general_every:
            return signs
        from workzone_ros.core.recognition import general_signs
        signs = signs + general_signs(self.general.detect(frame), focal, (), signs)
        self.timings['general_signs'].append((time.perf_counter() - t1) * 1e3)
        return signs


def _xywh(b) -> list[float]:
    return [float(b.x), float(b.y), float(b.w), float(b.h)]


def _stage_boxes(dets, tracks, signs: list[Sign]) -> dict:
    """``last_stages`` of one frame (module docstring); JSON-ready for the cache."""
    answer = {s.track_id: s.class_key for s in signs if s.track_id is not None}
    return {'dets': [_xywh(d.box) for d in dets],
            'tracks': [[_xywh(t.box), answer.get(t.track_id, 'background')] for t in tracks]}
