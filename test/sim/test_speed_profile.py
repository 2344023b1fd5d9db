"""The ego's speed profile: slow-down to the posted limit, stop-and-go, and the sensors that
follow it (odometry, LiDAR and camera ground truth, event times)."""
from __future__ import annotations

import collections

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from workzone_ros.interfaces import GtLidar, GtSigns, GtWorkzone, decode
from workzone_ros.sim.scenario import (
    RANDOM_STOP_PROBABILITY,
    LaneVehicle,
    ScenarioError,
    build_scene,
    load_scenario,
    parse_scenario,
    random_scenario,
)
from workzone_ros.sim.speed_profile import (
    MPH,
    SlowZone,
    SpeedProfile,
    SpeedProfileError,
    Stop,
)
from workzone_ros.sim.writer import EPOCH_NS, SynthOptions, write_bag

DT = 0.01


def _profile() -> SpeedProfile:
    return SpeedProfile(0.0, 26.8, [SlowZone(300.0, 900.0, 45 * MPH)], [Stop(1200.0, 8.0)],
                        decel=1.2, accel=1.0)


def test_profile_kinematics():
    p = _profile()
    t = np.arange(-1.0, 150.0, DT)
    s, v = p.s(t), p.speed(t)
    assert np.diff(s).min() >= 0.0                              # never backwards
    assert v.min() == 0.0 and v.max() == pytest.approx(26.8)
    acc = np.diff(v) / DT
    assert acc.min() >= -1.2 - 1e-6 and acc.max() <= 1.0 + 1e-6   # comfortable rates only
    ds_dt = np.gradient(s, t)
    assert np.abs(ds_dt - v)[1:-1].max() < 0.01                 # speed() is ds/dt
    # slowed to 45 mph once the braking distance from the sign is behind
    brake = (26.8 ** 2 - (45 * MPH) ** 2) / (2 * 1.2)
    inside = (s > 300.0 + brake + 1.0) & (s < 900.0)
    assert inside.any() and v[inside].max() <= 45 * MPH + 1e-6
    assert v[s < 300.0].min() == pytest.approx(26.8)
    # t_at and s are inverse; s(t_at(s)) == s everywhere
    q = np.linspace(-20.0, 2500.0, 4001)
    assert np.abs(p.s(p.t_at(q)) - q).max() < 1e-6
    assert np.diff(p.t_at(q)).min() > 0


def test_profile_standstill_and_first_arrival():
    p = _profile()
    arrive = float(p.t_at(1200.0))
    assert float(p.speed(arrive)) == 0.0
    during = arrive + np.linspace(0.0, 8.0, 50)
    assert np.all(p.s(during) == 1200.0) and np.all(p.speed(during) == 0.0)
    assert float(p.s(arrive + 8.5)) > 1200.0 and float(p.s(arrive - 0.5)) < 1200.0
    # the first time it reaches the stop, not the time it leaves
    assert float(p.t_at(1200.0 + 1e-6)) == pytest.approx(arrive + 8.0, abs=0.02)
    # the last 100 m before the stop on the braking envelope that ends there
    assert float(p.speed_at_s(1100.0)) == pytest.approx(np.sqrt(2 * 1.2 * 100.0))


@pytest.mark.parametrize('kwargs, needle', [
    ({'stops': [Stop(0.0, 3.0)]}, 'after the start'),
    ({'zones': [SlowZone(500.0, 400.0, 10.0)]}, 's_to >= s_from'),
    ({'decel': 0.0}, 'must be > 0'),
])
def test_profile_errors(kwargs, needle):
    with pytest.raises(SpeedProfileError, match=needle):
        SpeedProfile(0.0, 20.0, **kwargs)


def test_constant_is_the_default():
    spec = load_scenario('demo')
    assert spec.ego.speed_profile == 'constant' and spec.ego.stop_and_go is None
    _, ego, events = build_scene(spec, 0)
    assert ego.profile is None
    for e in events:                                 # x_m is rounded to the millimetre
        assert e.t == pytest.approx(e.x_m / 22.4, abs=1e-4)


def test_stop_and_go_preset():
    spec = load_scenario('stop_and_go')
    assert spec.ego.speed_profile == 'posted' and spec.ego.stop_and_go.at == 800.0
    scene, ego, events = build_scene(spec, 0)
    by_kind = collections.defaultdict(list)
    for e in events:
        by_kind[e.kind].append(e)
        assert e.t == pytest.approx(float(ego.t_at(e.x_m)), abs=1e-4)   # first passage
        assert 0.0 < e.t < spec.duration
    limit = spec.workzone.speed_limit * MPH
    s_sign, s_end = by_kind['speed_limit'][0].x_m, by_kind['zone_end'][0].x_m
    t = np.arange(0.0, spec.duration, 0.05)
    s, v = ego.s(t), ego.speed_at(t)
    assert np.diff(s).min() >= 0.0
    assert v.max() == pytest.approx(spec.ego.speed) and v.min() == 0.0
    brake = (spec.ego.speed ** 2 - limit ** 2) / (2 * spec.ego.decel)
    zone = (s > s_sign + brake) & (s <= s_end)
    assert zone.sum() > 100 and v[zone].max() <= limit + 0.05
    assert v[s < s_sign].min() == pytest.approx(spec.ego.speed)
    assert v[-1] == pytest.approx(spec.ego.speed)                # back to cruise after the zone
    # the standstill: 8 s at arc length 800, no motion in the poses either
    arrive = float(ego.t_at(800.0))
    stand = t[(t > arrive + 0.01) & (t < arrive + 7.99)]
    assert stand.size > 150 and np.all(ego.s(stand) == 800.0)
    p0 = ego.base_pose(float(stand[0]))
    for tt in stand[::20]:
        p = ego.base_pose(float(tt))
        assert np.array_equal(p.position, p0.position) and p.pitch == p.roll == 0.0
        lin, ang = ego.twist(float(tt))
        assert np.abs(lin).max() < 1e-9 and np.abs(ang).max() < 1e-9
    # the body-frame twist the writer puts on /odom is ds/dt (curve and shifts: < 1 %)
    for tt in np.arange(0.5, spec.duration - 0.5, 0.7):
        lin, _ = ego.twist(float(tt))
        assert lin[0] == pytest.approx(float(ego.speed_at(tt)), rel=0.01, abs=0.03), tt
    # the distractors still pass alongside, never through the ego
    for o in scene.objects:
        if not (isinstance(o, LaneVehicle) and o.speed):
            continue
        for tt in np.arange(0.0, spec.duration, 0.5):
            rel = ego.base_pose(float(tt)).to_body(o.at(float(tt)).center)
            assert not (abs(rel[1]) < 2.2 and -6.0 < rel[0] < 8.0), (o.object_id, tt, rel)


@pytest.mark.parametrize('ego, needle', [
    ({'speed_profile': 'posted'}, 'needs workzone.speed_limit'),
    ({'speed_profile': 'slow'}, 'speed_profile must be one of'),
    ({'stop_and_go': {'stop_s': 3}}, 'at (arc length'),
    ({'stop_and_go': {'at': 100, 'wait': 3}}, "unknown key 'wait'"),
    ({'start_s': 200, 'stop_and_go': {'at': 100}}, 'must lie after start_s'),
    ({'decel': 0.0}, 'decel must be in'),
])
def test_ego_keys_errors_are_one_line(ego, needle):
    with pytest.raises(ScenarioError) as exc:
        parse_scenario({'duration': 10, 'ego': ego}, 'bad')
    assert needle in str(exc.value) and '\n' not in str(exc.value)


def test_random_scenarios_draw_stop_and_go_on_some_seeds():
    specs = [random_scenario(seed) for seed in range(120)]
    stops = [s for s in specs if s.ego.stop_and_go is not None]
    share = len(stops) / len(specs)
    assert RANDOM_STOP_PROBABILITY - 0.12 < share < RANDOM_STOP_PROBABILITY + 0.12
    assert all(s.ego.speed_profile == 'constant' for s in specs if s.ego.stop_and_go is None)
    for spec in stops[:8]:
        seed = int(spec.name.split('_')[1])
        _, ego, events = build_scene(spec, seed)
        assert ego.profile is not None
        assert spec.ego.speed_profile == ('posted' if spec.workzone.speed_limit else 'constant')
        # the stretched run still passes the END ROAD WORK sign
        end = next(e for e in events if e.kind == 'zone_end')
        assert 0.0 < end.t < spec.duration
        for e in events:
            assert e.t == pytest.approx(float(ego.t_at(e.x_m)), abs=1e-4)


STOP_SCENARIO = """
name: halt
description: a short stop right at the start, for tests
duration: 2.6
ego: {speed: 6.0, lane: middle, decel: 3.0, accel: 3.0, stop_and_go: {at: 6.5, stop_s: 0.5}}
signs:
  - {class: speed_limit, s: 45, speed_value: 65, tilt_deg: 0, fade: 0}
distractors: {vehicles: 0, orange_vehicles: 0, yellow_vehicles: 0, cones: 0, drums: 0,
              general_signs: 0, mile_markers: false}
"""


def test_bag_follows_the_stop(tmp_path):
    path = tmp_path / 'halt.yaml'
    path.write_text(STOP_SCENARIO)
    spec = load_scenario(str(path))
    out = tmp_path / 'halt_bag'
    write_bag(spec, out, SynthOptions(seed=2, workers=0, compressed=True), progress=None)
    _, ego, _ = build_scene(spec, 2)
    arrive, leave = float(ego.t_at(6.5)), float(ego.t_at(6.5)) + 0.5
    assert 2.0 < arrive < 2.2
    msgs = collections.defaultdict(list)
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn, t, raw in reader.messages():
            msgs[conn.topic].append(((t - EPOCH_NS) / 1e9, reader.deserialize(raw,
                                                                              conn.msgtype)))
    # odometry: twist = ds/dt, zero and a fixed pose while the ego stands
    odom = msgs['/odom']
    assert len(odom) == 130
    still = []
    for t, m in odom[1:]:              # (the first twist differences across the road start)
        vx = m.twist.twist.linear.x
        assert vx == pytest.approx(float(ego.speed_at(t)), abs=0.02), t
        if arrive + 0.002 < t < leave - 0.002:
            assert vx == 0.0 and m.twist.twist.angular.z == 0.0
            still.append((m.pose.pose.position.x, m.pose.pose.position.y))
    assert len(still) >= 20 and len(set(still)) == 1
    xs = np.array([m.pose.pose.position.x for _, m in odom])
    assert np.diff(xs).min() >= 0.0                            # a straight road along +x
    # the sign stands still in the camera and the LiDAR while the ego does
    boxes = [(g.box.x, g.box.y, g.box.w, g.box.h)
             for t, m in msgs['/groundtruth/signs'] if arrive < t < leave
             for g in decode(m.data, GtSigns).signs]
    assert len(boxes) >= 6 and len(set(boxes)) == 1
    centers = [g.center for t, m in msgs['/groundtruth/lidar'] if arrive < t and t + 0.1 < leave
               for g in decode(m.data, GtLidar).signs]
    assert len(centers) >= 3 and len(set(centers)) == 1
    moving = [g.center for t, m in msgs['/groundtruth/lidar'] if t + 0.1 < arrive - 0.5
              for g in decode(m.data, GtLidar).signs]
    assert len(set(moving)) == len(moving) >= 2
    wz = decode(msgs['/groundtruth/workzone'][0][1].data, GtWorkzone)
    assert wz.events == []
