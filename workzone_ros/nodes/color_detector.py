"""``color_detector`` node: camera image (+ LiDAR ROIs) -> ``/workzone/detections``.

Thin wrapper around :mod:`workzone_ros.core.detect` (Seo et al. section III.A, with the
alternatives of Balali and Golparvar-Fard and of Cahail et al. selectable by ``method``). Each
image is converted, handed to the core detector together with the ROIs of the same image stamp (the
projector stamps its ``Rois`` with the image it projected into; a short ring buffer matches them
exactly), and the ``Detections`` payload is published with the image's header.

The projector publishes an image's ROIs after the image (it waits for the LiDAR scan nearest
in time, typically 50-150 ms).  So when the ROI topic has a publisher, each image is held
(at most ``rois_queue`` images, at most ``rois_wait`` seconds of wall time) until its ROIs
arrive; it is then processed at once, in the ROI callback.  An image whose ROIs do not come
is processed on colour alone when the wait expires (a timer), when ROIs of a newer image
arrive (the projector answers in stamp order, so its ROIs will not come), or when the queue
overflows.  Nothing blocks the executor.  Without an ROI publisher (no LiDAR) every image is
processed at once.
"""
from __future__ import annotations

import collections
import os
import statistics
import time
from typing import Any, Optional

from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core import kernels
from workzone_ros.core.color_model import ModelError, default_model, load_model
from workzone_ros.core.detect import ColorDetector, DetectorConfig, RgbLpModel
from workzone_ros.core.proposals import (
    MODES,
    ProposalConfig,
    SignProposer,
    detect_frame,
    stage_plan,
)
from workzone_ros.nodes import conversions as conv
from workzone_ros.nodes.base import ConfigError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.params import image_params, params_from_dataclass
from workzone_ros.resources import config_path

__all__ = ['ColorDetectorNode', 'NODE_CLASS', 'main', 'DEFAULT_MODEL']

DEFAULT_MODEL = str(config_path('models/color_orange.npz'))
PROPOSALS_MODEL = str(config_path('models/color_proposals.npz'))
#: the ``/diagnostics`` key of the frames measured lean (the launcher's report shows it)
LEAN_KEY = 'frames measured lean (behind the camera)'

# Parameters that map one to one onto DetectorConfig fields: default, description and range
# from the field's knob (workzone_ros/core/detect/config.py).  The other ~115 fields are
# refinement constants measured on the development bags (docs/detector_history.md), not
# node parameters.
_CORE = ('method', 'colors', 'threshold', 'scale', 'use_prior', 'open_px', 'close_px',
         'min_radius_px', 'max_radius_px', 'min_area_px', 'nms_iou', 'extension',
         'ext_min_aspect', 'roi_prior', 'roi_threshold', 'roi_margin', 'lidar_confidence',
         'lidar_only', 'lidar_only_confidence', 'smooth_px', 'border_frac', 'use_geometry',
         'roi_relax', 'lidar_only_threshold', 'camera_match', 'foreign_prior',
         'diamond_refine', 'rect_refine', 'pixel_boxes', 'blur_fit', 'max_blur_fits',
         'max_grown', 'max_shifted', 'outline_evidence',
         'rect_needs_edges', 'v_hysteresis', 'grow_level')
_CORE_PARAMS = params_from_dataclass(DetectorConfig, only=_CORE)


class ColorDetectorNode(WorkzoneNode):
    """Colour sign detector node (see the module docstring)."""

    PARAMS = (
        *image_params(),
        Param('image_queue', 5, 'images queued while the detector is busy (sensor QoS keep '
              'last, as deep as the other image subscriptions): 1 = the newest frame wins and '
              'every frame that arrives during a slow one is skipped; 5 absorbs a slow frame '
              'or a core kept busy for 150 ms at 30 fps and catches up (lean frames), at the '
              "cost of the queued frames' latency", min=1, max=30, read_only=True),
        Param('lean_behind', 1.0, 'an image that waited this many frame intervals or more in '
              'the input queue (the detector has fallen behind its camera) is measured lean: '
              'without the second attempts on blobs the first measurement did not box (chroma '
              'fit, grown blob, moved starts), at about half the cost on busy frames, so the '
              'queue drains instead of overflowing; 0 = never', min=0.0, max=30.0),
        Param('rois_topic', '/workzone/rois', 'LiDAR ROIs (Rois payload); empty = no LiDAR',
              read_only=True),
        Param('detections_topic', '/workzone/detections', 'output Detections payload',
              read_only=True),
        Param('model_path', '', 'colour model .npz (empty: config/models/color_orange.npz; '
              'the Cahail et al. HSV ranges if that file does not exist)', read_only=True),
        Param('proposals', 'auto', 'the recall-first colour candidates (core.proposals, '
              'Detection.proposal true) beside the rule-based detector, for the classifier to '
              'decide, which weighs them by their lower share of signs (its proposal_prior): '
              "auto = on frames of any camera other than the colour model's own (its size and "
              'intrinsics; the rules miss real signs there), on = every frame, off = never '
              '(docs/real_cameras.md)', choices=MODES),
        Param('rules', 'on', "the rule-based detector (shape tests and refinements tuned on "
              "the colour model's own camera): on, off, or auto = only where the proposals do "
              "not run or on the model's camera, so that on any other camera the proposals "
              'and the classifier alone decide (measured worse on the real clips than on: '
              'docs/real_cameras.md)', choices=MODES),
        Param('lean_beside_proposals', True, 'on a frame the proposals also go through, the '
              'rule-based detector measures lean (without the second attempts on blobs its '
              'first measurement did not box): those attempts are there for recall, which the '
              'proposals give; measured as accurate on the real clips, at p99 3 ms less '
              '(docs/real_cameras.md)'),
        Param('proposals_model', '', 'colour model with a candidate ranker for the proposals '
              '(empty: config/models/color_proposals.npz)', read_only=True),
        Param('max_candidates', 12, 'proposals per frame at most, best ranked first', min=1,
              max=100),
        Param('proposal_threshold', 0.5, 'P(sign colour | pixel) of a proposal pixel',
              min=0.01, max=1.0),
        Param('camera_info_topic', '/camera/camera_info', "the frames' CameraInfo: the model's "
              "spatial prior and fixed mounting row apply only to its own camera's frames "
              '(camera_match); empty = judge by the frame size alone', read_only=True),
        Param('rois_buffer', 30, 'ROIs messages kept for stamp matching', min=1, max=1000),
        Param('rois_wait', 0.25, 'hold an image at most this long (wall time, s) for its '
              'ROIs when the ROI topic has a publisher; 0 = never wait', min=0.0, max=5.0),
        Param('rois_queue', 4, 'images held for their ROIs at most', min=1, max=50),
    ) + _CORE_PARAMS
    INPUT_TOPICS = ('image_topic', 'rois_topic', 'camera_info_topic')

    def __init__(self, **kwargs: Any) -> None:
        """Create the node; raises ConfigError on an unreadable model file."""
        super().__init__('color_detector', **kwargs)
        p = self.params
        self._intrinsics: Optional[tuple[float, float, float, float]] = None
        path = p.model_path or DEFAULT_MODEL
        try:
            if p.model_path or os.path.exists(path):
                self._model = load_model(path)
                source = path
            else:
                self._model = default_model()
                source = 'Cahail et al. HSV ranges (no trained model file)'
                self.get_logger().warning(f'{path} not found: using the Cahail et al. HSV ranges; '
                                          "train one with 'workzone-ros train color'")
            self._detector = self._make_detector()
            self._proposal_model = load_model(p.proposals_model or PROPOSALS_MODEL) \
                if p.proposals != 'off' else None
            self._proposer = self._make_proposer()
        except (ModelError, ValueError) as exc:
            self.destroy_node()
            raise ConfigError(str(exc)) from None
        self.get_logger().info(f'colour model: {source}; classes {self._model.classes}')
        # the compiled kernels loaded (or compiled) before the first image, not in its
        # callback, where the frames behind it would be dropped
        kernels.warm()
        self._rois: collections.OrderedDict[int, list[interfaces.Roi]] = \
            collections.OrderedDict()
        self._frames = 0
        #: what the last frame went through (``/diagnostics`` key ``stages``)
        self._stages = 'no frame yet'
        self._held_counts = collections.Counter()
        # when the middleware received the last images (system clock ns): the frame interval
        self._arrivals: collections.deque[int] = collections.deque(maxlen=11)
        self._lean_frames = 0
        # images waiting for their ROIs: stamp ns -> (deadline monotonic s, image, header)
        self._pending: collections.OrderedDict[int, tuple] = collections.OrderedDict()
        self._pub = self.reliable_publisher(String, p.detections_topic)
        self._image_sub = self.image_subscription(p.image_topic, self._on_image, p.compressed,
                                                  depth=p.image_queue)
        self._rois_sub = None
        if p.rois_topic:
            self._rois_sub = self.reliable_subscription(String, p.rois_topic, self._on_rois,
                                                        depth=10)
            self._timer = self.create_timer(0.02, self._expire)
        self._info_sub = None
        if p.camera_info_topic:
            self._info_sub = self.reliable_subscription(CameraInfo, p.camera_info_topic,
                                                        self._on_info, depth=1)

    def _make_detector(self) -> ColorDetector:
        p = self.params
        cfg = DetectorConfig(**{q.attr: getattr(p, q.attr) for q in _CORE_PARAMS})
        lp = None
        if 'rgb_lp_thresholds' in self._model.extras:
            lp = RgbLpModel(self._model.extras['rgb_lp_thresholds'])
        det = ColorDetector(self._model, cfg, lp)
        det.set_camera(self._intrinsics)
        return det

    def _make_proposer(self) -> Optional[SignProposer]:
        p = self.params
        if p.proposals == 'off':
            return None
        if self._proposal_model is None:
            self._proposal_model = load_model(p.proposals_model or PROPOSALS_MODEL)
        cfg = ProposalConfig(threshold=p.proposal_threshold,
                             strong=max(ProposalConfig.strong, p.proposal_threshold),
                             max_candidates=p.max_candidates)
        return SignProposer(self._proposal_model, cfg)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Rebuild the detector with the new values (rejected values never get here)."""
        try:
            self._detector = self._make_detector()
            self._proposer = self._make_proposer()
        except (ModelError, ValueError) as exc:
            self.get_logger().error(f'parameter change not applied: {exc}')

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: the ROIs of the old pass are forgotten, images held for theirs go
        on colour alone now (their ROIs will not come)."""
        self._rois.clear()
        for _, *held in list(self._pending.values()):
            self._held_counts['time jump'] += 1
            self._detect(*held)
        self._pending.clear()

    # -- callbacks --
    def _on_info(self, msg: CameraInfo) -> None:
        """The frames' intrinsics, for the detector's camera match (an invalid CameraInfo
        raises ConversionError: dropped with its reason, the last valid one is kept)."""
        k = conv.camera_info_to_numpy(msg).K
        intrinsics = (float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))
        if intrinsics != self._intrinsics:
            self._intrinsics = intrinsics
            self._detector.set_camera(intrinsics)
            same = self._detector.same_camera(int(msg.width), int(msg.height))
            rules, props = stage_plan(self.params.proposals, self.params.rules, same)
            self.get_logger().info(
                f'camera {msg.width}x{msg.height} fx {intrinsics[0]:.1f}: '
                + ("the model's camera (its prior and mounting row apply)" if same else
                   "not the model's camera: location-free prior, no fixed mounting row")
                + '; colour stages: '
                + _stages_text(rules, props, props and self.params.lean_beside_proposals))

    def _on_rois(self, msg: String) -> None:
        rois = conv.string_to_payload(msg, interfaces.Rois)
        stamp = rois.header.stamp.to_ns()
        self._rois[stamp] = list(rois.rois)
        while len(self._rois) > self.params.rois_buffer:
            self._rois.popitem(last=False)
        # the held image of this stamp, and older ones whose ROIs will not come now
        for t in [t for t in self._pending if t <= stamp]:
            _, *held = self._pending.pop(t)
            self._held_counts['matched' if t == stamp else 'superseded'] += 1
            self._detect(*held)

    def _on_image(self, msg: Image) -> None:
        self._hold_or_process(msg, msg.header, self._behind())

    def _behind(self) -> bool:
        """Whether the image being handled waited ``lean_behind`` frame intervals or more
        in the input queue (the interval: the median gap between the last images' arrivals;
        unknown, so False, before two images arrived)."""
        if self.input_received_ns:
            self._arrivals.append(self.input_received_ns)
        if self.params.lean_behind <= 0 or len(self._arrivals) < 2:
            return False
        t = sorted(self._arrivals)
        interval = statistics.median(b - a for a, b in zip(t, t[1:])) * 1e-9
        return interval > 0 and self.input_wait_s >= self.params.lean_behind * interval

    def _waiting_for_rois(self) -> bool:
        """True when ROIs can come: a topic is set, a publisher exists, waiting is on."""
        p = self.params
        return bool(self._rois_sub is not None and p.rois_wait > 0
                    and self.count_publishers(p.rois_topic) > 0)

    def _hold_or_process(self, msg: Any, header: Any, lean: bool = False) -> None:
        stamp = conv.stamp_to_time(header.stamp).to_ns()
        if stamp in self._rois or not self._waiting_for_rois():
            self._detect(msg, header, lean)
            return
        old = self._pending.get(stamp)            # a repeated stamp keeps its first deadline
        deadline = old[0] if old else time.monotonic() + self.params.rois_wait
        self._pending[stamp] = (deadline, msg, header, lean)
        while len(self._pending) > self.params.rois_queue:
            _, (_, *held) = self._pending.popitem(last=False)
            self._held_counts['queue overflow'] += 1
            self._detect(*held)

    def _expire(self) -> None:
        """Timer: images whose ROIs did not come within ``rois_wait`` go on colour alone."""
        now = time.monotonic()
        for t in [t for t, held in self._pending.items() if held[0] <= now]:
            _, *held = self._pending.pop(t)
            self._held_counts['expired'] += 1
            self._detect(*held)

    def _detect(self, msg: Any, header: Any, lean: bool = False) -> None:
        try:
            bgr = (conv.compressed_to_numpy(msg) if isinstance(msg, CompressedImage)
                   else conv.image_to_numpy(msg, 'bgr8'))
        except conv.ConversionError as exc:
            self.drop(self.image_topic_of(msg), str(exc))
            return
        self._process(bgr, header, lean)

    def _process(self, bgr, header, lean: bool = False) -> None:
        head = conv.header_to_payload(header)
        rois: Optional[list] = self._rois.get(head.stamp.to_ns())
        p = self.params
        dets, rules, props = detect_frame(self._detector, self._proposer, bgr, p.proposals,
                                          p.rules, rois or (), lean, p.lean_beside_proposals)
        self._stages = _stages_text(rules, props, props and p.lean_beside_proposals)
        channelizers = None                 # None: not counted on this frame
        if rules:
            self._lean_frames += lean
            channelizers = len(self._detector.channelizers)
            for kind in self._detector.budget_spent:
                self._held_counts[f'frames over the {kind} budget'] += 1
        self._pub.publish(conv.payload_to_string(interfaces.Detections(
            header=head, detections=dets, channelizers=channelizers)))
        self._frames += 1


    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """Images held for their ROIs by how the wait ended, the frames whose budget of
        costly measurements (``max_blur_fits``, ``max_grown``, ``max_shifted``) ran out, and
        the frames detected and of them measured lean (``lean_behind``), and the stages the
        last frame went through (``stages``: rules, proposals or both, by ``proposals``,
        ``rules`` and the camera)."""
        return [(k if k.startswith('frames') else f'images held: {k}', str(v))
                for k, v in sorted(self._held_counts.items())] + [
            ('frames detected', str(self._frames)),
            (LEAN_KEY, str(self._lean_frames)), ('stages', self._stages)]


def _stages_text(rules: bool, proposals: bool, lean: bool) -> str:
    """'rules', 'rules (lean) + proposals', 'proposals' or 'none'."""
    return ' + '.join(name for name, on in (('rules' + (' (lean)' if lean else ''), rules),
                                            ('proposals', proposals)) if on) or 'none'


NODE_CLASS = ColorDetectorNode


def main(args: Optional[list[str]] = None) -> int:
    """Run the node (Jazzy-style main)."""
    return run_node(ColorDetectorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
