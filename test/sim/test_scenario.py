"""Scenario schema, MUTCD-like layout rules, the preset library and the ego trajectory."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from workzone_ros.core import signs as catalogue
from workzone_ros.sim.scenario import (
    ADVANCE_DEFAULT,
    RANDOM_STAND_PROBABILITY,
    STAND_BOTTOM_RANGE,
    STAND_LATERAL_RANGE,
    LaneVehicle,
    ScenarioError,
    build_scene,
    lane_profile,
    list_scenarios,
    load_scenario,
    parse_scenario,
    random_scenario,
    sign_bottom,
    sign_mount,
)
from workzone_ros.sim.world import SIGN_BOTTOM_HEIGHT, SIGN_LATERAL, Box, Cylinder, Quad

PRESETS = ('demo', 'paper_a', 'paper_b', 'paper_c', 'paper_d', 'paper_e', 'curve_dusk',
           'distractors')

# Seo et al., Table IV: frames, weather, and the events each video has (N/A rows left out).
TABLE_IV = {
    'paper_a': (3305, 'winter_overcast', {'begin', 'end'}),
    'paper_b': (4232, 'winter_overcast', {'begin', 'end', 'speed', 'right', 'closed'}),
    'paper_c': (874, 'spring_sunny', {'begin', 'end', 'speed', 'unknown', 'left', 'right'}),
    'paper_d': (3148, 'spring_sunny', {'begin', 'end', 'speed', 'unknown', 'left'}),
    'paper_e': (3280, 'spring_rain', {'begin', 'end', 'speed', 'unknown', 'left', 'right'}),
}


def _s(scene, p) -> float:
    return float(scene.road.to_frenet(np.array([p[0]]), np.array([p[1]]))[0][0])


def _table_events(events) -> set[str]:
    out = set()
    for e in events:
        if e.kind == 'zone_begin':
            out.add('begin')
        elif e.kind == 'zone_end':
            out.add('end')
        elif e.kind == 'speed_limit':
            out.add('speed')
        elif e.kind == 'lane_shift':
            out.add(e.value)
        elif e.kind == 'lane_closed':
            out.add('closed')
    return out


def test_library_lists_presets():
    names = list_scenarios()
    for name in PRESETS + ('random',):
        assert name in names and names[name], name


@pytest.mark.parametrize('name', sorted(TABLE_IV))
def test_paper_presets_match_table_iv(name):
    frames, weather, expected = TABLE_IV[name]
    spec = load_scenario(name)
    assert spec.frames == frames
    assert math.isclose(spec.duration, frames / 15.0)
    assert spec.weather == weather
    scene, ego, events = build_scene(spec, 0)
    assert _table_events(events) == expected
    # every event happens inside the video, with the zone in the middle of it
    assert all(0.0 < e.t < spec.duration for e in events)
    assert scene.ground_cover == ('snow' if weather.startswith('winter') else 'grass')


@pytest.mark.parametrize('name', PRESETS)
def test_layout_rules(name):
    spec = load_scenario(name)
    scene, ego, events = build_scene(spec, 0)
    road = scene.road
    for sp in scene.signs:
        # face bottom at 2.1 m on a post or 0.3-1.5 m on a portable stand, face turned
        # towards the ego traffic (a few degrees of jitter)
        if sign_mount(sp) == 'post':
            assert sign_bottom(sp) == pytest.approx(SIGN_BOTTOM_HEIGHT)
        else:
            assert STAND_BOTTOM_RANGE[0] <= sign_bottom(sp) <= STAND_BOTTOM_RANGE[1]
        s, _ = road.to_frenet(np.array([sp.center[0]]), np.array([sp.center[1]]))
        h = float(np.interp(s[0], road.s, road.heading))
        assert sp.normal @ np.array([math.cos(h), math.sin(h), 0.0]) < -0.9
        c = catalogue.get(sp.class_key)
        if c.shape == 'diamond':
            assert sp.width == pytest.approx(1.2 * math.sqrt(2))
        else:
            assert (sp.width, sp.height) == pytest.approx((c.width_m, c.height_m))
    # each sign stands on a post or a stand's mast reaching up to its face
    posts = [o for o in scene.objects if isinstance(o, Cylinder) and o.kind in ('post', 'stand')]
    assert len(posts) >= len(scene.signs)
    wz = spec.workzone
    if wz is None:
        assert events == []
        return
    by_kind = {}
    for e in events:
        by_kind.setdefault(e.kind, []).append(e)
    approach = by_kind['zone_approaching'][0]
    assert approach.x_m == pytest.approx(wz.taper_s - ADVANCE_DEFAULT, abs=1.0)
    begin, end = by_kind['zone_begin'][0], by_kind['zone_end'][0]
    assert approach.x_m < begin.x_m <= wz.taper_s < wz.end_s < end.x_m
    # MUTCD order: W20-1, W20-5, W4-2, speed limit, R22-1 ... G20-2
    order = [e.x_m for e in by_kind.get('lane_closed', [])] + \
        [e.x_m for e in by_kind.get('speed_limit', [])]
    assert order == sorted(order)
    assert all(approach.x_m < x < begin.x_m for x in order)
    if wz.lane_closed:
        keys = [next(s for s in scene.signs if s.object_id == e.sign_id).class_key
                for e in by_kind['lane_closed']]
        assert keys == [f'{wz.lane_closed}_lane_closed_ahead', f'{wz.lane_closed}_lane_ends']
    for e in by_kind.get('lane_shift', []):
        assert approach.x_m < e.x_m < end.x_m
    # drums along the taper and activity area, 12-20 m apart, never on the ego path
    drums = [o for o in scene.objects if isinstance(o, Cylinder) and o.kind == 'drum']
    zone = sorted(_s(scene, d.base) for d in drums
                  if wz.taper_s - 1 <= _s(scene, d.base) <= wz.end_s + 1)
    assert len(zone) >= wz.length / 20.0
    gaps = np.diff(zone)
    assert np.median(gaps) == pytest.approx(np.clip(np.median(gaps), 9.0, 20.0))
    for d in drums:
        s, lat = road.to_frenet(np.array([d.base[0]]), np.array([d.base[1]]))
        t = float(ego.t_at(s[0]))
        if 0 <= t <= spec.duration:
            assert abs(float(ego.d(t)) - float(lat[0])) > 1.6, (name, s[0], lat[0])


def test_every_catalogue_class_in_library():
    seen = set()
    for name in PRESETS:
        scene, _, _ = build_scene(load_scenario(name), 0)
        seen |= {s.class_key for s in scene.signs}
        if any(o.kind in ('drum', 'cone') for o in scene.objects):
            seen.add('background')
    assert seen == set(catalogue.BY_KEY)


def test_hard_negatives_in_library():
    scene, _, _ = build_scene(load_scenario('distractors'), 0)
    mats = {o.material for o in scene.objects if isinstance(o, Box)}
    kinds = {o.kind for o in scene.objects}
    assert {'vehicle_orange', 'vehicle_yellow', 'vehicle_paint'} <= mats
    assert {'drum', 'cone', 'guardrail', 'tree_line', 'overpass'} <= kinds
    keys = {s.class_key for s in scene.signs}
    assert {'warning_diamond', 'speed_limit', 'guide', 'mile_marker', 'stop', 'yield',
            'do_not_enter'} <= keys
    # stop / yield / do-not-enter stand further right, on side roads
    for s in scene.signs:
        if s.class_key in ('stop', 'yield', 'do_not_enter'):
            _, d = scene.road.to_frenet(np.array([s.center[0]]), np.array([s.center[1]]))
            assert d[0] < -15.0


def test_ego_follows_merges_and_shifts():
    spec = load_scenario('demo')          # ego in the closed right lane, shifts L / ? / R
    scene, ego, events = build_scene(spec, 0)
    wz = spec.workzone
    assert float(ego.d(0.0)) == pytest.approx(-3.7, abs=0.05)
    t_taper = float(ego.t_at(wz.taper_s))
    assert abs(float(ego.d(t_taper))) < 0.05            # merged into the middle lane
    t_shift = float(ego.t_at(wz.taper_s + wz.lane_shifts[0].at + 90.0))
    assert float(ego.d(t_shift)) == pytest.approx(1.85, abs=0.05)   # shifted left
    # smooth: bounded yaw rate, small pitch / roll
    yaws = np.unwrap([ego.base_pose(t).yaw for t in np.arange(0, spec.duration, 0.02)])
    assert np.abs(np.diff(yaws) / 0.02).max() < 0.1
    p = ego.base_pose(3.0)
    assert abs(p.pitch) < math.radians(0.5) and abs(p.roll) < math.radians(0.5)
    lin, ang = ego.twist(3.0)
    assert lin[0] == pytest.approx(22.4, rel=0.01) and abs(lin[1]) < 0.5
    assert np.allclose(ego.lidar_pose(3.0).position - p.position,
                       p.R @ np.array([1.0, 0.0, 1.95]))


def test_vehicles_follow_lanes():
    scene, ego, _ = build_scene(load_scenario('curve_dusk'), 0)
    movers = [o for o in scene.objects if isinstance(o, LaneVehicle) and o.speed]
    assert movers
    for v in movers:
        for t in (0.0, 20.0, 40.0):
            b = v.at(t)
            assert type(b) is Box
            s, d = scene.road.to_frenet(np.array([b.center[0]]), np.array([b.center[1]]))
            assert abs(d[0]) < 5.6
        # never inside the ego: other lanes, or ahead and faster
        for t in np.arange(0.0, 50.0, 0.5):
            b = v.at(float(t))
            rel = ego.base_pose(float(t)).to_body(b.center)
            assert not (abs(rel[1]) < 2.2 and -6.0 < rel[0] < 8.0), (v.object_id, t, rel)


def test_seeds_and_random_scenarios():
    spec = load_scenario('demo')
    a, b = build_scene(spec, 5), build_scene(spec, 5)
    assert [s.center.tolist() for s in a[0].signs] == [s.center.tolist() for s in b[0].signs]
    assert a[2] == b[2]
    c = build_scene(spec, 6)
    assert [s.yaw for s in a[0].signs] != [s.yaw for s in c[0].signs]
    seen_kinds = set()
    for seed in range(8):
        r = random_scenario(seed)
        assert r == random_scenario(seed)
        scene, ego, events = build_scene(r, seed)
        seen_kinds |= {e.kind for e in events}
        assert r.weather in ('winter_overcast', 'spring_sunny', 'spring_rain', 'dusk')
        ap = next(e for e in events if e.kind == 'zone_approaching')
        assert ap.x_m == pytest.approx(r.workzone.taper_s - ADVANCE_DEFAULT, abs=1.0)
        assert load_scenario('random', seed) == r
    assert {'zone_begin', 'zone_end', 'speed_limit', 'lane_shift', 'lane_closed'} <= seen_kinds


@pytest.mark.parametrize('data, needle', [
    ({'duration': 10, 'wether': 'dusk'}, "unknown key 'wether'"),
    ({'signs': [{'class': 'stopp', 's': 10}]}, "unknown sign class 'stopp'"),
    ({'signs': [{'class': 'background', 's': 10}]}, "unknown sign class 'background'"),
    ({'weather': 'sunny'}, 'weather must be one of'),
    ({'ego': {'speed': -3}}, 'speed must be in'),
    ({'ego': {'lane': 'fast'}}, 'lane must be one of'),
    ({'workzone': {'length': 300}}, 'taper_s'),
    ({'workzone': {'taper_s': 500, 'speed_limit': 47}}, 'multiple of 5'),
    ({'workzone': {'taper_s': 500, 'lane_shifts': [{'at': 10, 'direction': 'up'}]}},
     'direction must be one of'),
    ({'road': {'curves': [[100, 0.5]]}}, 'curvature'),
    ({'duration': 'long'}, 'duration must be a number'),
    ([1, 2], 'must be a mapping'),
])
def test_loader_errors_are_one_line(data, needle):
    with pytest.raises(ScenarioError) as exc:
        parse_scenario(data, 'bad')
    assert needle in str(exc.value) and '\n' not in str(exc.value)


def test_unknown_scenario_and_file_errors(tmp_path):
    with pytest.raises(ScenarioError, match='unknown scenario'):
        load_scenario('no_such_scenario')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('duration: [1\n')
    with pytest.raises(ScenarioError, match='cannot read scenario'):
        load_scenario(str(bad))
    ok = tmp_path / 'mine.yaml'
    ok.write_text('duration: 5\nworkzone: {taper_s: 100, advance: 450}\n')
    with pytest.raises(ScenarioError, match='no room for the W20-1'):
        build_scene(load_scenario(str(ok)), 0)
    with pytest.raises(ScenarioError, match='seed'):
        build_scene(load_scenario('demo'), -1)


def test_lane_profile_closed_lane_merges():
    spec = load_scenario('paper_b')          # left lane closed, ego starts in the left lane
    wz = spec.workzone
    s = np.array([0.0, wz.taper_s - 100.0, wz.taper_s + 50.0])
    d = lane_profile(wz, 'left', s)
    assert d[0] == pytest.approx(3.7) and d[1] == pytest.approx(0.0, abs=1e-6)
    assert lane_profile(wz, 'right', s)[1] == pytest.approx(-3.7)


# --- sign mounts ----------------------------------------------------------------------------

def _stand_of(scene, sp):
    """The mast Cylinder under a stand-mounted sign (within 0.1 m of its face, horizontally)."""
    masts = [o for o in scene.objects if isinstance(o, Cylinder) and o.kind == 'stand'
             and np.hypot(*(o.base[:2] - sp.center[:2])) < 0.1]
    assert len(masts) == 1, sp.object_id
    return masts[0]


@pytest.mark.parametrize('name', ['demo', 'paper_c', 'paper_d'])
def test_presets_have_both_mounts(name):
    spec = load_scenario(name)
    scene, _, events = build_scene(spec, 0)
    stands = [sp for sp in scene.signs if sign_mount(sp) == 'stand']
    posts = [sp for sp in scene.signs if sign_mount(sp) == 'post']
    assert posts and {sp.class_key for sp in stands} == {k for k, m in spec.workzone.mounts}
    for sp in stands:
        bottom = sign_bottom(sp)
        assert STAND_BOTTOM_RANGE[0] <= bottom <= STAND_BOTTOM_RANGE[1]
        mast = _stand_of(scene, sp)
        assert mast.base[2] == 0.0 and bottom < mast.height          # reaches the face
        legs = [o for o in scene.objects if isinstance(o, Quad) and o.kind == 'stand_leg'
                and np.hypot(*(o.corners[:, :2].mean(0) - mast.base[:2])) < 0.5]
        assert len(legs) == 2 and min(c[:, 2].min() for c in (g.corners for g in legs)) < 0.01
        # on the right shoulder's edge, not 1.2 m beyond it like a post
        _, d = scene.road.to_frenet(np.array([sp.center[0]]), np.array([sp.center[1]]))
        assert STAND_LATERAL_RANGE[0] - 1e-6 <= d[0] <= STAND_LATERAL_RANGE[1] + 1e-6
        # ... and stays there as the event's sign
        assert any(e.sign_id == sp.object_id for e in events) or \
            sp.class_key == 'other_workzone'


@pytest.mark.parametrize('name', ['paper_a', 'paper_b', 'paper_e'])
def test_other_presets_keep_posts(name):
    scene, _, _ = build_scene(load_scenario(name), 0)
    assert all(sign_mount(sp) == 'post' for sp in scene.signs)
    assert not any(o.kind.startswith('stand') for o in scene.objects)


def test_stands_do_not_move_the_rest_of_the_layout():
    spec = load_scenario('paper_c')
    data = yaml.safe_load(Path(spec.source).read_text())
    posts_only = parse_scenario({**data, 'workzone': {**data['workzone'], 'mounts': {}}},
                                'paper_c')
    a, _, ev_a = build_scene(spec, 3)
    b, _, ev_b = build_scene(posts_only, 3)
    assert [(e.kind, e.x_m, e.value) for e in ev_a] == [(e.kind, e.x_m, e.value) for e in ev_b]
    for sa, sb in zip(a.signs, b.signs):
        assert (sa.class_key, sa.yaw, sa.tilt, sa.fade) == (sb.class_key, sb.yaw, sb.tilt, sb.fade)
        if sign_mount(sa) == 'post':
            assert sa.center.tolist() == sb.center.tolist()
    keep = ('drum', 'cone', 'vehicle', 'truck', 'tree', 'tree_line', 'guardrail', 'overpass')
    def where(scene):
        return [(o.kind, np.round(getattr(o, 'base', getattr(o, 'center', None)), 9).tolist()
                 if not isinstance(o, Quad) else o.corners.round(9).tolist())
                for o in scene.objects if o.kind in keep]
    # Only channelizers that would stand inside a stand's footprint are left out.
    wa, wb = where(a), where(b)
    assert all(w in wb for w in wa)
    stands = [sp for sp in a.signs if sign_mount(sp) == 'stand']
    for kind, pos in (w for w in wb if w not in wa):
        assert kind in ('drum', 'cone')
        assert min(np.hypot(*(np.array(pos[:2]) - sp.center[:2])) for sp in stands) < 1.5


@pytest.mark.parametrize('seed', [3, 1302])
def test_channelizers_keep_clear_of_sign_stands(seed):
    # A drum directly under a low stand-mounted face would interpenetrate the stand's legs.
    scene, _, _ = build_scene(load_scenario('paper_c'), seed)
    stands = [sp for sp in scene.signs if sign_mount(sp) == 'stand']
    assert stands
    for o in scene.objects:
        if o.kind in ('drum', 'cone'):
            for sp in stands:
                assert np.hypot(*(o.base[:2] - sp.center[:2])) >= o.radius + sp.width / 2 + 0.3


def test_random_scenarios_put_warning_signs_on_stands():
    warning = [c.key for c in catalogue.CATALOGUE
               if c.category == 'workzone' and c.shape == 'diamond']
    n = stands = 0
    bottoms = []
    for seed in range(40):
        spec = random_scenario(seed)
        assert spec.workzone.stand_probability == RANDOM_STAND_PROBABILITY
        scene, _, _ = build_scene(spec, seed)
        for sp in scene.signs:
            if sign_mount(sp) == 'stand':
                assert sp.class_key in warning
                _stand_of(scene, sp)
                bottoms.append(sign_bottom(sp))
            if sp.class_key in warning:
                n += 1
                stands += sign_mount(sp) == 'stand'
    assert 0.25 < stands / n < 0.55, (stands, n)
    assert STAND_BOTTOM_RANGE[0] <= min(bottoms) < 0.6 and 1.2 < max(bottoms) <= 1.5
    a, b = build_scene(random_scenario(7), 7), build_scene(random_scenario(7), 7)
    assert [s.center.tolist() for s in a[0].signs] == [s.center.tolist() for s in b[0].signs]


def test_explicit_sign_mounts():
    spec = parse_scenario({'duration': 10, 'signs': [
        {'class': 'road_work_ahead', 's': 100, 'mount': 'stand', 'bottom': 0.3},
        {'class': 'end_road_work', 's': 150, 'mount': 'stand'},
        {'class': 'warning_diamond', 's': 200},
        {'class': 'stop', 's': 250, 'side': 'side_road', 'mount': 'stand', 'bottom': 1.5}]})
    scene, _, _ = build_scene(spec, 0)
    by_key = {sp.class_key: sp for sp in scene.signs}
    assert sign_bottom(by_key['road_work_ahead']) == pytest.approx(0.3)
    assert sign_mount(by_key['end_road_work']) == 'stand'
    assert sign_bottom(by_key['warning_diamond']) == pytest.approx(SIGN_BOTTOM_HEIGHT)
    assert sign_bottom(by_key['stop']) == pytest.approx(1.5)
    _, d = scene.road.to_frenet(np.array([by_key['stop'].center[0]]),
                                np.array([by_key['stop'].center[1]]))
    assert d[0] < SIGN_LATERAL - 3                   # a side-road stand stays on the side road
    for sp in scene.signs:
        if sign_mount(sp) == 'stand':
            _stand_of(scene, sp)


@pytest.mark.parametrize('data, needle', [
    ({'signs': [{'class': 'stop', 's': 10, 'mount': 'pole'}]}, 'mount must be one of'),
    ({'signs': [{'class': 'stop', 's': 10, 'bottom': 0.5}]}, 'bottom is for mount: stand'),
    ({'signs': [{'class': 'stop', 's': 10, 'mount': 'stand', 'bottom': 0.1}]}, 'bottom must'),
    ({'workzone': {'taper_s': 500, 'mounts': {'road_work': 'stand'}}}, 'unknown sign class'),
    ({'workzone': {'taper_s': 500, 'mounts': {'road_work_ahead': 'tripod'}}},
     'road_work_ahead must be one of'),
    ({'workzone': {'taper_s': 500, 'stand_probability': 1.5}}, 'stand_probability'),
])
def test_mount_errors_are_one_line(data, needle):
    with pytest.raises(ScenarioError) as exc:
        parse_scenario(data, 'bad')
    assert needle in str(exc.value) and '\n' not in str(exc.value)
