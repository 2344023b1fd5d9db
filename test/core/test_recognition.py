"""The classifier node's per-frame rules (core.recognition), with a stand-in model."""
import numpy as np

from workzone_ros.core.classifier import Prediction
from workzone_ros.core.recognition import (
    RecognitionConfig,
    SignRecognizer,
    unclassifiable,
    weigh_prior,
)
from workzone_ros.interfaces import Box, Detection, Roi, Track


class _Model:
    """Answers the classes it is given, in order, for the boxes it gets."""

    def __init__(self, answers):
        self.answers = answers
        self.calls = []

    def classify_boxes(self, frame, boxes, margin=None):
        self.calls.append(list(boxes))
        return [None if a is None else Prediction(a, 0.9, {a: 0.9, 'background': 0.1})
                for a in self.answers[:len(boxes)]]


def _track(tid, x, y, w, h):
    return Track(track_id=tid, box=Box(x=x, y=y, w=w, h=h), source='detection', age=1,
                 hits=1, similarity=1.0)


def test_small_and_outside_boxes_are_unknown_background_is_rejected_signs_get_a_distance():
    frame = np.zeros((480, 640, 3), np.uint8)
    model = _Model(['road_work_ahead', 'background'])
    rec = SignRecognizer(model, RecognitionConfig(read_speed=False))
    items = [_track(1, 100, 100, 40, 40), _track(2, 300, 100, 30, 30),
             _track(3, 10, 10, 5, 5), _track(4, 630, 100, 40, 40)]
    roi = Roi(candidate_id=5, box=Box(x=90, y=90, w=60, h=60), center=(120.0, 120.0),
              range_m=33.0, radius_m=0.8, position=(0.0, 0.0, 33.0))
    signs, rejected = rec.recognize(frame, items, 554.0, [roi])
    assert len(model.calls[0]) == 2                       # one batch, only classifiable boxes
    by_id = {s.track_id: s for s in signs}
    assert by_id[1].class_key == 'road_work_ahead' and by_id[1].distance_m == 33.0
    assert by_id[1].distance_source == 'lidar'
    assert 2 not in by_id and rejected == [items[1].box]
    assert by_id[3].category == 'unknown' and 'min_size' in by_id[3].reason
    assert by_id[4].category == 'unknown' and 'inside the image' in by_id[4].reason


def test_a_box_only_the_proposals_found_needs_stronger_evidence_to_be_a_sign():
    """The same answer (road_work_ahead 0.9 against background 0.1) is a sign on a rule-
    checked detection or track, and background on a proposal at the default prior (e^2.9
    ~ 18: background 1.8 against 0.9); a prior of 0 weighs both alike."""
    frame = np.zeros((480, 640, 3), np.uint8)
    box = Box(x=100, y=100, w=40, h=40)
    items = [Detection(box=box, confidence=0.9), Detection(box=box, confidence=0.4,
                                                            proposal=True),
             Track(track_id=7, box=box, source='detection', age=3, hits=3, similarity=0.0,
                   proposal=True)]
    rec = SignRecognizer(_Model(['road_work_ahead'] * 3), RecognitionConfig(read_speed=False))
    signs, rejected = rec.recognize(frame, items, 554.0)
    assert [s.class_key for s in signs] == ['road_work_ahead'] and len(rejected) == 2
    rec.config = RecognitionConfig(read_speed=False, proposal_prior=0.0)
    signs, rejected = rec.recognize(frame, items, 554.0)
    assert len(signs) == 3 and not rejected


def test_the_prior_is_bayes_rule_on_background():
    pred = Prediction('road_work_ahead', 0.6, {'road_work_ahead': 0.6, 'background': 0.1,
                                               'lane_closed': 0.3})
    out = weigh_prior(pred, np.log(2.0))      # background's odds doubled: 0.2 / 1.1
    assert out.class_key == 'road_work_ahead'
    assert abs(out.probabilities['background'] - 0.2 / 1.1) < 1e-9
    assert abs(sum(out.probabilities.values()) - 1.0) < 1e-9
    assert weigh_prior(pred, np.log(10.0)).class_key == 'background'
    assert weigh_prior(pred, 0.0) is pred
    no_bg = Prediction('stop', 0.7, {'stop': 0.7, 'yield': 0.3})
    assert weigh_prior(no_bg, 5.0) is no_bg


def test_unclassifiable_reasons():
    assert unclassifiable(Box(x=0, y=0, w=20, h=20), 640, 480, 12, 0.5) == ''
    assert 'min_size' in unclassifiable(Box(x=0, y=0, w=20, h=8), 640, 480, 12, 0.5)
    assert 'only 6% of the box' in unclassifiable(Box(x=-15, y=-15, w=20, h=20), 640, 480, 12,
                                                  0.5)


class _Found:
    """A general sign as the general recogniser reports it (x, y, w, h box)."""

    def __init__(self, key, box, score=0.8, mile=None, mile_confidence=None):
        self.class_key, self.box, self.score = key, box, score
        self.mile, self.mile_confidence = mile, mile_confidence


def test_general_signs_are_category_general_with_a_distance_and_their_mile():
    from workzone_ros.core.recognition import general_signs
    found = [_Found('stop', (100, 100, 40, 40)),
             _Found('mile_marker', (500, 200, 10, 25), mile=42, mile_confidence=0.9),
             _Found('no_such_sign', (10, 10, 30, 30))]
    out = general_signs(found, focal_px=1000.0)
    assert [s.class_key for s in out] == ['stop', 'mile_marker']
    assert all(s.category == 'general' for s in out)
    assert out[0].code == 'R1-1' and out[0].distance_source == 'size'
    assert abs(out[0].distance_m - 1000.0 * 0.9 / 40) < 0.05
    assert out[1].mile == 42 and out[1].mile_confidence == 0.9
    assert out[0].mile is None


def test_a_general_sign_where_the_work_zone_chain_published_one_is_left_out():
    from workzone_ros.core.recognition import general_signs
    from workzone_ros.interfaces import Sign
    published = [Sign(box=Box(x=100, y=100, w=40, h=40), class_key='road_work_ahead',
                      code='W20-1', category='workzone', score=0.9)]
    found = [_Found('warning_diamond', (102, 101, 38, 40)),
             _Found('stop', (300, 100, 40, 40))]
    out = general_signs(found, focal_px=1000.0, published=published)
    assert [s.class_key for s in out] == ['stop']
