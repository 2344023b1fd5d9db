"""A fusion restarted inside a zone (hold_none): unknown until evidence, never a false none."""
from test_fusion import Placed, drive, first, phases

from workzone_ros.core.fusion import FusionConfig, WorkzoneFusion


def test_a_restart_inside_a_zone_stays_unknown_until_the_end_sign_is_passed():
    # the restarted fusion sees only the rest of the zone: open lane, then END ROAD WORK
    fusion = WorkzoneFusion()
    fusion.hold_none('restarted while inside')
    states = drive(fusion, [Placed('end_road_work', 600.0, 9)], 40.0)
    before_end = [st.phase for _, s, st in states if s < 600.0]
    assert set(before_end) <= {'unknown', 'leaving'}, set(before_end)
    assert phases(states)[-1] == 'none'
    assert first(states, lambda st: st.phase == 'none')[1] >= 600.0


def test_without_a_hold_the_same_quiet_road_is_none_after_the_warm_up():
    states = drive(WorkzoneFusion(), [], 5.0)
    assert phases(states) == ['unknown', 'none']


def test_a_held_restart_gives_up_after_the_zone_timeout():
    fusion = WorkzoneFusion(FusionConfig(timeout_m=300.0))
    fusion.hold_none('restarted while inside')
    states = drive(fusion, [], 30.0)                 # 670 m of nothing
    hit = first(states, lambda st: st.phase == 'none')
    assert hit is not None and 300.0 <= hit[1] <= 340.0
    assert 'after a restart' in hit[2].reason


def test_evidence_after_a_restart_rebuilds_the_state():
    fusion = WorkzoneFusion()
    fusion.hold_none('restarted while approaching')
    states = drive(fusion, [Placed('work_zone_begin', 200.0, 4)], 15.0)
    assert 'inside' in phases(states) and 'none' not in phases(states)


def test_an_end_sign_where_another_sign_stands_is_part_of_its_assembly():
    # the stand's flags above a lane-ends diamond classified END ROAD WORK: same place
    placed = [Placed('road_work_ahead', 300.0, 1), Placed('right_lane_ends', 500.0, 2),
              Placed('end_road_work', 503.0, 3), Placed('work_zone_begin', 700.0, 4)]
    states = drive(WorkzoneFusion(), placed, 40.0)
    assert phases(states) == ['unknown', 'none', 'approaching', 'inside']
    off = drive(WorkzoneFusion(FusionConfig(colocated_m=0.0)), placed, 40.0)
    assert 'leaving' in phases(off)
