"""The classifier node's per-frame rules (core.recognition), with a stand-in model."""
import numpy as np

from workzone_ros.core.classifier import Prediction
from workzone_ros.core.recognition import RecognitionConfig, SignRecognizer, unclassifiable
from workzone_ros.interfaces import Box, Roi, Track


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


def test_unclassifiable_reasons():
    assert unclassifiable(Box(x=0, y=0, w=20, h=20), 640, 480, 12, 0.5) == ''
    assert 'min_size' in unclassifiable(Box(x=0, y=0, w=20, h=8), 640, 480, 12, 0.5)
    assert 'only 6% of the box' in unclassifiable(Box(x=-15, y=-15, w=20, h=20), 640, 480, 12,
                                                  0.5)
