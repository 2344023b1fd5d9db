"""The work-zone fusion core on synthetic sequences of Signs payloads (no rclpy, no bags).

A tiny drive model: the ego moves along a straight route at ``speed`` (or a speed profile),
signs stand at route positions ``x``; a sign is in view (and classified) while it is between
``near`` and ``far`` metres ahead, with ``distance_m`` its true distance.
"""
from __future__ import annotations

import dataclasses
import math

import pytest

from workzone_ros.core.fusion import ACTIVE_PHASES, FusionConfig, WorkzoneFusion
from workzone_ros.interfaces import Box, Header, Sign, Signs, Time, WorkzoneState, decode, encode

FPS = 15.0
T0 = 1_000.0


@dataclasses.dataclass
class Placed:
    """A sign along the route."""

    key: str
    x: float
    track_id: int
    speed: int | None = None
    wrong: dict[int, str] = dataclasses.field(default_factory=dict)   # frame -> class


def sign(key: str, track_id: int | None = 1, dist: float | None = 50.0, score: float = 0.9,
         probabilities: dict | None = None, speed: int | None = None,
         category: str = 'workzone') -> Sign:
    """One classified sign."""
    return Sign(box=Box(x=400, y=200, w=30, h=30), class_key=key, code='-', category=category,
                score=score, track_id=track_id, probabilities=probabilities or {},
                speed_limit_mph=speed, speed_limit_confidence=None if speed is None else 0.9,
                distance_m=dist, distance_source='size' if dist is not None else 'none')


def frame(t: float, signs=(), frame_id: str = 'camera') -> Signs:
    """A Signs payload stamped at T0 + t seconds."""
    return Signs(header=Header(stamp=Time.from_sec(T0 + t), frame_id=frame_id),
                 signs=list(signs))


def drive(fusion: WorkzoneFusion, placed: list[Placed], duration: float, *,
          speed=22.4, odom: bool = True, near: float = 12.0, far: float = 120.0,
          channelizers=None, stale=lambda t: ()) -> list[tuple[float, float, WorkzoneState]]:
    """Run the fusion over a drive; returns (t, ego position, state) per frame."""
    out = []
    s = 0.0
    n = int(duration * FPS)
    for k in range(n):
        t = k / FPS
        v = speed(t, s) if callable(speed) else speed
        seen = []
        for p in placed:
            d = p.x - s
            if near <= d <= far:
                key = p.wrong.get(k, p.key)
                seen.append(sign(key, p.track_id, d, speed=p.speed))
        ch = channelizers(s) if channelizers else None
        st = fusion.update(frame(t, seen), odom_distance_m=s if odom else None,
                           channelizers=ch, stale_inputs=stale(t))
        out.append((t, s, st))
        s += v / FPS
    return out


def first(states, pred):
    """(t, s, state) of the first frame where ``pred(state)``, or None."""
    return next((x for x in states if pred(x[2])), None)


def phases(states) -> list[str]:
    """The distinct phases in order (consecutive repeats dropped)."""
    out: list[str] = []
    for _, _, st in states:
        if not out or out[-1] != st.phase:
            out.append(st.phase)
    return out


ZONE = [Placed('road_work_ahead', 400.0, 1),
        Placed('right_lane_closed_ahead', 550.0, 2),
        Placed('work_zone_speed_limit', 700.0, 3, speed=45),
        Placed('work_zone_begin', 850.0, 4),
        Placed('lane_shift_left', 1000.0, 5),
        Placed('end_road_work', 1400.0, 6)]


# --- the whole zone -------------------------------------------------------------------------

def test_a_zone_goes_none_approaching_inside_leaving_none_with_its_fields():
    fusion = WorkzoneFusion()
    states = drive(fusion, ZONE, 90.0)
    assert phases(states) == ['unknown', 'none', 'approaching', 'inside', 'leaving', 'none']
    t, s, st = first(states, lambda st: st.phase == 'inside')
    assert st.speed_limit_mph == 45 and st.lanes_closed == ['right'] and st.active
    assert 'passed' not in st.reason and 'work_zone_begin' in st.reason
    t, s, st = first(states, lambda st: st.lane_shift == 'left')
    assert st.phase == 'inside' and st.unknowns == []
    t, s, st = first(states, lambda st: st.phase == 'leaving')
    assert st.active and st.evidence[0].class_key == 'end_road_work'
    assert 0 < st.evidence[0].ahead_m < 120
    _, _, last = states[-1]
    assert last.phase == 'none' and not last.active
    assert (last.speed_limit_mph, last.lane_shift, last.lanes_closed) == (None, 'none', [])
    assert last.evidence == [] and last.likelihood == 0.0
    # the likelihood is above zero all through the zone (Gaussian propagation)
    zone = [st.likelihood for _, s, st in states if 860 < s < 1390]
    assert min(zone) > 0.5
    # every state is a valid payload
    assert decode(encode(last), WorkzoneState) == last


def test_approaching_starts_when_the_advance_sign_is_confirmed_not_on_its_first_frame():
    fusion = WorkzoneFusion()
    states = drive(fusion, ZONE[:1], 16.0)
    seen = first(states, lambda st: st.evidence)
    t_first_view = min(t for t, s, _ in states if 400 - s <= 120)
    assert seen[2].phase == 'approaching'
    assert seen[0] - t_first_view == pytest.approx((FusionConfig().min_hits - 1) / FPS, abs=1e-6)


@pytest.mark.parametrize('odom', [True, False])
def test_inside_starts_when_the_begin_sign_is_reached_not_when_first_seen(odom):
    fusion = WorkzoneFusion()
    begin = Placed('work_zone_begin', 500.0, 9)
    # without odometry the fusion assumes 22.35 m/s; drive at that speed
    states = drive(fusion, [begin], 30.0, speed=22.35, odom=odom)
    app = first(states, lambda st: st.phase == 'approaching')
    inside = first(states, lambda st: st.phase == 'inside')
    assert app is not None and app[1] < 500 - 100            # seen about 120 m ahead
    assert inside[1] == pytest.approx(500.0, abs=22.35 / FPS + 0.5)   # reached, within a frame
    assert inside[2].active and not app[2].active


def test_without_odometry_a_slower_car_reaches_the_begin_sign_later_than_assumed():
    """Time x assumed speed places the sign; the error is the speed ratio of the last look."""
    fusion = WorkzoneFusion()
    states = drive(fusion, [Placed('work_zone_begin', 500.0, 9)], 40.0, speed=15.0,
                   odom=False)
    inside = first(states, lambda st: st.phase == 'inside')
    # last seen 12 m ahead: assumed reached after 12 / 22.35 s, really after 12 / 15 s
    assert 500.0 - 12.0 < inside[1] < 500.0


def test_without_odometry_a_car_standing_before_the_begin_sign_does_not_reach_it():
    """Stop-and-go: the car stands 30 m before R22-1 (in view) for 20 s, then drives on."""
    fusion = WorkzoneFusion()
    states = drive(fusion, [Placed('work_zone_begin', 500.0, 9)], 50.0, odom=False,
                   speed=lambda t, s: 0.0 if 10.0 < t < 30.0 and s >= 470 else 22.35)
    inside = first(states, lambda st: st.phase == 'inside')
    assert inside is not None and inside[1] == pytest.approx(500.0, abs=3.0)


def test_a_car_that_slows_down_in_the_zone_keeps_it_with_odometry():
    fusion = WorkzoneFusion()
    placed = [Placed('road_work_ahead', 300.0, 1), Placed('work_zone_begin', 500.0, 2)]

    def speed(t, s):          # crawl at 0.5 m/s once inside (a jam): 400 s for 200 m
        return 22.4 if s < 520 else 0.5
    states = drive(fusion, placed, 420.0, speed=speed)
    assert states[-1][2].phase == 'inside'
    assert states[-1][2].evidence_age_s > 380                 # nothing seen for minutes
    assert states[-1][2].distance_since_evidence_m < 250
    assert states[-1][2].likelihood > 0.8                     # propagated over metres


def test_without_odometry_the_same_crawl_times_out_and_says_why():
    fusion = WorkzoneFusion()
    placed = [Placed('road_work_ahead', 300.0, 1), Placed('work_zone_begin', 500.0, 2)]
    states = drive(fusion, placed, 150.0, speed=lambda t, s: 22.4 if s < 520 else 0.5,
                   odom=False)
    end = first(states, lambda st: st.phase == 'none' and 'timeout' in st.reason)
    assert end is not None and 'timeout_s 90' in end[2].reason


# --- eq. 4 and hysteresis -------------------------------------------------------------------

def test_discounted_vote_corrects_a_wrong_latest_classification():
    """Seo et al. Fig. 3(b): two of the last five decisions wrong, the end sign still wins."""
    seq = ['end_road_work', 'end_road_work', 'other_workzone', 'end_road_work',
           'other_workzone']

    def run(config):
        fusion = WorkzoneFusion(config)
        for k in range(6):                      # inside a zone already (approaching)
            fusion.update(frame(k / FPS, [sign('road_work_ahead', track_id=1, dist=40.0 - k)]),
                          odom_distance_m=k * 1.5)
        for k, key in enumerate(seq, 6):
            st = fusion.update(frame(k / FPS, [sign(key, track_id=7, dist=80.0 - k)]),
                               odom_distance_m=k * 1.5)
        return st
    st = run(FusionConfig(min_hits=5))          # decided on the fifth (latest) frame
    assert st.phase == 'leaving'
    assert st.evidence[0].class_key == 'end_road_work' and st.evidence[0].track_id == 7
    # the latest decision alone (T = 0) says other_workzone: an in-zone sign ahead
    st = run(FusionConfig(min_hits=5, vote_window=0))
    assert st.phase == 'approaching'
    assert [e.class_key for e in st.evidence if e.track_id == 7] == ['other_workzone']


def test_probabilities_vote_rather_than_the_class_key():
    def run(probs):
        fusion = WorkzoneFusion()
        for k in range(6):
            st = fusion.update(frame(k / FPS, [sign('end_road_work', 3, 90.0,
                                                   probabilities=probs)]),
                               odom_distance_m=k * 1.5)
        return st
    st = run({'work_zone_begin': 0.55, 'end_road_work': 0.35, 'background': 0.1})
    assert st.phase == 'approaching' and st.evidence[0].class_key == 'work_zone_begin'
    # a vote whose discounted mean stays under min_confidence (0.4) is no evidence
    st = run({'work_zone_begin': 0.35, 'end_road_work': 0.33, 'background': 0.32})
    assert st.phase == 'unknown' and st.evidence == []


def test_a_single_stray_false_sign_does_not_start_a_zone():
    fusion = WorkzoneFusion()
    states = []
    for k in range(60):
        seen = [sign('road_work_ahead', track_id=42, dist=60.0)] if k == 30 else []
        seen += [sign('end_road_work', track_id=None, dist=40.0)] if k == 40 else []
        states.append(fusion.update(frame(k / FPS, seen), odom_distance_m=k * 1.5))
    assert {st.phase for st in states} == {'unknown', 'none'}
    assert max(st.likelihood for st in states) == 0.0


def test_untracked_signs_vote_alone_but_pool_their_hits():
    fusion = WorkzoneFusion()
    for k in range(5):
        st = fusion.update(frame(k / FPS, [sign('road_work_ahead', track_id=None,
                                               dist=100.0 - k)]), odom_distance_m=k * 1.5)
    assert st.phase == 'approaching' and st.evidence[0].track_id is None


def test_background_general_and_unclassified_signs_are_no_evidence():
    fusion = WorkzoneFusion()
    for k in range(40):
        seen = [sign('background', 1, 30.0, category='workzone'),
                sign('stop', 2, 30.0, category='general'),
                sign('unknown', 3, None, category='unknown', score=0.0)]
        st = fusion.update(frame(k / FPS, seen), odom_distance_m=k * 1.5)
    assert st.phase == 'none' and st.likelihood == 0.0 and fusion.unknown_classes == 0


def test_an_unknown_class_key_is_counted_not_fatal():
    fusion = WorkzoneFusion()
    for k in range(20):
        seen = [sign('flying_saucer', 1, 30.0),
                sign('road_work_ahead', 2, 80.0,
                     probabilities={'road_work_ahead': 0.9, 'martian': 0.1})]
        st = fusion.update(frame(k / FPS, seen), odom_distance_m=k * 1.5)
    assert fusion.unknown_classes == 40
    assert st.phase == 'approaching'


# --- fields ---------------------------------------------------------------------------------

def test_speed_limit_values_are_voted_over_frames():
    fusion = WorkzoneFusion()
    readings = [45, 45, 40, 45, None, 48, 45]
    for k, v in enumerate(readings):
        st = fusion.update(frame(k / FPS, [sign('work_zone_speed_limit', 5, 60.0 - k,
                                               speed=v)]), odom_distance_m=k * 1.5)
    assert st.speed_limit_mph == 45 and 'speed_limit_value' not in st.unknowns
    assert any(e.field == 'speed_limit_mph' and e.track_id == 5 for e in st.evidence)


def test_an_unread_speed_limit_is_listed_in_unknowns():
    fusion = WorkzoneFusion()
    for k in range(6):
        st = fusion.update(frame(k / FPS, [sign('work_zone_speed_limit', 5, 60.0 - k)]),
                           odom_distance_m=k * 1.5)
    assert st.speed_limit_mph is None and st.unknowns == ['speed_limit_value']
    assert st.phase == 'approaching'


def test_plain_lane_shift_has_an_unknown_direction():
    fusion = WorkzoneFusion()
    for k in range(6):
        st = fusion.update(frame(k / FPS, [sign('lane_shift', 5, 60.0 - k)]),
                           odom_distance_m=k * 1.5)
    assert st.lane_shift == 'unknown' and 'lane_shift_direction' in st.unknowns


def test_lane_closures_accumulate_and_the_latest_shift_wins():
    fusion = WorkzoneFusion()
    placed = [Placed('left_lane_closed_ahead', 200.0, 1), Placed('left_lane_ends', 300.0, 2),
              Placed('work_zone_begin', 400.0, 3), Placed('lane_shift_right', 500.0, 4),
              Placed('lane_shift', 700.0, 5)]
    states = drive(fusion, placed, 35.0)
    st = states[-1][2]
    assert st.lanes_closed == ['left'] and st.lane_shift == 'unknown'
    mid = first(states, lambda st: st.lane_shift == 'right')
    assert mid is not None and mid[2].phase == 'approaching'     # seen before the begin
    at = first(states, lambda st: st.phase == 'inside')
    assert at[2].lane_shift == 'right' and at[2].lanes_closed == ['left']


# --- time outs, stale inputs, resets --------------------------------------------------------

def test_no_evidence_for_timeout_m_ends_the_zone():
    fusion = WorkzoneFusion(FusionConfig(timeout_m=500.0))
    states = drive(fusion, [Placed('work_zone_begin', 200.0, 1)], 40.0)
    end = first(states, lambda st: st.phase == 'none' and 'timeout' in st.reason)
    assert end is not None
    assert end[1] - 188.0 == pytest.approx(500.0, abs=2.0)      # last seen 12 m before it
    assert end[2].evidence == [] and end[2].likelihood == 0.0


def test_stale_inputs_never_give_none():
    fusion = WorkzoneFusion(FusionConfig(timeout_m=300.0))
    stale = lambda t: ('/workzone/signs',) if t > 12.0 else ()   # noqa: E731
    states = drive(fusion, [Placed('work_zone_begin', 200.0, 1)], 40.0, stale=stale)
    after = [st for t, _, st in states if t > 12.0]
    assert all(st.phase == 'inside' for st in after)
    assert after[-1].stale_inputs == ['/workzone/signs']
    # when the inputs come back, the quiet distance counts again from there
    st = fusion.update(frame(40.0), odom_distance_m=states[-1][1] + 1.0)
    assert st.phase == 'inside'


def test_a_quiet_start_is_unknown_while_stale_and_none_when_live():
    fusion = WorkzoneFusion()
    for k in range(30):
        st = fusion.update(frame(k / FPS), odom_distance_m=k * 1.5,
                           stale_inputs=('/odom',))
    assert st.phase == 'unknown'
    st = fusion.update(frame(2.1), odom_distance_m=50.0)
    assert st.phase == 'none'
    st = fusion.tick(Time.from_sec(T0 + 2.5), stale_inputs=('/camera/camera_info',))
    assert st.phase == 'unknown' and 'stale' in st.reason


def test_a_backwards_stamp_resets_to_unknown_and_is_counted():
    fusion = WorkzoneFusion()
    drive(fusion, ZONE[:1], 16.0)
    assert fusion.phase == 'approaching'
    st = fusion.update(frame(-50.0), odom_distance_m=0.0)
    assert st.phase == 'unknown' and fusion.resets == 1 and st.evidence == []
    assert 'jumped back' in st.reason


def test_tick_ages_evidence_and_times_out_without_signs():
    fusion = WorkzoneFusion(FusionConfig(timeout_s=20.0))
    for k in range(5):
        fusion.update(frame(k / FPS, [sign('road_work_ahead', 1, 80.0)]))
    st = fusion.tick(Time.from_sec(T0 + 10.0))
    assert st.phase == 'approaching' and st.evidence_age_s == pytest.approx(10 - 4 / FPS, abs=1e-3)
    assert st.distance_since_evidence_m == pytest.approx((10 - 4 / FPS) * 22.35, rel=1e-3)
    st = fusion.tick(Time.from_sec(T0 + 5.0))          # an older stamp: no reset in tick
    assert fusion.resets == 0
    st = fusion.tick(Time.from_sec(T0 + 25.0))
    assert st.phase == 'none' and 'timeout' in st.reason


def test_before_any_input_the_state_is_unknown():
    st = WorkzoneFusion().tick(Time(sec=5))
    assert st.phase == 'unknown' and not st.active and st.likelihood == 0.0
    assert st.evidence_age_s is None and st.distance_since_evidence_m is None


# --- channelizers ---------------------------------------------------------------------------

def test_channelizers_alone_never_start_a_zone_but_raise_the_likelihood():
    fusion = WorkzoneFusion()
    states = drive(fusion, [], 20.0, channelizers=lambda s: 4)
    assert {st.phase for _, _, st in states} == {'unknown', 'none'}
    assert states[-1][2].likelihood == pytest.approx(0.3)


def test_channelizers_support_inside_when_the_begin_sign_is_missed():
    placed = [Placed('road_work_ahead', 200.0, 1)]
    drums = lambda s: 3 if s > 600 else 0            # noqa: E731 - the taper's drums
    on = drive(WorkzoneFusion(), placed, 40.0, channelizers=drums)
    inside = first(on, lambda st: st.phase == 'inside')
    assert inside is not None and 600 < inside[1] < 700 and 'channelizers' in inside[2].reason
    off = drive(WorkzoneFusion(FusionConfig(use_channelizers=False)), placed, 40.0,
                channelizers=drums)
    assert first(off, lambda st: st.phase == 'inside') is None


def test_channelizers_wait_for_a_begin_sign_that_is_ahead():
    # drums along the taper at 600 m are in view from 480 m; R22-1 stands at 560 m
    placed = [Placed('road_work_ahead', 200.0, 1), Placed('work_zone_begin', 560.0, 2)]
    states = drive(WorkzoneFusion(), placed, 40.0, channelizers=lambda s: 3 if s > 480 else 0)
    inside = first(states, lambda st: st.phase == 'inside')
    assert inside[1] == pytest.approx(560.0, abs=2.0) and 'reached' in inside[2].reason


# --- the configuration ----------------------------------------------------------------------

@pytest.mark.parametrize('name,value', [('gamma', 0.0), ('gamma', 1.5), ('vote_window', -1),
                                        ('min_hits', 2.5), ('sigma_m', float('nan')),
                                        ('use_channelizers', 1), ('timeout_m', 'far')])
def test_bad_configuration_names_the_field(name, value):
    with pytest.raises(ValueError, match=f'FusionConfig.{name}'):
        FusionConfig(**{name: value})


def test_every_knob_is_documented_and_a_new_config_keeps_the_memory():
    for f in dataclasses.fields(FusionConfig):
        assert len(f.metadata['doc']) > 20, f.name
    fusion = WorkzoneFusion()
    drive(fusion, ZONE[:1], 16.0)
    fusion.config = FusionConfig(sigma_m=300.0)
    assert fusion.phase == 'approaching'
    with pytest.raises(TypeError):
        fusion.config = {'sigma_m': 3}


def test_active_is_inside_or_leaving():
    assert ACTIVE_PHASES == ('inside', 'leaving')
    assert math.isclose(FusionConfig().assumed_speed_mps, 50 * 0.44704, rel_tol=1e-3)


def test_an_end_sign_alone_starts_nothing():
    fusion = WorkzoneFusion()
    states = drive(fusion, [Placed('end_road_work', 300.0, 1)], 20.0)
    assert {st.phase for _, _, st in states} == {'unknown', 'none'}


def test_an_end_sign_reacquired_after_the_zone_ended_does_not_flicker():
    """The tracker loses END ROAD WORK near the pass and finds it again under a new id,
    with a distance estimate a few metres long."""
    fusion = WorkzoneFusion()
    states = drive(fusion, [Placed('work_zone_begin', 300.0, 1), Placed('end_road_work', 600.0,
                                                                        2)], 27.0)
    assert states[-1][2].phase == 'none'
    s = states[-1][1]
    for k in range(10):                      # 8 m too far: the pass looks 8 m away again
        s += 1.5
        st = fusion.update(frame(27.0 + k / FPS, [sign('end_road_work', 9, 600.0 + 8.0 - s)]),
                           odom_distance_m=s)
        assert st.phase == 'none', st.reason


def test_the_next_zone_seen_before_the_end_sign_is_passed_is_kept():
    fusion = WorkzoneFusion()
    placed = [Placed('work_zone_begin', 300.0, 1), Placed('end_road_work', 600.0, 2),
              Placed('road_work_ahead', 680.0, 3)]
    states = drive(fusion, placed, 40.0)
    assert phases(states)[-3:] == ['leaving', 'none', 'approaching']
    assert states[-1][2].evidence[0].class_key == 'road_work_ahead'


def test_a_clock_ahead_of_the_image_stamps_is_not_a_reset():
    fusion = WorkzoneFusion()
    assert fusion.tick(Time.from_sec(T0 + 500.0)).phase == 'unknown'   # nothing aged yet
    for k in range(30):
        fusion.update(frame(k / FPS, [sign('road_work_ahead', 1, 90.0 - k)]),
                      odom_distance_m=k * 1.5)
        fusion.tick(Time.from_sec(T0 + k / FPS + 0.05))   # the node's clock, 50 ms ahead
    assert fusion.resets == 0 and fusion.phase == 'approaching'


def test_reaching_another_orange_sign_does_not_start_the_zone():
    """W20-1 is often classified other_workzone: reaching it must not mean inside."""
    fusion = WorkzoneFusion()
    states = drive(fusion, [Placed('other_workzone', 200.0, 1),
                            Placed('work_zone_begin', 600.0, 2)], 35.0)
    inside = first(states, lambda st: st.phase == 'inside')
    assert phases(states)[:4] == ['unknown', 'none', 'approaching', 'inside']
    assert inside[1] == pytest.approx(600.0, abs=2.0)
