"""``classifier`` node: image + ``/workzone/tracks`` -> ``/workzone/signs`` (Seo et al. III.B).

Thin wrapper around :mod:`workzone_ros.core.classifier` (log-polar + PCA + SVM with a
``background`` reject class), :mod:`workzone_ros.core.digits` (the work-zone speed limit's
value) and :mod:`workzone_ros.core.sign_distance` (LiDAR range, else apparent size).

Images are kept in a short ring buffer keyed by stamp; a ``Tracks`` payload (or a
``Detections`` payload when tracking is off: ``input_topic: /workzone/detections``) is
processed with the image of exactly the same stamp, every box of the frame in one batch.
A ``Signs`` payload is published for every frame, with an empty list when there is nothing,
so a listener can tell a quiet scene from a dead camera.  Boxes the classifier rejects
(``background``) are not published (they are counted in ``/diagnostics``); a box too small
to classify, or mostly outside the image, is published as ``unknown`` with the reason, never
as a guess.  ``/workzone/debug_image`` (sensor QoS) shows the frame with the signs and a
banner with the phase of ``/workzone/state``; ``debug_image: false`` turns it off.

With ``general_signs: true`` (the default) every ``general_every``-th frame (3) that gets a
``Signs`` payload is also searched for general US signs (:mod:`workzone_ros.core.general`:
stop, yield, do-not-enter, warning, speed limit, guide signs, mile markers); they are
published with category ``general`` and never change the work-zone state.  ``false`` costs
nothing: the recogniser is not even loaded.
"""
from __future__ import annotations

import collections
from typing import Any, Optional

from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import String

from workzone_ros import interfaces as I
from workzone_ros.core.overlay import draw_debug
from workzone_ros.core.recognition import (
    PROPOSAL_PRIOR,
    RecognitionConfig,
    SignRecognizer,
    general_signs,
)
from workzone_ros.core.sign_distance import focal_from_fov
from workzone_ros.core.sync import ExactStampPairs
from workzone_ros.nodes import conversions as conv
from workzone_ros.nodes.base import ConfigError, InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.params import image_params
from workzone_ros.resources import config_path

__all__ = ['ClassifierNode', 'NODE_CLASS', 'main']


class ClassifierNode(WorkzoneNode):
    """Sign classification node (see the module docstring)."""

    PARAMS = (
        *image_params(),
        Param('input_topic', '/workzone/tracks', 'boxes to classify: Tracks (or Detections '
              'when tracking is off)', read_only=True),
        Param('rois_topic', '/workzone/rois', "LiDAR ROIs: a sign's distance is its ROI's "
              'range (empty: distance from the apparent size only)', read_only=True),
        Param('camera_info_topic', '/camera/camera_info', 'focal length for the size-based '
              'distance', read_only=True),
        Param('state_topic', '/workzone/state', 'the phase shown in the debug banner '
              '(empty: no banner)', read_only=True),
        Param('signs_topic', '/workzone/signs', 'output Signs payloads', read_only=True),
        Param('debug_image_topic', '/workzone/debug_image', 'output debug image',
              read_only=True),
        Param('debug_image', True, 'publish the debug image'),
        Param('model_path', '', 'classifier model (empty: config/models default)',
              read_only=True),
        Param('margin', 0.1, 'crop margin around a box (fraction of its size per side)',
              min=0.0, max=1.0),
        Param('min_size', 12, 'boxes smaller than this (px, either side) are published as '
              'unknown', min=1, max=1000),
        Param('min_visible', 0.5, 'boxes with less than this share inside the image are '
              'published as unknown', min=0.0, max=1.0),
        Param('read_speed', True, 'read the value of work-zone speed limit signs'),
        Param('proposal_prior', PROPOSAL_PRIOR, 'added to the log-odds of background on a box '
              'only the colour proposals found (a Detection or Track with proposal true): '
              "ln of the odds that a rule-checked box is a sign over a proposal's, measured on "
              "your camera's labelled clips by 'workzone-ros evaluate real_signs' (0: weigh "
              'proposals like rule-checked boxes)', min=0.0, max=20.0),
        Param('general_signs', True, 'also recognise general signs (stop, yield, '
              'do-not-enter, warning, speed limit, guide, mile markers) on the whole frame'),
        Param('general_every', 3, 'search every n-th frame for general signs (they never '
              'change the work-zone state; 1: every frame)', min=1, max=100),
        Param('assumed_hfov_deg', 60.0, 'horizontal field of view used for distances until a '
              'CameraInfo arrives', min=1.0, max=179.0),
        Param('image_buffer', 10, 'images kept while waiting for their boxes', min=1,
              max=100, read_only=True),
        Param('rois_buffer', 30, 'ROIs payloads kept for stamp matching', min=1, max=1000),
    )
    INPUT_TOPICS = ('image_topic', 'input_topic', 'rois_topic', 'camera_info_topic')

    def __init__(self, **kwargs: Any) -> None:
        """Create the node; raises ConfigError on a missing or invalid model file."""
        super().__init__('classifier', **kwargs)
        p = self.params
        self._model = self._load_model(p.model_path)
        self._recognizer = SignRecognizer(self._model, self._recognition_config())
        self._general = self._general_detector() if p.general_signs else None
        self._frames = 0
        if p.read_speed:
            from workzone_ros.core.digits import warm_up
            warm_up()       # the digit classifier and templates, before the first frame
        # each image with its boxes (the same stamp), whichever comes first
        self._pairs = ExactStampPairs(self.params.image_buffer)
        self._rois: collections.OrderedDict[int, list[I.Roi]] = collections.OrderedDict()
        self._focal: Optional[float] = None
        self._state: Optional[I.WorkzoneState] = None
        self._last_ns: Optional[int] = None
        self.counts = collections.Counter()
        self._signs_pub = self.reliable_publisher(String, p.signs_topic)
        self._debug_pub = self.sensor_publisher(Image, p.debug_image_topic)
        self._image_sub = self.image_subscription(p.image_topic, self._on_image, p.compressed)
        self._input_sub = self.reliable_subscription(String, p.input_topic, self._on_boxes)
        self._rois_sub = (self.reliable_subscription(String, p.rois_topic, self._on_rois)
                          if p.rois_topic else None)
        self._info_sub = (self.reliable_subscription(CameraInfo, p.camera_info_topic,
                                                     self._on_info, depth=1)
                          if p.camera_info_topic else None)
        self._state_sub = (self.reliable_subscription(String, p.state_topic, self._on_state,
                                                      depth=1, transient_local=True)
                           if p.state_topic else None)

    def _recognition_config(self) -> RecognitionConfig:
        p = self.params
        return RecognitionConfig(margin=p.margin, min_size=p.min_size,
                                 min_visible=p.min_visible, read_speed=p.read_speed,
                                 proposal_prior=p.proposal_prior)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Apply live changes of margin, min_size, min_visible, read_speed, proposal_prior,
        general_signs."""
        self._recognizer.config = self._recognition_config()
        if not self.params.general_signs:
            self._general = None
        elif self._general is None:
            self._general = self._general_detector()

    def _general_detector(self):
        from workzone_ros.core.general import GeneralSignDetector
        return GeneralSignDetector.sharing(self._model)     # the CNN is loaded once

    def _load_model(self, path: str):
        from workzone_ros.core import classifier as core
        path = path or str(config_path(core.DEFAULT_MODEL))
        try:
            model = core.load_model(path)
        except (core.ModelError, OSError, ValueError) as exc:
            self.destroy_node()
            raise ConfigError(f'classifier model: {exc}') from None
        self.get_logger().info(f'classifier model {path}: {len(model.classes)} classes')
        return model

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: the images, boxes and ROIs waiting by stamp are from the old pass."""
        self._pairs.clear()
        self._rois.clear()
        self._last_ns = None

    # --- callbacks ------------------------------------------------------------------------

    def _on_info(self, msg: CameraInfo) -> None:
        self._focal = float(conv.camera_info_to_numpy(msg).K[1, 1])

    def _on_state(self, msg: String) -> None:
        self._state = conv.string_to_payload(msg, I.WorkzoneState)

    def _on_rois(self, msg: String) -> None:
        rois = conv.string_to_payload(msg, I.Rois)
        self._rois[rois.header.stamp.to_ns()] = list(rois.rois)
        while len(self._rois) > self.params.rois_buffer:
            self._rois.popitem(last=False)

    def _on_image(self, msg: Any) -> None:
        ns = conv.stamp_to_time(msg.header.stamp).to_ns()
        # converted on arrival: a malformed image is dropped with its reason now, not
        # buffered until it silently falls out of the ring
        image = ((conv.compressed_to_numpy(msg) if isinstance(msg, CompressedImage)
                  else conv.image_to_numpy(msg, 'bgr8')), msg.header)
        pair = self._pairs.add_image(ns, image)
        if pair is not None:
            self._process(*pair)

    def _on_boxes(self, msg: String) -> None:
        payload = conv.string_to_payload(msg)
        if not isinstance(payload, (I.Tracks, I.Detections)):
            raise InputError(f'expected Tracks or Detections, got {I.schema_of(payload)}')
        pair, dropped = self._pairs.add_boxes(payload.header.stamp.to_ns(), payload)
        for reason in dropped:
            self.drop(self.params.input_topic, reason)
        if pair is not None:
            self._process(*pair)

    # --- the step -------------------------------------------------------------------------

    def _process(self, image: tuple, payload: Any) -> None:
        frame, header = image
        ns = payload.header.stamp.to_ns()
        if self._last_ns is not None and ns < self._last_ns:
            if self._last_ns - ns <= 2_000_000_000:
                raise InputError('boxes older than the last processed frame')
            self.get_logger().info('time jumped back: buffers reset')
            self._rois.clear()
        self._last_ns = ns
        for reason in self._pairs.processed(ns):
            self.drop(self.params.input_topic, reason)
        items = payload.tracks if isinstance(payload, I.Tracks) else payload.detections
        signs, rejected = self._classify(frame, items, self._rois.get(ns, ()))
        self._signs_pub.publish(conv.payload_to_string(I.Signs(header=payload.header,
                                                                signs=signs)))
        if self.params.debug_image:
            overlay = draw_debug(frame, signs, rejected, self._state,
                                 show_banner=bool(self.params.state_topic))
            self._debug_pub.publish(conv.numpy_to_image(overlay, 'bgr8', header))

    def _focal_px(self, width: int) -> float:
        return self._focal or focal_from_fov(width, self.params.assumed_hfov_deg)

    def _classify(self, frame, items, rois) -> tuple[list[I.Sign], list[I.Box]]:
        """Signs of one frame, and the boxes rejected as background."""
        focal = self._focal_px(frame.shape[1])
        signs, rejected = self._recognizer.recognize(frame, items, focal, rois)
        self._frames += 1
        if self._general is not None and self._frames % self.params.general_every == 0:
            extra = general_signs(self._general.detect(frame), focal, rois, signs)
            self.counts['general'] += len(extra)
            signs = signs + extra
        self.counts['signs'] += sum(1 for s in signs if s.category != 'unknown')
        self.counts['unknown'] += sum(1 for s in signs if s.category == 'unknown')
        self.counts['rejected'] += len(rejected)
        return signs, rejected

    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """Counts of published, unknown and rejected boxes."""
        return [(f'boxes {k}', str(v)) for k, v in sorted(self.counts.items())]


NODE_CLASS = ClassifierNode


def main(args: Optional[list[str]] = None) -> int:
    """Entry point ``classifier``."""
    return run_node(ClassifierNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
