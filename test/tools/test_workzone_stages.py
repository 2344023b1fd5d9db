"""Per-stage accuracy of ``evaluate workzone --signs pipeline`` (``workzone_stages``) on
hand-made frames, whose figures are worked out by hand in the comments, and the stages'
boxes carried from the pipeline (and its cache) to the JSON figures."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from workzone_ros.interfaces import Box, Detection, Sign, Track
from workzone_ros.tools import workzone_stages as ws

# Frame 1: signs A (road_work_ahead) and B (lane_shift_left) legible; C illegible (other).
FRAME_1 = {
    'gt_wz': [('road_work_ahead', (0, 0, 10, 10)), ('lane_shift_left', (100, 0, 10, 10))],
    'gt_other': [(200, 0, 10, 10)],
    'dets': [(0, 0, 10, 10),          # on A, IoU 1: matched
             (1, 0, 10, 10),          # on A again (IoU 0.818): unmatched, not false
             (200, 0, 10, 10),        # on the illegible sign C: ignored
             (300, 300, 10, 10)],     # on no sign: false
    'tracks': [((0, 0, 10, 10), 'road_work_ahead'),       # A, right class
               ((100, 0, 10, 10), 'lane_shift_right'),    # B, wrong class
               ((400, 400, 10, 10), 'road_work_ahead'),   # on no sign, given a work-zone class
               ((500, 500, 10, 10), 'background')],       # on no sign, not published
}
# Frame 2: D (road_work_ahead) covered by a track not classified; E (end_road_work) missed.
FRAME_2 = {
    'gt_wz': [('road_work_ahead', (0, 0, 20, 20)), ('end_road_work', (50, 50, 10, 10))],
    'gt_other': [],
    'dets': [],
    'tracks': [((0, 0, 20, 20), 'unknown')],
}


def _frames(*stages):
    return [SimpleNamespace(stages=s) for s in stages]


def test_match_is_one_to_one_best_first_at_iou_half_inclusive():
    gts = [(0, 0, 10, 20)]
    assert ws.match([(0, 0, 10, 10)], gts) == [(0, 0)]             # IoU exactly 0.5
    assert ws.match([(0, 0, 10, 9)], gts) == []                    # IoU 0.45
    assert ws.match([(0, 1, 10, 19), (0, 0, 10, 20)], gts) == [(1, 0)]   # best IoU wins


def test_detection_figures_by_hand():
    d = ws.stage_figures(_frames(FRAME_1, FRAME_2))['detection']
    # 4 detections, 1 ignored (on C), 1 matched (A); 4 legible signs (A, B, D, E)
    assert (d['detections'], d['ignored'], d['matched'], d['signs']) == (4, 1, 1, 4)
    assert d['precision'] == round(1 / 3, 4) and d['recall'] == 0.25
    assert d['false'] == 1 and d['false_per_frame'] == 0.5            # 1 over 2 frames


def test_tracking_figures_by_hand():
    t = ws.stage_figures(_frames(FRAME_1, FRAME_2))['tracking']
    # A, B and D covered, E not; the boxes at (400, 400) and (500, 500) are on no sign
    assert (t['track_boxes'], t['covered'], t['coverage']) == (5, 3, 0.75)
    assert t['off_sign'] == 2 and t['off_sign_per_frame'] == 1.0


def test_classification_figures_by_hand():
    c = ws.stage_figures(_frames(FRAME_1, FRAME_2))['classification']
    # matched boxes: A -> road_work_ahead (right), B -> lane_shift_right, D -> unknown
    assert (c['boxes'], c['correct'], c['accuracy']) == (3, 1, round(1 / 3, 4))
    assert c['confusion'] == {'lane_shift_left': {'lane_shift_right': 1},
                              'road_work_ahead': {'road_work_ahead': 1, 'unknown': 1}}
    # road_work_ahead: P 1/1, R 1/2; lane_shift_left: never given (P 0), R 0/1
    assert c['classes']['road_work_ahead'] == {'boxes': 2, 'given': 1, 'correct': 1,
                                               'precision': 1.0, 'recall': 0.5}
    assert c['classes']['lane_shift_left']['precision'] == 0.0
    assert c['macro_precision'] == 0.5 and c['macro_recall'] == 0.25
    # two boxes on no sign, one of them given a work-zone class: 1 over 2 frames
    assert (c['background_boxes'], c['background_as_workzone']) == (2, 1)
    assert c['background_as_workzone_per_frame'] == 0.5


def test_pooled_figures_sum_the_bags_and_gt_mode_is_na():
    one, two = ws.stage_figures(_frames(FRAME_1)), ws.stage_figures(_frames(FRAME_2))
    both = ws.stage_figures(_frames(FRAME_1, FRAME_2))
    assert ws.pool_stages([one, None, two]) == both
    assert ws.pool_stages([None]) is None and ws.stage_figures(_frames(None)) is None
    assert 'n/a' in ws.stage_lines(None)[0]
    assert any('LiDAR' in line and 'evaluate lidar' in line for line in ws.stage_lines(both))
    md = '\n'.join(ws.report_lines([{'bag': '/b/one', 'stages': one},
                                    {'bag': '/b/two', 'stages': two}], both))
    assert '| one | 1 |' in md and '| **pooled** | 2 | 0.333 | 0.250 | 0.500 | 0.750 |' in md
    assert 'evaluate lidar' in md
    assert 'n/a' in '\n'.join(ws.report_lines([], None))


def test_the_pipeline_records_each_tracks_answer():
    from workzone_ros.tools.workzone_pipeline import _stage_boxes
    box = Box(x=1.0, y=2.0, w=3.0, h=4.0)
    tracks = [Track(track_id=k, box=box, source='detection', age=1, hits=1, similarity=1.0)
              for k in (1, 2, 3)]
    signs = [Sign(box=box, class_key='road_work_ahead', code='W20-1', category='workzone',
                  score=0.9, track_id=1),
             Sign(box=box, class_key='unknown', code='-', category='unknown', score=0.0,
                  track_id=2),
             Sign(box=box, class_key='stop', code='R1-1', category='general', score=0.9)]
    out = _stage_boxes([Detection(box=box, confidence=0.9)], tracks, signs)
    assert out == {'dets': [[1.0, 2.0, 3.0, 4.0]],
                   'tracks': [[[1.0, 2.0, 3.0, 4.0], 'road_work_ahead'],
                              [[1.0, 2.0, 3.0, 4.0], 'unknown'],
                              [[1.0, 2.0, 3.0, 4.0], 'background']]}


@pytest.fixture
def perfect_pipeline(monkeypatch):
    """A pipeline whose detections and tracks are the legible GT signs, rightly classified."""
    from workzone_ros.tools import eval_workzone as ev
    from workzone_ros.tools import workzone_pipeline as wp

    class Perfect:
        needs_images = True

        def __init__(self, opts):
            self.gt = ev.GtSignSource(opts, 'x', {})
            self.last_stages = None

        def __call__(self, gt, image, focal):
            signs, n = self.gt(gt)
            boxes = [[s.box.x, s.box.y, s.box.w, s.box.h] for s in signs]
            self.last_stages = {'dets': boxes,
                                'tracks': [[b, s.class_key] for b, s in zip(boxes, signs)]}
            return signs, n
    monkeypatch.setattr(wp, 'PipelineSource', Perfect)


def test_cached_stages_reach_the_figures(perfect_pipeline, tmp_path):
    """The cache keeps the stages' boxes; a cached run (no images) scores every stage."""
    from test_eval_workzone import write_gt_bag

    from workzone_ros.bagio import read_messages
    from workzone_ros.interfaces import GtSigns, decode
    from workzone_ros.tools import eval_workzone as ev
    from workzone_ros.tools import workzone_pipeline as wp
    bag = write_gt_bag(tmp_path / 'zone', seconds=12.0)
    opts = ev.EvalOptions(signs='pipeline', cache=str(tmp_path / 'cache'))
    src = wp.CachedSource(opts, 'zone', opts.cache)
    for _, _, msg in read_messages(str(bag), ['/groundtruth/signs']):
        src(decode(msg.data, GtSigns), None, None)
    src.flush()
    r = ev.evaluate_bag(str(bag), opts)
    s = r['stages']
    assert s['frames'] == r['frames'] == 180 and s['detection']['signs'] > 0
    assert s['detection']['precision'] == s['detection']['recall'] == 1.0
    assert s['tracking']['coverage'] == 1.0 and s['classification']['accuracy'] == 1.0
    assert s['detection']['false'] == s['tracking']['off_sign'] == 0
    assert ev.summarise([r])['stages'] == s
