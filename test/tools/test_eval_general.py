"""``workzone-ros evaluate general --mile-hd WxH``: the size option, the HD camera (same
horizontal field of view) and a tiny render run with one numbered mile marker whose
``renders.mile_hd`` counts add up."""
from __future__ import annotations

import argparse
import math

import pytest

from workzone_ros.core.general import GeneralConfig, GeneralSignDetector
from workzone_ros.tools import eval_general as ev


def test_frame_size_parses_and_rejects() -> None:
    assert ev.frame_size('1280x720') == (1280, 720)
    assert ev.frame_size('1920X1080') == (1920, 1080)
    for bad in ('1280', '1280x', 'axb', '1280x720x3', '10x10', '100000x720'):
        with pytest.raises(argparse.ArgumentTypeError):
            ev.frame_size(bad)
    with pytest.raises(SystemExit):
        ev.main(['--mile-hd', 'big', '--no-renders'])
    # the options parse (no renders, no real clips: an empty report)
    assert ev.main(['--mile-hd', '1280x720', '--mile-min-px', '12', '--mile-work-width',
                    '1280', '--no-renders', '--verify', 'templates']) == 0


def test_hd_camera_keeps_the_horizontal_field_of_view() -> None:
    from workzone_ros.sim.world import DEFAULT_CAMERA as cam
    hd = ev.hd_camera(1280, 720)
    assert (hd.width, hd.height) == (1280, 720)
    assert math.isclose(math.atan(hd.cx / hd.fx), math.atan(cam.cx / cam.fx))
    assert hd.fx == hd.fy and (hd.cx, hd.cy) == (640.0, 360.0)
    assert hd.dist == cam.dist


def _args(**kw) -> argparse.Namespace:
    base = dict(every=3, min_px=20.0, min_visible=0.8, hd_frames=0, sheet_n=0, mile_hd=None,
                mile_min_px=12.0, mile_work_width=None)
    base.update(kw)
    return argparse.Namespace(**base)


def test_mile_hd_counts_on_one_short_scenario() -> None:
    from workzone_ros.sim.scenario_spec import DistractorSpec, ScenarioSpec, SignSpec
    spec = ScenarioSpec(
        name='mile_hd', duration=1.0, signs=(SignSpec('mile_marker', 40.0, speed_value=123),),
        distractors=DistractorSpec(vehicles=0, orange_vehicles=0, yellow_vehicles=0, cones=0,
                                   drums=0, general_signs=0, mile_markers=False))
    det = GeneralSignDetector(GeneralConfig())
    plain = ev.evaluate_renders([(spec, 3)], det, _args(), None)
    assert 'mile_hd' not in plain
    out = ev.evaluate_renders([(spec, 3)], det, _args(mile_hd=(1280, 720)), None)
    wide = ev.evaluate_renders([(spec, 3)], det, _args(mile_hd=(1280, 720),
                                                       mile_work_width=1280), None)
    assert out['mile_hd']['work_width'] == 640 and wide['mile_hd']['work_width'] == 1280
    for hd in (out['mile_hd'], wide['mile_hd']):
        _check(hd, out['frames'])
    # the native table is unchanged by the HD pass
    assert out['all'] == plain['all'] and out['mile_numbers'] == plain['mile_numbers']


def _check(hd: dict, frames: int) -> None:
    assert hd['frame_size'] == [1280, 720]
    assert 1 <= hd['frames'] <= frames
    small = hd['at_mile_min_px']
    assert small['min_px'] == 12.0 and hd['min_px'] == 20.0
    # the 0.25 m wide marker reaches 12 px (not 20) at 1280x720 before it leaves the frame
    assert small['visible_mile_markers'] >= 1
    for rule in (hd, small):
        assert rule['recognised'] <= rule['detected'] <= rule['visible_mile_markers']
        assert sum(rule['mile_numbers'].values()) == rule['recognised']
        rows = rule['by_distance_m'].values()
        assert sum(r.get('visible', 0) for r in rows) == rule['visible_mile_markers']
        assert sum(r.get('recognised', 0) for r in rows) == rule['recognised']
        assert sum(r.get('read_correct', 0) for r in rows) == \
            rule['mile_numbers']['read_correct']
