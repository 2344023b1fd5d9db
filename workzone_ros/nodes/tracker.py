"""``tracker`` node: camera image + ``/workzone/detections`` -> ``/workzone/tracks`` (seed 001).

Thin wrapper around :class:`workzone_ros.core.track.MultiTracker`.  Images are kept in a
short ring buffer keyed by their stamp; a ``Detections`` payload is processed with the image
of exactly the same stamp (the detector stamps its output with the image it ran on).  When the
detections arrive first they wait (a few frames) for their image.  Frames are processed in
stamp order; anything older than the last processed frame is dropped (latest-frame-wins), and
a stamp that jumps backwards (a looping bag) resets the tracks.
"""
from __future__ import annotations

import collections
from typing import Any, Optional

from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from workzone_ros.core.track import (
    ASSOCIATIONS,
    METHODS,
    MODES,
    OUR_SCALES,
    MultiTracker,
    TrackerConfig,
)
from workzone_ros.interfaces import Detections, Tracks
from workzone_ros.nodes.base import InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import (
    compressed_to_numpy,
    image_to_numpy,
    payload_to_string,
    stamp_to_time,
    string_to_payload,
)

__all__ = ['TrackerNode', 'NODE_CLASS', 'main']

_D = TrackerConfig()

#: Parameters that map one to one onto TrackerConfig fields.
_CORE_PARAMS = (
    Param('mode', _D.mode, 'detection_only (seed 001 baseline) or detection_and_tracking',
          choices=MODES),
    Param('method', _D.method, 'meanshift (seed 001) or camshift (OpenCV peer)',
          choices=METHODS),
    Param('hue_bins', _D.hue_bins, 'hue bins nh of the target histogram', min=2, max=180),
    Param('sat_bins', _D.sat_bins, 'saturation bins ns of the target histogram', min=2,
          max=256),
    Param('scales', list(OUR_SCALES), 'candidate kernel sizes relative to the previous box '
          '(seed 001: 1.0 1.02 1.05 1.07 1.10)'),
    Param('max_iterations', _D.max_iterations, 'mean-shift iterations per candidate', min=1,
          max=100),
    Param('shift_threshold_px', _D.shift_threshold_px, 'stop when the centre moves less',
          min=0.0, max=10.0),
    Param('max_samples', _D.max_samples, 'pixels sampled inside a box', min=16,
          max=100000),
    Param('search_margin', _D.search_margin, 'search window beyond the largest candidate '
          '(half-boxes)', min=0.0, max=5.0),
    Param('use_velocity', _D.use_velocity, 'start from the constant-velocity prediction'),
    Param('min_similarity', _D.min_similarity, 'Bhattacharyya coefficient below which a '
          'track is lost', min=0.0, max=1.0),
    Param('max_lost_frames', _D.max_lost_frames, 'lost frames before a track ends', min=0,
          max=100),
    Param('max_coast_frames', _D.max_coast_frames, 'frames without a detection before a '
          'track ends', min=0, max=10000),
    Param('min_hits_to_coast', _D.min_hits_to_coast, 'detections before a track may run on '
          'its own', min=1, max=100),
    Param('min_hits_to_fuse', _D.min_hits_to_fuse, 'detections before the tracked box may '
          'outvote a detection (fuse)', min=1, max=100),
    Param('max_background_similarity', _D.max_background_similarity, 'a target this '
          'similar to its surroundings never runs on its own', min=0.0, max=1.0),
    Param('iou_gate', _D.iou_gate, 'IoU at which a detection agrees with a track', min=0.0,
          max=1.0),
    Param('agree_iou', _D.agree_iou, 'IoU with the tracked box at which a detection '
          'corrects the track', min=0.0, max=1.0),
    Param('similarity_gate', _D.similarity_gate, 'histogram similarity at which an '
          'overlapping detection agrees', min=0.0, max=1.0),
    Param('model_update', _D.model_update, 'weight of a correcting detection in the model',
          min=0.0, max=1.0),
    Param('max_box_fraction', _D.max_box_fraction, 'end when the box is wider/taller than '
          'this image fraction', min=0.0, max=1.0),
    Param('min_inside_fraction', _D.min_inside_fraction, 'end when less of the box than '
          'this is inside the image', min=0.0, max=1.0),
    Param('min_box_px', _D.min_box_px, 'ignore smaller detections', min=1, max=1000),
    Param('anchor_on_color', _D.anchor_on_color, 'track the coloured part and keep the box '
          'geometry (regulatory two-colour guard)'),
    Param('duplicate_iou', _D.duplicate_iou, 'overlap at which the weaker of two tracks '
          'ends', min=0.0, max=1.0),
    Param('duplicate_containment', _D.duplicate_containment, "share of a track's anchor "
          "inside another track's box at which the weaker ends (1 = off)", min=0.0, max=1.0),
    Param('duplicate_area_ratio', _D.duplicate_area_ratio, 'containment duplicates only up '
          'to this box area ratio', min=1.0, max=1000.0),
    Param('background_weighting', _D.background_weighting, 'corrected background-weighted '
          'histogram in the mean-shift weights'),
    Param('surround_weight', _D.surround_weight, 'penalty of sign colour around a '
          'candidate in the scale choice (0 = seed)', min=0.0, max=5.0),
    Param('surround_size', _D.surround_size, 'outer size of that band', min=1.0, max=3.0),
    Param('association', _D.association, 'fuse (ours) or overwrite (seed 001): how an '
          'associated detection updates a confident track', choices=ASSOCIATIONS),
    Param('fuse_temperature', _D.fuse_temperature, 'score scale of the fusion weights',
          min=1e-3, max=1000.0),
    Param('size_sigma', _D.size_sigma, 'log-size tolerance of the size-consistency factor',
          min=1e-3, max=10.0),
    Param('size_history', _D.size_history, 'fuse: detected sizes whose 1/size trend '
          'predicts the size the detection is compared with (0 = last size)', min=0,
          max=100),
    Param('fuse_iou', _D.fuse_iou, 'anchor IoU at which tracked and detected boxes are '
          'averaged rather than chosen', min=0.0, max=1.0),
    Param('fuse_bias', _D.fuse_bias, "added to the detection's score in the fusion",
          min=-1.0, max=1.0),
    Param('fuse_min_px', _D.fuse_min_px, 'smaller tracks are overwritten, not fused',
          min=0.0, max=1000.0),
    Param('prefer_detection', _D.prefer_detection, 'fuse: an agreeing, complete detection '
          'gives the box (false: blend)'),
    Param('max_coast_background_similarity', _D.max_coast_background_similarity,
          'a target this similar to its surroundings is never published on its own '
          '(1 = off)', min=0.0, max=1.0),
    Param('max_coast_white_fraction', _D.max_coast_white_fraction, 'a coloured shape this '
          'white (drum, cone bands) is never published on its own (1 = off)', min=0.0,
          max=1.0),
    Param('white_bottom_share', _D.white_bottom_share, 'a shape with at least this share '
          'of its white below its colour (regulatory white bottom) is exempt from the white '
          'gate (> 1 = off)', min=0.0, max=2.0),
    Param('truncated_aspect', _D.truncated_aspect, 'two-colour guard: a detection is '
          "truncated only when its height/width is below this times the track's (0 = off)",
          min=0.0, max=1.0),
    Param('anchor_kind_ratio', _D.anchor_kind_ratio, 'two-colour guard: a detection is '
          "extended only when its coloured anchor's height/width is at most this times the "
          "track's (0 = off)", min=0.0, max=10.0),
    Param('min_saturation_contrast', _D.min_saturation_contrast, 'sign-likeness: a target '
          'less saturated than this above its surroundings is never published on its own '
          '(-1 = off)', min=-1.0, max=1.0),
    Param('saturation_reference', _D.saturation_reference, "sign-likeness: percentile of "
          "the surroundings' saturation the face's upper decile is compared with (90 = the "
          'previous rule)', min=0.0, max=100.0),
    Param('min_chroma_contrast', _D.min_chroma_contrast, 'sign-likeness: a target whose '
          'chroma (S*V) upper decile is less than this times that of its surroundings is '
          'never published on its own (0 = off)', min=0.0, max=100.0),
    Param('chroma_reference', _D.chroma_reference, "sign-likeness: percentile of the "
          "surroundings' chroma the face's upper decile is compared with (90 = the previous "
          'rule)', min=0.0, max=100.0),
    Param('min_hits_after_loss', _D.min_hits_after_loss, 'a track that lost its target '
          'since its last detection is published on its own again only with this many '
          'detections (1 = always)', min=0, max=1000),
    Param('ring_margin', _D.ring_margin, 'drift guard: the ring must also exceed the ring '
          'at the last detection by this (< 0 = off)', min=-1.0, max=1.0),
    Param('ring_margin_min_hits', _D.ring_margin_min_hits, 'ring_margin applies to tracks '
          'with this many detections', min=0, max=1000),
    Param('max_ring_similarity', _D.max_ring_similarity, 'drift guard: surroundings this '
          'similar to the target lose a coasting track (1 = off)', min=0.0, max=1.0),
    Param('max_growth_excess', _D.max_growth_excess, 'drift guard: growth beyond the '
          "detections' perspective trend that ends a coasting track (0 = off)", min=0.0,
          max=10.0),
    Param('growth_guard_needs_trend', _D.growth_guard_needs_trend, 'the growth guard acts '
          'only once two detections measured the trend'),
    # Off unless configured (config/workzone.yaml turns it on): the node's own test draws a
    # sign approached far slower (2 %/frame at 50 px) than the cue's minimum.
    Param('min_approach_speed', 0.0, 'motion cue: a track that the camera approaches slower '
          'than this (m/s, from the fall of its inverse size or offset from the focus of '
          'expansion) is not published on its own (a vehicle ahead; 0 = off; core default '
          f'{_D.min_approach_speed})', min=0.0, max=100.0),
    Param('sign_size_m', _D.sign_size_m, 'motion cue: nominal sign face size (m)', min=0.05,
          max=10.0),
    Param('camera_hfov_deg', _D.camera_hfov_deg, "motion cue: the camera's horizontal field "
          'of view (deg) for its focal length', min=1.0, max=179.0),
    Param('frame_rate', _D.frame_rate, 'motion cue: frames per second until the image stamps '
          'tell', min=0.1, max=1000.0),
    Param('motion_window', _D.motion_window, 'motion cue: frames of track history used',
          min=2, max=1000),
    Param('motion_min_frames', _D.motion_min_frames, 'motion cue: judged only on a history '
          'spanning at least this many frames', min=2, max=1000),
    Param('focus_of_expansion', list(_D.focus_of_expansion), 'motion cue: focus of '
          'expansion as image fractions [x, y] (straight ahead)'),
    Param('radial_min_offset', _D.radial_min_offset, 'motion cue: the offset estimate '
          'counts when the offset from the focus is at least this many box sizes',
          min=0.0, max=100.0),
    Param('approach_from_detections', _D.approach_from_detections, 'motion cue: also the '
          "trend of the track's detected sizes (free of the tracker's own scale lag)"),
    Param('perspective_max_background', _D.perspective_max_background, 'perspective scale: '
          'only for targets whose background similarity is at most this (1 = always)',
          min=0.0, max=1.0),
    Param('perspective_scale', _D.perspective_scale, 'candidates also around the size the '
          "Theil-Sen trend of the track's detected sizes predicts (static-sign perspective)"),
    Param('perspective_min', _D.perspective_min, 'perspective scale: smallest predicted / '
          'current size used', min=0.1, max=1.0),
    Param('perspective_max', _D.perspective_max, 'perspective scale: largest predicted / '
          'current size used', min=1.0, max=10.0),
    Param('perspective_min_detections', _D.perspective_min_detections, 'perspective scale: '
          'detections the trend needs (and it extrapolates no further than they span)',
          min=3, max=1000),
)


def config_from_params(params: Any) -> TrackerConfig:
    """The core configuration from the node's ``params``."""
    values = {p.attr: getattr(params, p.attr) for p in _CORE_PARAMS}
    values['scales'] = tuple(float(v) for v in values['scales'])
    values['focus_of_expansion'] = tuple(float(v) for v in values['focus_of_expansion'])
    return TrackerConfig(**values)


class TrackerNode(WorkzoneNode):
    """Kernel-based sign tracking (seed 001): detections + image -> tracks."""

    PARAMS = (
        Param('image_topic', '/camera/image_raw', 'input camera image (bgr8/rgb8/...)'),
        Param('compressed', False, 'only <image_topic>/compressed (false: raw, or compressed '
              'while no raw image arrives)',
              read_only=True),
        Param('detections_topic', '/workzone/detections', 'input Detections payloads'),
        Param('tracks_topic', '/workzone/tracks', 'output Tracks payloads'),
        Param('image_buffer', 10, 'images kept while waiting for their detections', min=1,
              max=100),
    ) + _CORE_PARAMS
    INPUT_TOPICS = ('image_topic', 'detections_topic')

    def __init__(self, **kwargs: Any) -> None:
        """Create the node (kwargs go to ``rclpy.node.Node``)."""
        super().__init__('tracker', **kwargs)
        self._tracker = MultiTracker(config_from_params(self.params))
        n = self.params.image_buffer
        self._images: collections.OrderedDict[int, Any] = collections.OrderedDict()
        self._pending: collections.OrderedDict[int, Detections] = collections.OrderedDict()
        self._max = n
        self._last_ns: Optional[int] = None
        self._tracks_pub = self.reliable_publisher(String, self.params.tracks_topic)
        self._image_sub = self.image_subscription(self.params.image_topic, self._on_image,
                                                  self.params.compressed)
        self._det_sub = self.reliable_subscription(String, self.params.detections_topic,
                                                   self._on_detections)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Apply live parameter changes to the tracker (tracks are kept)."""
        try:
            self._tracker.reconfigure(config_from_params(self.params))
        except ValueError as exc:
            self.warn_throttled('reconfigure', f'tracker configuration rejected: {exc}')

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: tracks and the images / detections waiting by stamp restart."""
        self._tracker.reset()
        self._images.clear()
        self._pending.clear()
        self._last_ns = None

    # --- callbacks ------------------------------------------------------------------------

    def _on_image(self, msg: Any) -> None:
        ns = stamp_to_time(msg.header.stamp).to_ns()
        # converted on arrival: a malformed image is dropped with its reason now, not
        # buffered until it silently falls out of the ring
        frame = (compressed_to_numpy(msg) if isinstance(msg, CompressedImage)
                 else image_to_numpy(msg, desired_encoding='bgr8'))
        if ns in self._pending:
            self._process(frame, self._pending.pop(ns))
            return
        self._images[ns] = frame
        while len(self._images) > self._max:
            self._images.popitem(last=False)

    def _on_detections(self, msg: String) -> None:
        dets = string_to_payload(msg, Detections)
        ns = dets.header.stamp.to_ns()
        image = self._images.pop(ns, None)
        if image is not None:
            self._process(image, dets)
            return
        self._pending[ns] = dets              # its image has not arrived yet
        while len(self._pending) > self._max:
            self._pending.popitem(last=False)
            self.drop(self.params.detections_topic,
                      'no image with the stamp of these detections arrived')

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
        for old in [k for k in self._images if k <= ns]:
            del self._images[old]
        for old in [k for k in self._pending if k <= ns]:
            del self._pending[old]
        self._tracks_pub.publish(payload_to_string(Tracks(header=dets.header, tracks=tracks)))


NODE_CLASS = TrackerNode


def main(args: Optional[list[str]] = None) -> int:
    """Entry point ``tracker``."""
    return run_node(TrackerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
