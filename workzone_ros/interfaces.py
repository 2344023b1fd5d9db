"""JSON payloads of our std_msgs/String topics: typed, versioned, strictly validated.

Every payload carries ``schema`` (``"workzone_ros/<Name>/<version>"``) and a ``header`` equal
to the camera image it was computed from (DESIGN.md, "Topics").  Schemas are msgspec Structs:
unknown fields, wrong types and out-of-range values are rejected with one
:class:`PayloadError` whose message names the field.  No rclpy import: the simulator, the
evaluation tools and the nodes share these definitions.

Usage::

    text = encode(Detections(header=h, detections=[...]))
    dets = decode(text, Detections)          # raises PayloadError on anything malformed
    any_payload = decode_any(text)           # dispatch on the ``schema`` field
"""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

import msgspec

__all__ = [
    'PayloadError', 'Time', 'Header', 'Box', 'Roi', 'Rois', 'Detection', 'Detections',
    'Track', 'Tracks', 'Sign', 'Signs', 'Evidence', 'WorkzoneState', 'GtSign', 'GtObject',
    'GtSigns', 'GtLidarSign', 'GtLidar', 'GtEvent', 'Extrinsics', 'GtWorkzone', 'PAYLOADS',
    'encode', 'decode', 'decode_any', 'to_dict', 'schema_of',
]


class PayloadError(ValueError):
    """A payload that is not valid JSON, has the wrong schema, or fails validation."""


_STRUCT = dict(forbid_unknown_fields=True, omit_defaults=False)

NonNeg = Annotated[float, msgspec.Meta(ge=0.0)]
Unit = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
Count = Annotated[int, msgspec.Meta(ge=0)]


class Time(msgspec.Struct, frozen=True, **_STRUCT):
    """builtin_interfaces/Time (``sec`` is an int32 there: a payload stamp outside it is no
    ROS time and is rejected)."""

    sec: Annotated[int, msgspec.Meta(ge=-2 ** 31, le=2 ** 31 - 1)]
    nanosec: Annotated[int, msgspec.Meta(ge=0, lt=1_000_000_000)] = 0

    @classmethod
    def from_ns(cls, ns: int) -> 'Time':
        """Time from integer nanoseconds."""
        return cls(sec=int(ns) // 1_000_000_000, nanosec=int(ns) % 1_000_000_000)

    @classmethod
    def from_sec(cls, t: float) -> 'Time':
        """Time from float seconds."""
        return cls.from_ns(round(t * 1e9))

    def to_ns(self) -> int:
        """Integer nanoseconds."""
        return self.sec * 1_000_000_000 + self.nanosec

    def to_sec(self) -> float:
        """Float seconds."""
        return self.sec + self.nanosec * 1e-9


class Header(msgspec.Struct, frozen=True, **_STRUCT):
    """std_msgs/Header: the stamp and frame of the camera image a payload belongs to."""

    stamp: Time
    frame_id: str = ''


class Box(msgspec.Struct, frozen=True, **_STRUCT):
    """Axis-aligned image box in pixels: top-left corner and size."""

    x: float
    y: float
    w: NonNeg
    h: NonNeg

    @property
    def x2(self) -> float:
        """Right edge."""
        return self.x + self.w

    @property
    def y2(self) -> float:
        """Bottom edge."""
        return self.y + self.h

    @property
    def area(self) -> float:
        """Area in square pixels."""
        return self.w * self.h

    def iou(self, other: 'Box') -> float:
        """Intersection over union with ``other`` (0 when either is empty)."""
        iw = min(self.x2, other.x2) - max(self.x, other.x)
        ih = min(self.y2, other.y2) - max(self.y, other.y)
        if iw <= 0 or ih <= 0:
            return 0.0
        inter = iw * ih
        union = self.area + other.area - inter
        return inter / union if union > 0 else 0.0


# --- perception payloads ------------------------------------------------------------------

class Roi(msgspec.Struct, frozen=True, **_STRUCT):
    """One LiDAR sign candidate projected into the image."""

    candidate_id: int
    box: Box
    center: tuple[float, float]              # projected candidate centre (u, v), pixels
    range_m: NonNeg
    radius_m: NonNeg
    position: tuple[float, float, float]     # candidate centre in the camera frame, metres
    intensity: float = 0.0
    points: Count = 0


class Rois(msgspec.Struct, frozen=True, tag='workzone_ros/Rois/1', tag_field='schema',
           **_STRUCT):
    """Projector output: image-stamped ROIs with the LiDAR stamp they came from."""

    header: Header
    rois: list[Roi] = []
    lidar_stamp: Optional[Time] = None
    motion_compensated: bool = False


Color = Literal['orange', 'red', 'yellow', 'white', 'green']
Kind = Literal['warning', 'regulatory', 'general', 'unknown']


class Detection(msgspec.Struct, frozen=True, **_STRUCT):
    """One sign detection in the image.

    ``proposal``: a recall-first colour candidate (``core.proposals``) that no shape rule
    has checked; only the classifier can say whether it is a sign.  ``confidence`` is then the
    candidate's rank score.
    """

    box: Box
    confidence: Unit
    color: Color = 'orange'
    kind: Kind = 'unknown'
    sources: list[Literal['color', 'lidar']] = msgspec.field(default_factory=lambda: ['color'])
    roi_id: Optional[int] = None
    proposal: bool = False


class Detections(msgspec.Struct, frozen=True, tag='workzone_ros/Detections/1',
                 tag_field='schema', **_STRUCT):
    """color_detector output.

    ``channelizers``: orange blobs of the frame the detector rejected as drums or cones (the
    fusion's weaker in-zone evidence); None when the detector does not count them.
    """

    header: Header
    detections: list[Detection] = []
    channelizers: Optional[Count] = None


class Track(msgspec.Struct, frozen=True, **_STRUCT):
    """One tracked sign (Lee et al.).

    ``proposal``: the track follows recall-first colour proposals (``Detection.proposal``)
    that no shape rule checked; the classifier weighs it by their lower share of signs.
    """

    track_id: int
    box: Box
    source: Literal['detection', 'tracking']
    age: Count
    hits: Count
    similarity: Unit
    confidence: Unit = 0.0
    kind: Kind = 'unknown'
    color: Color = 'orange'
    proposal: bool = False


class Tracks(msgspec.Struct, frozen=True, tag='workzone_ros/Tracks/1', tag_field='schema',
             **_STRUCT):
    """tracker output."""

    header: Header
    tracks: list[Track] = []


class Sign(msgspec.Struct, frozen=True, **_STRUCT):
    """One classified sign.

    ``class_key`` is a key of the sign catalogue (``core/signs.py``), or ``unknown`` with
    ``category: "unknown"`` and a ``reason`` when the crop could not be classified (too
    small, outside the image): never a guess.  ``distance_m`` is the estimated distance from
    the camera (LiDAR range of the ROI the sign came from, else apparent size x the class's
    standard size / focal length) and ``distance_source`` says which.  A general sign
    (category ``general``: stop, yield, guide signs, mile markers, ...) comes from the
    general-sign recogniser and never changes the work-zone state; a mile marker carries
    its number in ``mile`` when it could be read.
    """

    box: Box
    class_key: str
    code: str
    category: Literal['workzone', 'general', 'unknown']
    score: Unit
    track_id: Optional[int] = None
    speed_limit_mph: Optional[int] = None
    speed_limit_confidence: Optional[Unit] = None
    probabilities: dict[str, float] = {}
    distance_m: Optional[NonNeg] = None
    distance_source: Literal['lidar', 'size', 'none'] = 'none'
    reason: str = ''
    mile: Optional[int] = None
    mile_confidence: Optional[Unit] = None


class Signs(msgspec.Struct, frozen=True, tag='workzone_ros/Signs/1', tag_field='schema',
            **_STRUCT):
    """classifier output."""

    header: Header
    signs: list[Sign] = []


class Evidence(msgspec.Struct, frozen=True, **_STRUCT):
    """A sign (or channelizing devices) that contributed to the state, with its vote.

    ``field`` names the state field it supports (``phase``, ``speed_limit_mph``,
    ``lane_shift``, ``lanes_closed``); ``distance_m`` the estimated distance to the sign
    when it was last seen; ``ahead_m`` the distance still to travel to it now (negative
    once passed; None for evidence that is not a sign).
    """

    class_key: str
    weight: float
    stamp: Time
    track_id: Optional[int] = None
    field: str = 'phase'
    distance_m: Optional[float] = None
    ahead_m: Optional[float] = None


class WorkzoneState(msgspec.Struct, frozen=True, tag='workzone_ros/WorkzoneState/1',
                    tag_field='schema', **_STRUCT):
    """fusion output for the planner: what is known, and explicitly what is not."""

    header: Header
    active: bool
    likelihood: Unit
    phase: Literal['unknown', 'none', 'approaching', 'inside', 'leaving']
    speed_limit_mph: Optional[int] = None
    lane_shift: Literal['none', 'left', 'right', 'unknown'] = 'none'
    lanes_closed: list[Literal['left', 'right', 'unknown']] = []
    unknowns: list[str] = []        # e.g. "speed_limit_value", "lane_shift_direction"
    stale_inputs: list[str] = []    # input topics whose last message is too old
    evidence: list[Evidence] = []
    evidence_age_s: Optional[NonNeg] = None     # age of the newest evidence (None: none yet)
    distance_since_evidence_m: Optional[NonNeg] = None  # travelled since the newest evidence
    reason: str = ''                # why the phase is what it is (the last transition's cause)


# --- ground truth (synthetic bags only) ---------------------------------------------------

class GtSign(msgspec.Struct, frozen=True, **_STRUCT):
    """A sign visible in one camera frame."""

    sign_id: int
    class_key: str
    code: str
    category: Literal['workzone', 'general']
    box: Box                    # image bbox of the visible part of the face
    distance_m: NonNeg
    visible_fraction: Unit


class GtObject(msgspec.Struct, frozen=True, **_STRUCT):
    """A hard negative (drum, cone, orange vehicle, ...) visible in one camera frame."""

    object_id: int
    kind: str
    box: Box
    distance_m: NonNeg


class GtSigns(msgspec.Struct, frozen=True, tag='workzone_ros/GtSigns/1', tag_field='schema',
              **_STRUCT):
    """``/groundtruth/signs``: per camera frame, stamped like the image."""

    header: Header
    signs: list[GtSign] = []
    distractors: list[GtObject] = []
    weather: str = ''


class GtLidarSign(msgspec.Struct, frozen=True, **_STRUCT):
    """The points of one LiDAR scan that hit one sign face."""

    sign_id: int
    class_key: str
    center: tuple[float, float, float]      # face centre in the lidar frame at scan time
    indices: list[int]                      # indices into the scan's points


class GtLidar(msgspec.Struct, frozen=True, tag='workzone_ros/GtLidar/1', tag_field='schema',
              **_STRUCT):
    """``/groundtruth/lidar``: per scan, stamped like the PointCloud2."""

    header: Header
    signs: list[GtLidarSign] = []


class GtEvent(msgspec.Struct, frozen=True, **_STRUCT):
    """A driving-condition change along the route."""

    kind: Literal['zone_approaching', 'zone_begin', 'zone_end', 'speed_limit', 'lane_shift',
                  'lane_closed']
    t: float                                 # bag time (s) when the ego passes the sign
    x_m: float                               # distance along the route (m)
    value: Union[int, float, str, None] = None   # 45, 'left', 'right', ...
    sign_id: Optional[int] = None


class Extrinsics(msgspec.Struct, frozen=True, **_STRUCT):
    """LiDAR -> camera transform: X_cam = R @ X_lidar + t (R from roll/pitch/yaw, or matrix)."""

    translation: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    matrix: Optional[list[list[float]]] = None


class GtWorkzone(msgspec.Struct, frozen=True, tag='workzone_ros/GtWorkzone/1',
                 tag_field='schema', **_STRUCT):
    """``/groundtruth/workzone``: zone bounds and every driving-condition change."""

    header: Header
    scenario: str
    seed: int
    begin_t: Optional[float] = None
    begin_x_m: Optional[float] = None
    end_t: Optional[float] = None
    end_x_m: Optional[float] = None
    events: list[GtEvent] = []
    extrinsics: Optional[Extrinsics] = None
    weather: str = ''


PAYLOADS: tuple[type, ...] = (Rois, Detections, Tracks, Signs, WorkzoneState, GtSigns, GtLidar,
                              GtWorkzone)
_BY_SCHEMA = {p.__struct_config__.tag: p for p in PAYLOADS}
_ENCODER = msgspec.json.Encoder()
_ANY = msgspec.json.Decoder(Union[PAYLOADS])  # type: ignore[valid-type]
_DECODERS = {p: msgspec.json.Decoder(p) for p in PAYLOADS}


def schema_of(cls_or_payload) -> str:
    """The ``schema`` string of a payload class or instance."""
    return cls_or_payload.__struct_config__.tag


def encode(payload) -> str:
    """Serialise a payload to compact JSON text (``schema`` first)."""
    return _ENCODER.encode(payload).decode()


def _explain(text, exc: Exception, expected: str) -> PayloadError:
    if isinstance(exc, msgspec.DecodeError) and 'Invalid value' in str(exc) \
            and '$.schema' in str(exc):
        try:
            got = msgspec.json.decode(text).get('schema')
        except Exception:  # noqa: BLE001 - the original error is the useful one
            got = None
        if isinstance(got, str):
            name = got.rsplit('/', 1)[0]
            known = [s for s in _BY_SCHEMA if s.rsplit('/', 1)[0] == name]
            if known and (expected == 'a workzone_ros' or known[0] == expected):
                return PayloadError(f'payload schema {got!r} is another version; this build '
                                    f'reads {known[0]!r}')
            return PayloadError(f'payload schema {got!r} is not {expected}')
    return PayloadError(f'invalid {expected} payload: {exc}')


def decode(text: Union[str, bytes], cls: type):
    """Parse and validate ``text`` as payload ``cls``.

    Raises:
        PayloadError: not JSON, wrong schema or version, missing/unknown fields, bad values.
    """
    if cls not in _DECODERS:
        raise TypeError(f'{cls!r} is not a workzone_ros payload')
    try:
        return _DECODERS[cls].decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise _explain(text, exc, schema_of(cls)) from None


def decode_any(text: Union[str, bytes]):
    """Parse any known payload, dispatching on its ``schema`` field.

    Raises:
        PayloadError: as :func:`decode`, or an unknown schema.
    """
    try:
        return _ANY.decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise _explain(text, exc, 'a workzone_ros') from None


def to_dict(payload) -> dict:
    """The payload as plain Python builtins (for printing and reports)."""
    return msgspec.to_builtins(payload)
