"""The launcher's live scoring (``launch --score``) gives the figures of ``evaluate workzone``
when the graph published what the in-process fusion computes; frames the graph never
answered count as unknown."""
from __future__ import annotations

import threading
from pathlib import Path

import pytest
from test_eval_workzone import write_gt_bag

from workzone_ros.interfaces import Header, Signs, WorkzoneState
from workzone_ros.tools import eval_workzone as ev
from workzone_ros.tools.live_score import score_live


class _Recorded:
    """What a LiveRecorder holds after a run."""

    def __init__(self, states, signs):
        self._lock = threading.Lock()
        self.states, self.signs = states, signs


@pytest.fixture(scope='module')
def bag(tmp_path_factory) -> Path:
    return write_gt_bag(tmp_path_factory.mktemp('live') / 'zone', seconds=50.0)


def _replay(bag: Path, keep=lambda k: True) -> _Recorded:
    """The states the fusion node would publish for this bag (GT signs, odometry)."""
    from workzone_ros.bagio import read_messages
    from workzone_ros.core.fusion import WorkzoneFusion
    from workzone_ros.core.odometry import TravelledDistance
    from workzone_ros.interfaces import GtSigns, decode
    fusion, odo, states, signs = WorkzoneFusion(), TravelledDistance(), {}, {}
    opts = ev.EvalOptions()
    source = None
    for k, (topic, _, msg) in enumerate(read_messages(str(bag), ['/groundtruth/workzone',
                                                                  '/groundtruth/signs',
                                                                  '/odom'])):
        if topic == '/groundtruth/workzone':
            source = ev._gt_source(opts, bag.name, decode(msg.data, ev.GtWorkzone))
        elif topic == '/odom':
            p = msg.pose.pose.position
            odo.update(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, p.x, p.y)
        else:
            gt = decode(msg.data, GtSigns)
            found, channel = source(gt, None, None)
            payload = Signs(header=Header(stamp=gt.header.stamp), signs=found)
            st: WorkzoneState = fusion.update(payload, odom_distance_m=odo.distance_m,
                                              channelizers=channel)
            if keep(k):
                ns = gt.header.stamp.to_ns()
                states[ns], signs[ns] = st, payload
    return _Recorded(states, signs)


def test_a_live_run_scores_like_the_in_process_evaluation(bag, tmp_path):
    offline = ev.evaluate_bag(str(bag), ev.EvalOptions())
    live = score_live(str(bag), _replay(bag), str(tmp_path / 'report'))
    for key in ('phase_accuracy', 'flicker', 'zone_begin', 'zone_end', 'changes'):
        assert live[key] == offline[key], key
    text = (tmp_path / 'report' / 'README.md').read_text()
    assert 'Table IV' in text and 'timeline.png' in text


def test_frames_the_graph_never_answered_count_as_unknown(bag, tmp_path):
    recorded = _replay(bag, keep=lambda k: False)       # nothing published
    live = score_live(str(bag), recorded)
    assert live['answered_frames'] == 0 and live['phase_accuracy'] < 0.5
    assert not live['zone_begin']['recognised']
