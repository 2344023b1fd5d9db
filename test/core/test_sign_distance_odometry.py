"""Sign distance estimates (LiDAR range, apparent size) and metres travelled from odometry."""
import math

import numpy as np
import pytest

from workzone_ros.core.odometry import TravelledDistance
from workzone_ros.core.overlay import banner_text, draw_debug
from workzone_ros.core.sign_distance import (
    distance_from_size,
    estimate_distance,
    face_box_height_m,
    focal_from_fov,
)
from workzone_ros.interfaces import Box, Header, Roi, Sign, Time, WorkzoneState


def _roi(x, y, w, h, range_m, cid=1):
    return Roi(candidate_id=cid, box=Box(x=x, y=y, w=w, h=h), center=(x + w / 2, y + h / 2),
               range_m=range_m, radius_m=0.8, position=(0.0, 0.0, range_m))


def test_a_diamond_box_is_its_side_times_sqrt2_and_a_rectangle_its_height():
    assert face_box_height_m('road_work_ahead') == pytest.approx(1.2 * math.sqrt(2))
    assert face_box_height_m('end_road_work') == pytest.approx(0.6)
    assert face_box_height_m('background') is None
    assert face_box_height_m('no_such_sign') is None


def test_size_distance_is_the_pinhole_relation():
    f = focal_from_fov(640, 60.0)
    assert f == pytest.approx(320 / math.tan(math.radians(30)))
    # a 1.2 m diamond (1.70 m box) 50 m away on a 554 px focal length is ~18.8 px tall
    h = f * 1.2 * math.sqrt(2) / 50.0
    d = distance_from_size(Box(x=0, y=0, w=h, h=h), 'road_work_ahead', f)
    assert d == pytest.approx(50.0)
    assert distance_from_size(Box(x=0, y=0, w=0, h=0), 'road_work_ahead', f) is None


def test_lidar_range_wins_over_size_and_the_nearest_roi_centre_is_chosen():
    box = Box(x=100, y=100, w=20, h=20)
    far = _roi(60, 60, 100, 100, 80.0, cid=1)     # contains the centre, centre 0 px away
    near = _roi(95, 95, 40, 40, 30.0, cid=2)      # contains it too, centre 5 px away
    d, source = estimate_distance(box, 'road_work_ahead', 554.0, [near, far])
    assert (d, source) == (80.0, 'lidar')
    d, source = estimate_distance(box, 'road_work_ahead', 554.0, [_roi(300, 300, 20, 20, 9.0)])
    assert source == 'size' and d == pytest.approx(554.0 * 1.2 * math.sqrt(2) / 20)
    assert estimate_distance(box, 'background', 554.0, []) == (None, 'none')
    assert estimate_distance(box, 'road_work_ahead', None, []) == (None, 'none')


def test_bad_fov_is_a_clear_error():
    with pytest.raises(ValueError, match='field of view'):
        focal_from_fov(640, 0.0)


def test_travelled_distance_sums_the_path_and_survives_glitches_and_loops():
    odo = TravelledDistance(max_speed_mps=60.0)
    for k in range(11):                            # 10 steps of 2 m at 10 Hz (20 m/s)
        odo.update(k * 0.1, 2.0 * k, 0.0)
    assert odo.distance_m == pytest.approx(20.0)
    odo.update(1.1, 500.0, 0.0)                   # 480 m in 0.1 s: a pose reset, not travel
    assert odo.distance_m == pytest.approx(20.0) and odo.rejected == 1
    with pytest.raises(ValueError, match='not finite'):
        odo.update(1.2, float('nan'), 0.0)
    assert odo.distance_m == pytest.approx(20.0)    # state kept
    odo.update(0.0, 0.0, 0.0)                     # the bag looped: restart
    assert odo.resets == 1 and odo.distance_m == 0.0


def test_a_stopped_car_travels_nothing():
    odo = TravelledDistance()
    for k in range(20):
        odo.update(k * 0.02, 5.0, 3.0)
    assert odo.distance_m == 0.0


def test_debug_overlay_draws_boxes_and_the_phase_banner_without_touching_the_frame():
    frame = np.zeros((120, 160, 3), np.uint8)
    sign = Sign(box=Box(x=40, y=50, w=30, h=30), class_key='road_work_ahead', code='W20-1',
                category='workzone', score=0.93, track_id=4, distance_m=42.0)
    state = WorkzoneState(header=Header(stamp=Time(sec=1)), active=True, likelihood=0.8,
                          phase='inside', speed_limit_mph=45, lanes_closed=['right'])
    out = draw_debug(frame, [sign], [Box(x=100, y=80, w=10, h=10)], state)
    assert frame.max() == 0                                    # input untouched
    assert out[50, 55].tolist() != [0, 0, 0]                   # top edge of the sign's box
    assert out[5, 150].tolist() != [0, 0, 0]                   # banner
    text = banner_text(state)
    assert 'INSIDE' in text and '45 mph' in text and 'closed right' in text
    assert banner_text(None) == 'work zone: no state yet'
