"""Payload schemas: round trips, strict validation, versioning."""
import pytest

from workzone_ros import interfaces as I


def _header():
    return I.Header(stamp=I.Time(sec=12, nanosec=345), frame_id='camera')


def _examples():
    box = I.Box(x=10, y=20, w=30, h=40)
    t = I.Time(sec=1, nanosec=2)
    return [
        I.Rois(header=_header(), lidar_stamp=t, rois=[I.Roi(
            candidate_id=3, box=box, center=(25.0, 40.0), range_m=42.0, radius_m=0.8,
            position=(1.0, 0.5, 42.0), intensity=200.0, points=17)]),
        I.Detections(header=_header(), detections=[I.Detection(
            box=box, confidence=0.9, kind='regulatory', sources=['color', 'lidar'])]),
        I.Tracks(header=_header(), tracks=[I.Track(
            track_id=1, box=box, source='tracking', age=4, hits=3, similarity=0.8)]),
        I.Signs(header=_header(), signs=[I.Sign(
            box=box, class_key='road_work_ahead', code='W20-1', category='workzone',
            score=0.7, track_id=1, probabilities={'road_work_ahead': 0.7})]),
        I.WorkzoneState(header=_header(), active=True, likelihood=0.6, phase='inside',
                        speed_limit_mph=45, lane_shift='left', lanes_closed=['right'],
                        unknowns=['lane_shift_direction'],
                        evidence=[I.Evidence(class_key='work_zone_begin', weight=0.9, stamp=t)]),
        I.GtSigns(header=_header(), signs=[I.GtSign(
            sign_id=5, class_key='stop', code='R1-1', category='general', box=box,
            distance_m=30.0, visible_fraction=1.0)],
            distractors=[I.GtObject(object_id=9, kind='drum', box=box, distance_m=12.0)]),
        I.GtLidar(header=_header(), signs=[I.GtLidarSign(
            sign_id=5, class_key='stop', center=(30.0, -5.0, 2.5), indices=[1, 2, 3])]),
        I.GtWorkzone(header=_header(), scenario='demo', seed=0, begin_t=10.0, end_t=30.0,
                     events=[I.GtEvent(kind='speed_limit', t=12.0, x_m=300.0, value=45)],
                     extrinsics=I.Extrinsics(translation=(0.0, -0.5, -0.4))),
    ]


@pytest.mark.parametrize('payload', _examples(), ids=lambda p: type(p).__name__)
def test_round_trip_and_schema_tag(payload):
    text = I.encode(payload)
    assert text.startswith('{"schema":"workzone_ros/%s/1"' % type(payload).__name__)
    assert I.decode(text, type(payload)) == payload
    assert I.decode_any(text) == payload


def test_every_payload_is_covered():
    assert {type(p) for p in _examples()} == set(I.PAYLOADS)


@pytest.mark.parametrize('mutate, fragment', [
    (lambda s: s[:-3], 'truncated'),
    (lambda s: s.replace('"confidence":0.9', '"confidence":1.9'), 'confidence'),
    (lambda s: s.replace('"kind"', '"kindx"'), 'unknown field'),
    (lambda s: s.replace('"w":30', '"w":-3'), '$.detections[0].box.w'),
    (lambda s: s.replace('"confidence":0.9', '"confidence":"high"'), 'confidence'),
    (lambda s: 'not json', 'invalid'),
])
def test_malformed_detections_are_rejected_with_a_reason(mutate, fragment):
    text = I.encode(_examples()[1])
    with pytest.raises(I.PayloadError) as err:
        I.decode(mutate(text), I.Detections)
    assert fragment in str(err.value)
    assert '\n' not in str(err.value)


def test_other_version_and_other_schema_are_named():
    text = I.encode(_examples()[1])
    with pytest.raises(I.PayloadError, match='another version'):
        I.decode(text.replace('Detections/1', 'Detections/7'), I.Detections)
    with pytest.raises(I.PayloadError, match='is not workzone_ros/Detections/1'):
        I.decode(I.encode(_examples()[2]), I.Detections)


def test_box_iou():
    a = I.Box(x=0, y=0, w=10, h=10)
    assert a.iou(a) == 1.0
    assert a.iou(I.Box(x=5, y=0, w=10, h=10)) == pytest.approx(50 / 150)
    assert a.iou(I.Box(x=20, y=20, w=1, h=1)) == 0.0


def test_time_conversions():
    t = I.Time.from_sec(3.25)
    assert (t.sec, t.nanosec) == (3, 250_000_000)
    assert I.Time.from_ns(t.to_ns()) == t
