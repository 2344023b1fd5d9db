"""``workzone-ros evaluate workzone`` on small bags written here (ground truth only, no
rendering): the GT-signs mode finds the zone's begin and end, the JSON schema, the report,
and one-line errors for a corrupt bag or a bag without ground truth."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from wz_tools_helpers import run_cli

from workzone_ros import bagio
from workzone_ros.interfaces import (
    Box,
    GtEvent,
    GtSign,
    GtSigns,
    GtWorkzone,
    Header,
    Time,
    encode,
)
from workzone_ros.tools import eval_workzone as ev

T0 = 1_700_000_000_000_000_000
FPS = 15
FOCAL = 554.26
SPEED = 20.0
#: (sign id, class, route position m, event kind, value); the ego starts at 0 m.
LAYOUT = [(1, 'road_work_ahead', 150.0, 'zone_approaching', None),
          (2, 'work_zone_speed_limit', 300.0, 'speed_limit', 45),
          (3, 'work_zone_begin', 450.0, 'zone_begin', None),
          (4, 'lane_shift_right', 600.0, 'lane_shift', 'right'),
          (5, 'end_road_work', 900.0, 'zone_end', None)]
SIZE = {'road_work_ahead': (1.7, 1.7), 'work_zone_speed_limit': (1.2, 2.1),
        'work_zone_begin': (1.2, 1.5), 'lane_shift_right': (1.7, 1.7),
        'end_road_work': (1.2, 0.6)}


def _gt_signs(t_ns: int, s: float) -> GtSigns:
    signs = []
    for sid, key, x, _, _ in LAYOUT:
        ahead = x - s
        if not 8.0 < ahead < 200.0:
            continue
        d = math.hypot(ahead, 9.75)
        w, h = (FOCAL * m / d for m in SIZE[key])
        u = 320 + FOCAL * 9.75 / ahead
        if u + w / 2 > 640:
            continue
        signs.append(GtSign(sign_id=sid, class_key=key, code='-', category='workzone',
                            box=Box(x=u - w / 2, y=200 - h, w=w, h=h),
                            distance_m=round(d, 3), visible_fraction=1.0))
    return GtSigns(header=Header(stamp=Time.from_ns(t_ns), frame_id='camera'), signs=signs)


def _gt_workzone(t_ns: int) -> GtWorkzone:
    events = [GtEvent(kind=kind, t=x / SPEED, x_m=x, value=value, sign_id=sid)
              for sid, _, x, kind, value in LAYOUT]
    return GtWorkzone(header=Header(stamp=Time.from_ns(t_ns), frame_id='odom'),
                      scenario='unit', seed=0, begin_t=450.0 / SPEED, begin_x_m=450.0,
                      end_t=900.0 / SPEED, end_x_m=900.0, events=events, weather='test')


def write_gt_bag(path: Path, seconds: float = 55.0, workzone: bool = True) -> Path:
    """GT signs per frame at 15 fps, odometry at 50 Hz, the zone's truth at t0."""
    ts = bagio.typestore()
    T = ts.types
    String = T['std_msgs/msg/String']

    def header(t_ns, frame):
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame)

    def odom(t_ns, x):
        p = T['geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](x=x, y=0.0, z=0.0),
                                        orientation=T['geometry_msgs/msg/Quaternion'](
                                            x=0.0, y=0.0, z=0.0, w=1.0))
        v3 = T['geometry_msgs/msg/Vector3']
        return T['nav_msgs/msg/Odometry'](
            header=header(t_ns, 'odom'), child_frame_id='base_link',
            pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=p, covariance=np.zeros(36)),
            twist=T['geometry_msgs/msg/TwistWithCovariance'](
                twist=T['geometry_msgs/msg/Twist'](linear=v3(x=SPEED, y=0.0, z=0.0),
                                                   angular=v3(x=0.0, y=0.0, z=0.0)),
                covariance=np.zeros(36)))
    with bagio.BagWriter(path) as bag:
        bag.add_topic('/groundtruth/signs', 'std_msgs/msg/String')
        bag.add_topic('/odom', 'nav_msgs/msg/Odometry')
        if workzone:
            bag.add_topic('/groundtruth/workzone', 'std_msgs/msg/String', qos='transient_local')
            bag.write('/groundtruth/workzone', T0, String(data=encode(_gt_workzone(T0))))
        events = sorted([(T0 + round(k * 1e9 / FPS), 'f') for k in range(int(seconds * FPS))]
                        + [(T0 + k * 20_000_000, 'o') for k in range(int(seconds * 50))])
        for t_ns, kind in events:
            s = (t_ns - T0) * 1e-9 * SPEED
            if kind == 'o':
                bag.write('/odom', t_ns, odom(t_ns, s))
            else:
                bag.write('/groundtruth/signs', t_ns, String(data=encode(_gt_signs(t_ns, s))))
    return path


@pytest.fixture(scope='module')
def gt_bag(tmp_path_factory) -> Path:
    return write_gt_bag(tmp_path_factory.mktemp('wz') / 'zone')


def test_gt_signs_recognise_the_begin_end_and_changes(gt_bag):
    res = ev.evaluate_bag(str(gt_bag), ev.EvalOptions())
    assert 'error' not in res, res
    assert res['zone_begin']['recognised'] and res['zone_end']['recognised']
    assert abs(res['zone_begin']['error_s']) < 0.2 and abs(res['zone_end']['error_s']) < 0.2
    assert [(c['kind'], c['value'], c['recognised']) for c in res['changes']] == \
        [('speed_limit', 45, True), ('lane_shift', 'right', True)]
    assert res['flicker'] == 0 and res['phase_accuracy'] > 0.95
    assert res['zone_begin']['images'] > 0 and res['zone_begin']['recall'] == 1.0
    assert set(res['time_to_correct']) == {'approaching', 'inside', 'leaving', 'none'}


def test_without_odometry_the_bounds_are_still_within_a_second(gt_bag):
    res = ev.evaluate_bag(str(gt_bag), ev.EvalOptions(odom=False))
    # the drive is at 20 m/s, the fusion assumes 22.35 m/s: the last look is ~10 m ahead
    assert abs(res['zone_begin']['error_s']) < 1.0 and abs(res['zone_end']['error_s']) < 1.0


def test_noise_is_seeded_and_deterministic(gt_bag):
    opts = ev.EvalOptions(drop=0.3, confuse=0.1, spurious=0.05, seed=3)
    a, b = (ev.evaluate_bag(str(gt_bag), opts) for _ in range(2))
    for r in (a, b):                 # wall clock and processing times are not deterministic
        for key in ('wall_s', 'stage_ms', '_stage_ms'):
            r.pop(key)
    assert a == b
    assert a['zone_begin']['recall'] < 1.0


def test_truth_phases_follow_legibility_and_the_passing_times(gt_bag):
    gtw, frames, _ = ev.run_bag(str(gt_bag), ev.EvalOptions())
    onsets = ev.truth_phases(frames, gtw, 12.0)
    assert onsets['inside'] == pytest.approx(22.5) and onsets['none'] == pytest.approx(45.0)
    assert onsets['approaching'] < 150 / SPEED and onsets['leaving'] < 45.0
    assert [f.truth for f in frames if f.t < onsets['approaching']] == \
        ['none'] * sum(f.t < onsets['approaching'] for f in frames)


def test_cli_json_schema_and_report(gt_bag, tmp_path):
    out = tmp_path / 'out.json'
    proc = run_cli('evaluate', 'workzone', str(gt_bag), '--json', str(out), '--report',
                   str(tmp_path / 'rep'), timeout=120)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert set(data) == {'tool', 'options', 'bags', 'summary'}
    bag = data['bags'][0]
    for key in ('frames', 'phase_accuracy', 'active_accuracy', 'unknown_frames',
                'confusion_phase', 'zone_begin', 'zone_end', 'changes', 'time_to_correct',
                'onsets', 'phase_changes', 'truth_changes', 'flicker', 'likelihood_inside',
                'likelihood_outside', 'sign_confusion', 'unknown_classes', 'resets',
                'wall_s'):
        assert key in bag, key
    for key in ('truth_t', 'pred_t', 'error_s', 'error_m', 'recognised', 'images',
                'precision', 'recall'):
        assert key in bag['zone_begin'], key
    s = data['summary']
    assert (s['bounds_recognised'], s['bounds'], s['changes_recognised'], s['changes']) == \
        (2, 2, 2, 2)
    assert bag['stages'] is None and s['stages'] is None       # --signs gt: no stages
    readme = (tmp_path / 'rep' / 'README.md').read_text()
    assert 'Table IV' in readme and 'zone_timeline.png' in readme
    assert 'Per-stage accuracy' in readme and 'n/a' in readme
    assert (tmp_path / 'rep' / 'zone_timeline.png').stat().st_size > 1000
    assert '[1/1] zone' in proc.stderr


def test_a_corrupt_bag_and_missing_ground_truth_are_one_line_errors(tmp_path):
    bad = tmp_path / 'bad'
    bad.mkdir()
    (bad / 'metadata.yaml').write_text('not: [a bag')
    no_gt = write_gt_bag(tmp_path / 'no_gt', seconds=2.0, workzone=False)
    for bag, needle in ((bad, 'bad'), (no_gt, 'groundtruth'), (tmp_path / 'nope', 'no such')):
        proc = run_cli('evaluate', 'workzone', str(bag), timeout=60)
        assert proc.returncode == 2
        errors = [ln for ln in proc.stderr.splitlines() if not ln.startswith('[')]
        assert len(errors) == 1 and needle in errors[0] and 'Traceback' not in proc.stderr, \
            proc.stderr


def test_fusion_overrides_change_the_run_and_bad_ones_are_one_line_errors(gt_bag):
    res = ev.evaluate_bag(str(gt_bag), ev.EvalOptions(fusion=(('timeout_m', 100.0),)))
    assert not res['zone_end']['recognised']            # timed out inside the zone
    assert ev._overrides(['sigma_m=400', 'use_channelizers=false', 'min_hits=4']) == \
        (('sigma_m', 400.0), ('use_channelizers', False), ('min_hits', 4))
    for bad in ('sigma=3', 'sigma_m', 'sigma_m=far', 'gamma=2'):
        with pytest.raises(ValueError):
            ev._overrides([bad])
    proc = run_cli('evaluate', 'workzone', str(gt_bag), '--fusion', 'gamma=2', timeout=60)
    assert proc.returncode == 2 and 'FusionConfig.gamma' in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_pipeline_without_a_classifier_is_a_one_line_error(gt_bag, tmp_path):
    proc = run_cli('evaluate', 'workzone', str(gt_bag), '--signs', 'pipeline',
                   '--classifier-model', str(tmp_path / 'none.npz'), timeout=60)
    assert proc.returncode == 2 and 'no sign classifier' in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and 'Traceback' not in proc.stderr


def test_cached_pipeline_signs_are_replayed_without_images(gt_bag, tmp_path, monkeypatch):
    """The cache stores a bag's Signs; a rerun reads them back (no images, no models)."""
    from workzone_ros.tools import workzone_pipeline as wp

    calls = []

    class FakePipeline:                        # the GT signs stand in for the perception
        needs_images = True

        def __init__(self, opts):
            self.gt = ev.GtSignSource(opts, 'x', {})

        def __call__(self, gt, image, focal):
            calls.append(gt.header.stamp.to_ns())
            return self.gt(gt)
    monkeypatch.setattr(wp, 'PipelineSource', FakePipeline)
    opts = ev.EvalOptions(signs='pipeline', cache=str(tmp_path / 'cache'))
    src = wp.CachedSource(opts, 'zone', opts.cache)
    assert src.needs_images
    frames = []
    from workzone_ros.bagio import read_messages
    from workzone_ros.interfaces import decode
    for topic, _, msg in read_messages(str(gt_bag), ['/groundtruth/signs']):
        frames.append(decode(msg.data, GtSigns))
    first = [src(g, None, None) for g in frames[:50]]
    src.flush()
    again = wp.CachedSource(opts, 'zone', opts.cache)
    assert not again.needs_images and len(calls) == 50
    assert [again(g, None, None) for g in frames[:50]] == first and len(calls) == 50


def test_stage_times_are_summarised_pooled_and_drawn():
    """Per-stage processing times: p50/p99/max per stage, pooled over bags in pipeline
    order, and one histogram row per stage in the report's PNG."""
    from workzone_ros.tools.eval_workzone import pooled_stage_ms, stage_summary
    from workzone_ros.tools.workzone_report import draw_stage_histograms
    s = stage_summary([1.0] * 98 + [50.0, 100.0])
    assert s['frames'] == 100 and s['p50'] == 1.0 and s['max'] == 100.0
    assert 1.0 < s['p99'] <= 100.0
    assert stage_summary([])['p50'] is None
    pooled = pooled_stage_ms([{'_stage_ms': {'color_detector': [1.0], 'fusion': [0.1]}},
                              {'_stage_ms': {'color_detector': [2.0], 'fusion': [0.2]}}, {}])
    assert pooled == {'color_detector': [1.0, 2.0], 'fusion': [0.1, 0.2]}
    img = draw_stage_histograms(pooled)
    assert img.ndim == 3 and img.shape[0] > 2 * 90
    assert (img < 255).any(axis=2).sum() > 1000        # bars, axes and labels drawn
