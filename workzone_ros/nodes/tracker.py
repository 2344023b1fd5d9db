"""``tracker`` node: camera image + ``/workzone/detections`` -> ``/workzone/tracks`` (Lee et al.).

Thin wrapper around :class:`workzone_ros.core.track.MultiTracker`.  Images are kept in a
short ring buffer keyed by their stamp; a ``Detections`` payload is processed with the image
of exactly the same stamp (the detector stamps its output with the image it ran on).  When the
detections arrive first they wait (a few frames) for their image.  Frames are processed in
stamp order; anything older than the last processed frame is dropped (latest-frame-wins), and
a stamp that jumps backwards (a looping bag) resets the tracks.

The classifier's ``Signs`` on ``signs_topic`` confirm or reject the tracks of the frame they
answer (``needs_confirmation``, :mod:`workzone_ros.core.track.confirmation`): a track id this
node published for that stamp with no sign of any category was rejected as background.
An empty ``signs_topic``: no confirmation (the previous rule).
"""
from __future__ import annotations

import collections
from typing import Any, Optional

from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from workzone_ros.core.sync import ExactStampPairs
from workzone_ros.core.track import MultiTracker, TrackerConfig
from workzone_ros.core.track.confirmation import classifier_verdicts
from workzone_ros.interfaces import Detections, Signs, Tracks
from workzone_ros.nodes.base import InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import (
    compressed_to_numpy,
    image_to_numpy,
    payload_to_string,
    stamp_to_time,
    string_to_payload,
)
from workzone_ros.nodes.params import image_params, params_from_dataclass

__all__ = ['TrackerNode', 'NODE_CLASS', 'main']

#: The core's switches for the evaluation's comparisons (Lee et al.'s detection-only baseline
#: and their association rule, CamShift as a peer): ``evaluate tracker`` names them as its
#: configurations; a node always runs the mean-shift tracker with our association.
EVALUATION_ONLY = ('mode', 'method', 'association')
#: One parameter per other TrackerConfig field: default, description and range from its
#: knob().  The motion cue is off unless configured (config/workzone.yaml turns it on): the
#: node's own test draws a sign approached far slower (2 %/frame at 50 px) than the cue's
#: minimum.
_CORE_PARAMS = params_from_dataclass(TrackerConfig, skip=EVALUATION_ONLY,
                                     defaults={'min_approach_speed': 0.0})
#: Frames whose published track ids are kept for the classifier's answer (its latency).
_SENT_FRAMES = 30


def config_from_params(params: Any) -> TrackerConfig:
    """The core configuration from the node's ``params``."""
    values = {p.attr: getattr(params, p.attr) for p in _CORE_PARAMS}
    values['scales'] = tuple(float(v) for v in values['scales'])
    values['focus_of_expansion'] = tuple(float(v) for v in values['focus_of_expansion'])
    return TrackerConfig(**values)


class TrackerNode(WorkzoneNode):
    """Kernel-based sign tracking (Lee et al.): detections + image -> tracks."""

    PARAMS = (
        *image_params(),
        Param('detections_topic', '/workzone/detections', 'input Detections payloads',
              read_only=True),
        Param('tracks_topic', '/workzone/tracks', 'output Tracks payloads', read_only=True),
        Param('signs_topic', '/workzone/signs', "the classifier's Signs: its answers confirm or "
              'reject tracks (needs_confirmation; empty: no confirmation)', read_only=True),
        Param('image_buffer', 10, 'images kept while waiting for their detections', min=1,
              max=100, read_only=True),
    ) + _CORE_PARAMS
    INPUT_TOPICS = ('image_topic', 'detections_topic')

    def __init__(self, **kwargs: Any) -> None:
        """Create the node (kwargs go to ``rclpy.node.Node``)."""
        super().__init__('tracker', **kwargs)
        self._tracker = MultiTracker(config_from_params(self.params))
        # each image with its detections (the same stamp), whichever comes first
        self._pairs = ExactStampPairs(self.params.image_buffer)
        self._last_ns: Optional[int] = None
        self._sent: collections.OrderedDict[int, list[int]] = collections.OrderedDict()
        self.counts = {'confirmed': 0, 'rejected': 0}
        self._tracks_pub = self.reliable_publisher(String, self.params.tracks_topic)
        self._image_sub = self.image_subscription(self.params.image_topic, self._on_image,
                                                  self.params.compressed)
        self._det_sub = self.reliable_subscription(String, self.params.detections_topic,
                                                   self._on_detections)
        self._signs_sub = (self.reliable_subscription(String, self.params.signs_topic,
                                                      self._on_signs)
                           if self.params.signs_topic else None)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Apply live parameter changes to the tracker (tracks are kept)."""
        try:
            self._tracker.reconfigure(config_from_params(self.params))
        except ValueError as exc:
            self.warn_throttled('reconfigure', f'tracker configuration rejected: {exc}')

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: tracks and the images / detections waiting by stamp restart."""
        self._tracker.reset()
        self._pairs.clear()
        self._sent.clear()
        self._last_ns = None

    # --- callbacks ------------------------------------------------------------------------

    def _on_image(self, msg: Any) -> None:
        ns = stamp_to_time(msg.header.stamp).to_ns()
        # converted on arrival: a malformed image is dropped with its reason now, not
        # buffered until it silently falls out of the ring
        frame = (compressed_to_numpy(msg) if isinstance(msg, CompressedImage)
                 else image_to_numpy(msg, desired_encoding='bgr8'))
        pair = self._pairs.add_image(ns, frame)
        if pair is not None:
            self._process(*pair)

    def _on_detections(self, msg: String) -> None:
        dets = string_to_payload(msg, Detections)
        pair, dropped = self._pairs.add_boxes(dets.header.stamp.to_ns(), dets)
        for reason in dropped:
            self.drop(self.params.detections_topic, reason)
        if pair is not None:
            self._process(*pair)

    def _on_signs(self, msg: String) -> None:
        signs = string_to_payload(msg, Signs)
        sent = self._sent.get(signs.header.stamp.to_ns(), ())
        confirmed, rejected = classifier_verdicts(sent, signs.signs)
        self._tracker.confirm(confirmed, rejected)
        self.counts['confirmed'] += len(confirmed)
        self.counts['rejected'] += len(rejected)

    # --- the step -------------------------------------------------------------------------

    def _process(self, frame: Any, dets: Detections) -> None:
        ns = dets.header.stamp.to_ns()
        if self._last_ns is not None and ns < self._last_ns:
            if self._last_ns - ns > 2_000_000_000:
                self.get_logger().info('time jumped back: tracks reset')
                self._tracker.reset()
            else:
                raise InputError('detections older than the last processed frame')
        tracks = self._tracker.step(frame, dets.detections, stamp=ns * 1e-9)
        self._last_ns = ns
        for reason in self._pairs.processed(ns):
            self.drop(self.params.detections_topic, reason)
        self._sent[ns] = [t.track_id for t in tracks]
        while len(self._sent) > _SENT_FRAMES:
            self._sent.popitem(last=False)
        self._tracks_pub.publish(payload_to_string(Tracks(header=dets.header, tracks=tracks)))


    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """Tracks the classifier confirmed as signs and rejected as background."""
        return [(f'tracks {k}', str(v)) for k, v in sorted(self.counts.items())]


NODE_CLASS = TrackerNode


def main(args: Optional[list[str]] = None) -> int:
    """Entry point ``tracker``."""
    return run_node(TrackerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
