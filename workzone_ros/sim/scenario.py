"""Scenario YAML schema, loader and scene builder for the synthetic highway work zone.

A scenario file (config/scenarios/*.yaml) says *what* happens along the route: the road shape,
the weather, the ego lane and speed, one work zone with its driving-condition changes (speed
limit, lane closure, lane shifts), extra signs and how many hard negatives to scatter.  The
builder turns it into a :class:`~workzone_ros.sim.world.Scene` laid out as MUTCD typical
applications do (advance warning signs on the right shoulder: W20-1 about 450 m before the
taper, then W20-5L/R, W4-2L/R, the work-zone speed limit, W1-4 lane shifts, R22-1; drums
along the taper and the activity area; G20-2 after it), an :class:`EgoTrajectory` that keeps
its lane and follows merges and shifts, and the ground-truth events.

Schema (every key optional except where noted; unknown keys are errors)::

    name: demo                      # default: the file stem
    description: one line           # shown by `workzone-ros synth list`
    duration: 40.0                  # seconds (or `frames:` at 15 fps)
    weather: spring_sunny           # winter_overcast | spring_sunny | spring_rain | dusk
    ground_cover: grass             # grass | dry_grass | snow (default: snow in winter)
    road: {curves: [[length_m, curvature_1_per_m], ...], guardrails: true,
           tree_line: true, overpasses: [s_m, ...],
           buildings: 0.0}          # share of roadside stretches with a building front
    ego: {speed: 22.4, lane: middle, start_s: 0.0, jitter: 1.0,
          speed_profile: constant,  # constant | posted (slow to workzone.speed_limit)
          decel: 1.2, accel: 1.0,   # m/s^2 of every slow-down / speed-up
          stop_and_go: {at: 700, stop_s: 8}}   # standstill at arc length `at` (m)
    workzone: {taper_s: 600, length: 500, advance: 450, speed_limit: 45,
               lane_closed: left|right|null, taper_length: 150, drum_spacing: 15,
               lane_shifts: [{at: 200, direction: left|right|unknown, offset: 1.85}],
               other_signs: 1, work_vehicles: 1,
               mounts: {road_work_ahead: stand},   # class key -> post | stand
               stand_probability: 0.0}             # other orange warning diamonds
    signs: [{class: stop, s: 300, side: right|left|side_road, d: null, speed_value: null,
             fade: null, tilt_deg: null, mount: post|stand, bottom: null}]
    distractors: {vehicles: 4, orange_vehicles: 1, yellow_vehicles: 1, cones: 2, drums: 1,
                  general_signs: 3, mile_markers: true}
    lidar: {model: hdl64,           # hdl64 | hdl32 | vlp16 (sim/lidar.py LIDAR_PRESETS)
            max_range: null}        # metres (null: the preset's datasheet range)

Positions are arc lengths ``s`` (m) along the route; the ego starts at ``ego.start_s`` and,
with ``speed_profile: constant`` (the default) and no ``stop_and_go``, drives at constant
speed, so an event at ``s`` happens at ``t = (s - start_s) / speed``.  ``speed_profile:
posted`` brakes at ``decel`` from the work-zone speed limit sign down to ``speed_limit`` mph
(needs ``workzone.speed_limit``) and accelerates at ``accel`` back to ``speed`` from the END
ROAD WORK sign; ``stop_and_go`` brakes to a standstill at arc length ``at``, stands ``stop_s``
seconds and drives on (sim/speed_profile.py).  Either way ``EgoTrajectory.t_at(s)`` is the
first time the ego reaches ``s`` and every event's ``t`` comes from it.  ``random`` scenarios
draw a stop-and-go (with the posted profile) on about a quarter of the seeds, from their own
generator: the other seeds keep their scenarios.

Sign mounts.  ``post`` (default): a fixed post, the face's bottom
:data:`~workzone_ros.sim.world.SIGN_BOTTOM_HEIGHT` = 2.1 m above the road (MUTCD 2009,
Section 2A.18: 7 ft).  ``stand``: a portable sign stand as on real work zones (Section 6F.03
allows 1 ft = 0.3 m for temporary signs on portable supports): the face's bottom
:data:`STAND_BOTTOM_RANGE` 0.3-1.5 m above the ground (``bottom:`` or drawn per sign), a thin
mast behind the face and two splayed legs, and on some stands two small orange flags above
the face.  A right-shoulder stand stands on the shoulder edge or slightly beyond
(:data:`STAND_LATERAL_RANGE`) instead of 1.2 m past it, pulled in so a low face clears the
guardrail line.  Work-zone signs the builder places (W20-1, W20-5, W4-2, W1-4, R22-1, ...)
take their mount from ``workzone.mounts`` by class key; the other orange warning diamonds go
on a stand with probability ``workzone.stand_probability`` (0 in the presets, 0.4 in
``random`` scenarios).  Mount draws and stand heights come from their own generator, so a
stand never moves anything else in the layout.  :func:`sign_mount` tells a built sign's mount.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.interfaces import GtEvent
from workzone_ros.sim.scenario_spec import (  # noqa: F401 - re-exported
    _GUARDRAIL_D,
    _GUARDRAIL_TOP,
    ADVANCE_DEFAULT,
    BEGIN_SIGN_LEAD,
    END_SIGN_LAG,
    FPS,
    LANES,
    LEFT_SIGN_LATERAL,
    MIN_SIGN_GAP,
    MOUNTS,
    RANDOM_STAND_PROBABILITY,
    RANDOM_STOP_PROBABILITY,
    SHIFT_LENGTH,
    SHIFT_SIGN_LEAD,
    SIDE_ROAD_LATERAL,
    SPEED_PROFILES,
    STAND_BOTTOM_RANGE,
    STAND_FLAG_PROBABILITY,
    STAND_LATERAL_RANGE,
    WEATHERS,
    DistractorSpec,
    EgoSpec,
    LaneShift,
    LidarSpec,
    RoadSpec,
    ScenarioError,
    ScenarioSpec,
    SignSpec,
    StopAndGo,
    WorkzoneSpec,
    list_scenarios,
    load_scenario,
    parse_scenario,
    random_scenario,
    scenario_dir,
)
from workzone_ros.sim.sign_mounts import STAND_FOOT, sign_bottom, sign_mount, stand_parts
from workzone_ros.sim.speed_profile import (
    MPH,
    SlowZone,
    SpeedProfile,
    SpeedProfileError,
    Stop,
)
from workzone_ros.sim.trajectory import (
    EgoTrajectory,
    LaneVehicle,
    _merge_target,
    lane_profile,
    lateral_offset,
)
from workzone_ros.sim.world import (
    LANE_WIDTH,
    LEFT_SHOULDER,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
    SIGN_BOTTOM_HEIGHT,
    SIGN_LATERAL,
    Cone,
    Cylinder,
    Quad,
    Road,
    Scene,
    SignPanel,
)

__all__ = [
    'ScenarioError', 'FPS', 'WEATHERS', 'LaneShift', 'WorkzoneSpec', 'SignSpec', 'RoadSpec',
    'EgoSpec', 'StopAndGo', 'DistractorSpec', 'LidarSpec', 'ScenarioSpec', 'EgoTrajectory',
    'LaneVehicle',
    'scenario_dir', 'list_scenarios', 'load_scenario', 'parse_scenario', 'random_scenario',
    'build_scene', 'lateral_offset', 'MOUNTS', 'STAND_BOTTOM_RANGE', 'STAND_LATERAL_RANGE',
    'RANDOM_STAND_PROBABILITY', 'sign_bottom', 'sign_mount', 'stand_parts', 'SPEED_PROFILES',
    'RANDOM_STOP_PROBABILITY', 'ADVANCE_DEFAULT', 'lane_profile', 'STAND_FOOT',
]


# --- scene building -------------------------------------------------------------------------

@dataclass
class _Placed:
    class_key: str
    s: float
    d: float
    role: str = ''                      # 'advance', 'begin', 'end', 'shift', ...
    speed_value: Optional[int] = None
    fade: Optional[float] = None
    tilt_deg: Optional[float] = None
    event: Optional[tuple[str, Any]] = None
    mount: Optional[str] = None         # None: the work zone's mounts / stand probability
    bottom: Optional[float] = None


class _Builder:
    def __init__(self, spec: ScenarioSpec, seed: int):
        self.spec = spec
        self.seed = int(seed)
        self.rng = np.random.default_rng([self.seed, zlib.crc32(spec.name.encode())])
        # mounts draw from their own stream: a stand never moves anything else
        self.mount_rng = np.random.default_rng([self.seed, zlib.crc32(spec.name.encode()),
                                                0x57a4d])
        self.ego_end_s = spec.ego.start_s + spec.ego.speed * spec.duration
        need = self.ego_end_s + 700.0
        wz = spec.workzone
        if wz is not None:
            need = max(need, wz.end_s + END_SIGN_LAG + 200.0)
        need = max(need, max((sg.s for sg in spec.signs), default=0.0) + 100.0)
        curves = list(spec.road.curves)
        have = sum(L for L, _ in curves)
        if have < need:
            curves.append((need - have, 0.0))
        self.road = Road(curves)
        self.objects: list = []
        self.signs: list[SignPanel] = []
        self._next_id = 1

    def new_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    # signs ------------------------------------------------------------------------------
    def plan_signs(self) -> list[_Placed]:
        spec, wz, rng = self.spec, self.spec.workzone, self.rng
        right: list[_Placed] = []
        other: list[_Placed] = []
        if wz is not None:
            t = wz.taper_s
            right.append(_Placed('road_work_ahead', t - wz.advance, SIGN_LATERAL, 'advance',
                                 event=('zone_approaching', None)))
            seq: list[_Placed] = []
            if wz.lane_closed:
                side = wz.lane_closed
                seq.append(_Placed(f'{side}_lane_closed_ahead', 0, SIGN_LATERAL, 'advance',
                                   event=('lane_closed', side)))
                seq.append(_Placed(f'{side}_lane_ends', 0, SIGN_LATERAL, 'advance',
                                   event=('lane_closed', side)))
            if wz.speed_limit is not None:
                seq.append(_Placed('work_zone_speed_limit', 0, SIGN_LATERAL, 'advance',
                                   speed_value=wz.speed_limit,
                                   event=('speed_limit', wz.speed_limit)))
            first = t - wz.advance
            last = t - BEGIN_SIGN_LEAD - MIN_SIGN_GAP
            for i, p in enumerate(seq):
                p.s = first + (i + 1) * (last - first) / (len(seq) + 1) \
                    + float(rng.uniform(-8, 8))
            right += seq
            for sh in wz.lane_shifts:
                key = {'left': 'lane_shift_left', 'right': 'lane_shift_right',
                       'unknown': 'lane_shift'}[sh.direction]
                right.append(_Placed(key, t + sh.at - SHIFT_SIGN_LEAD, SIGN_LATERAL, 'shift',
                                     event=('lane_shift', sh.direction)))
            right.append(_Placed('work_zone_begin', t - BEGIN_SIGN_LEAD, SIGN_LATERAL, 'begin',
                                 event=('zone_begin', None)))
            for _ in range(wz.other_signs):
                right.append(_Placed('other_workzone', float(rng.uniform(
                    t + 20.0, wz.end_s - 20.0)), SIGN_LATERAL, 'inside'))
            right.append(_Placed('end_road_work', wz.end_s + END_SIGN_LAG, SIGN_LATERAL, 'end',
                                 event=('zone_end', None)))
            # speed limit resumes after the zone (a general white sign)
            right.append(_Placed('speed_limit', wz.end_s + END_SIGN_LAG + 150.0, SIGN_LATERAL,
                                 'general', speed_value=65))
        for sg in spec.signs:
            d = sg.d if sg.d is not None else {'right': SIGN_LATERAL,
                                                'left': LEFT_SIGN_LATERAL,
                                                'side_road': SIDE_ROAD_LATERAL}[sg.side]
            p = _Placed(sg.class_key, sg.s, d, 'explicit', sg.speed_value, sg.fade, sg.tilt_deg,
                        mount=sg.mount, bottom=sg.bottom)
            (right if sg.side == 'right' and sg.d is None else other).append(p)
        # random general signs (hard negatives) and mile markers, outside the sign sequence
        gen_keys = ('warning_diamond', 'speed_limit', 'guide', 'stop', 'yield', 'do_not_enter')
        lo, hi = spec.ego.start_s + 60.0, self.ego_end_s + 100.0
        for _ in range(spec.distractors.general_signs):
            key = str(rng.choice(gen_keys))
            s = float(rng.uniform(lo, hi))
            if key in ('stop', 'yield', 'do_not_enter'):
                other.append(_Placed(key, s, SIDE_ROAD_LATERAL + float(rng.uniform(-3, 2)),
                                     'general'))
            else:
                right.append(_Placed(key, s, SIGN_LATERAL, 'general',
                                     speed_value=int(rng.choice([55, 60, 65, 70]))
                                     if key == 'speed_limit' else None))
        if spec.distractors.mile_markers:
            step = 1609.344 / 2
            s = step * math.ceil((spec.ego.start_s + 50.0) / step)
            while s < hi:
                other.append(_Placed('mile_marker', s, SIGN_LATERAL + 1.0, 'general'))
                s += step
        # keep right-shoulder signs apart: work-zone signs keep their order and push each
        # other along; explicitly placed signs stay where the file says; random ones yield
        right.sort(key=lambda p: (p.s, p.role == 'general'))
        zone = [p for p in right if p.role not in ('general', 'explicit')]
        for a, b in zip(zone, zone[1:]):
            if b.s - a.s < MIN_SIGN_GAP:
                b.s = a.s + MIN_SIGN_GAP
        kept = zone + [p for p in right if p.role == 'explicit']
        for p in (p for p in right if p.role == 'general'):
            if all(abs(p.s - q.s) >= MIN_SIGN_GAP for q in kept):
                kept.append(p)
        return sorted(kept + other, key=lambda p: (p.s, p.d))

    def mount_of(self, p: _Placed, c: catalogue.SignClass, w: float, h: float
                 ) -> tuple[str, float, float, bool]:
        """``(mount, face bottom, lateral offset, flags)`` of a planned sign (module docstring).

        Four draws from the mount generator per sign whatever the outcome, so one sign's
        mount never changes another's.
        """
        u_mount, u_bottom, u_lat, u_flags = (float(v) for v in self.mount_rng.random(4))
        wz = self.spec.workzone
        mount = p.mount
        if mount is None:
            mounts = dict(wz.mounts) if wz is not None else {}
            warning = c.category == 'workzone' and c.shape == 'diamond'
            mount = mounts.get(p.class_key) or (
                'stand' if warning and wz is not None and u_mount < wz.stand_probability
                else 'post')
        if mount == 'post':
            return 'post', SIGN_BOTTOM_HEIGHT, p.d, False
        lo, hi = STAND_BOTTOM_RANGE
        bottom = p.bottom if p.bottom is not None else lo + (hi - lo) * u_bottom
        d = p.d
        if p.d == SIGN_LATERAL:                        # right shoulder: on its edge
            lo, hi = STAND_LATERAL_RANGE
            d = lo + (hi - lo) * u_lat
            # keep the face and the legs on the road side of a guardrail line
            y = min(max(_GUARDRAIL_TOP + 0.05 - bottom, 0.0), h)
            reach = (min(y, h / 2) * w / h) if c.shape == 'diamond' else (w / 2 if y else 0.0)
            d = max(d, _GUARDRAIL_D + 0.05 + max(reach, STAND_FOOT))
        return 'stand', float(bottom), float(d), u_flags < STAND_FLAG_PROBABILITY

    def add_sign(self, p: _Placed) -> SignPanel:
        c = catalogue.get(p.class_key)
        rng = self.rng
        if c.shape == 'diamond':
            w = h = c.width_m * math.sqrt(2.0)
        else:
            w, h = c.width_m, c.height_m
        x, y, heading = self.road.pose_at(p.s, p.d)
        jitter = math.radians(float(rng.uniform(-4.0, 4.0)))
        if p.d < SIGN_LATERAL - 3:                        # side road: turned a bit more
            jitter += math.radians(float(rng.uniform(-15.0, 15.0)))
        yaw = float(heading) + math.pi + jitter
        tilt = math.radians(p.tilt_deg) if p.tilt_deg is not None else (
            math.radians(float(rng.uniform(-3.0, 3.0))) if rng.random() < 0.25 else 0.0)
        fade = p.fade if p.fade is not None else (
            float(rng.uniform(0.1, 0.45)) if rng.random() < 0.2 else 0.0)
        mount, bottom, d_stand, flags = self.mount_of(p, c, w, h)
        if mount == 'stand' and d_stand != p.d:          # stands on the shoulder edge
            x, y, _ = self.road.pose_at(p.s, d_stand)
        center = np.array([float(x), float(y), bottom + h / 2])
        speed_value = p.speed_value
        if speed_value is None and p.class_key == 'work_zone_speed_limit':
            speed_value = 45
        if speed_value is None and p.class_key == 'speed_limit':
            speed_value = 65
        panel = SignPanel(self.new_id(), p.class_key, center, yaw, w, h, tilt, fade,
                          speed_value)
        self.signs.append(panel)
        if mount == 'stand':
            self.objects += stand_parts(panel, flags, self.new_id)
            return panel
        # posts behind the face; guide signs stand on two
        back = -panel.normal * 0.06
        offsets = [-w * 0.33, w * 0.33] if w > 2.0 else [0.0]
        right = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
        for o in offsets:
            base = center + back + right * o
            base[2] = 0.0
            self.objects.append(Cylinder(self.new_id(), 'post', base, 0.05 if w <= 2.0 else 0.08,
                                         SIGN_BOTTOM_HEIGHT + h * 0.85, 'post'))
        return panel

    # objects -----------------------------------------------------------------------------
    def world(self, s: float, d: float, z: float = 0.0) -> np.ndarray:
        x, y, _ = self.road.pose_at(s, d)
        return np.array([float(x), float(y), z])

    def clear_of_signs(self, pos: np.ndarray, radius: float) -> bool:
        """A channelizer at ``pos`` stays clear of sign mounts (nothing interpenetrates).

        Posts need ``radius`` + 0.2 m; a portable stand's legs and low face need ``radius``
        + the face's half width + 0.3 m (crews set a stand beside the drum line, not in it).
        """
        for sg in self.signs:
            if sign_mount(sg) == 'stand':
                need = radius + 0.5 * float(sg.width) + 0.3
            else:
                need = radius + 0.2
            if math.hypot(*(pos[:2] - np.asarray(sg.center)[:2])) < need:
                return False
        return True

    def drum(self, s: float, d: float) -> None:
        if not self.clear_of_signs(self.world(s, d), 0.29):
            return
        self.objects.append(Cylinder(
            self.new_id(), 'drum', self.world(s, d), 0.29, 0.95, 'drum_orange',
            [(0.18, 0.30, 'drum_band'), (0.42, 0.54, 'drum_band'), (0.66, 0.78, 'drum_band')]))

    def cone(self, s: float, d: float) -> None:
        if not self.clear_of_signs(self.world(s, d), 0.18):
            return
        self.objects.append(Cone(self.new_id(), 'cone', self.world(s, d), 0.18, 0.71,
                                 'cone_orange', [(0.40, 0.52, 'drum_band')]))

    def vehicle(self, kind: str, material: str, lane: str, s0: float, speed: float,
                rear: Optional[str] = None) -> None:
        length, width, height = {'car': (4.6, 1.85, 1.5), 'van': (5.5, 2.0, 2.3),
                                 'truck': (8.5, 2.5, 3.2)}[kind]
        grid = self.s_grid
        d_grid = lane_profile(self.spec.workzone, lane, grid) if lane in LANES \
            else np.full_like(grid, float(lane))
        x, y, h = self.road.pose_at(s0, float(np.interp(s0, grid, d_grid)))
        v = LaneVehicle(self.new_id(), 'truck' if kind == 'truck' else 'vehicle',
                        np.array([float(x), float(y), 0.0]), length, width, height, float(h),
                        material, speed, True, rear, road=self.road, s0=s0, s_grid=grid,
                        d_grid=d_grid)
        self.objects.append(v)

    def build_workzone(self) -> None:
        wz, rng = self.spec.workzone, self.rng
        if wz is None:
            return
        t = wz.taper_s
        taper_sp, tangent_sp = wz.drum_spacing * 0.8, wz.drum_spacing * 1.2
        off = lambda s: float(lateral_offset(wz, np.array([s]))[0])  # noqa: E731
        edge = ROAD_HALF_WIDTH
        if wz.lane_closed:
            sign = -1.0 if wz.lane_closed == 'right' else 1.0
            d_start, d_line = sign * (edge - 0.3), sign * (LANE_WIDTH / 2 + 0.35)
        else:                                              # shoulder closure
            sign = -1.0
            d_start, d_line = -(edge + RIGHT_SHOULDER - 0.4), -(edge + 0.45)
        s = t
        while s < t + wz.taper_length:                     # merging / shoulder taper
            f = (s - t) / wz.taper_length
            self.drum(s, d_start + (d_line - d_start) * f + off(s))
            s += taper_sp
        down = min(40.0, wz.length * 0.1)
        while s < wz.end_s - down:                         # tangent along the activity area
            self.drum(s, d_line + float(rng.uniform(-0.08, 0.08)) + off(s))
            s += tangent_sp
        while s <= wz.end_s:                               # downstream taper
            f = (s - (wz.end_s - down)) / max(down, 1.0)
            self.drum(s, d_line + (d_start - d_line) * f + off(s))
            s += taper_sp
        # work vehicles (orange trucks, static) and cone clusters in the closed area
        work_d = (sign * LANE_WIDTH if wz.lane_closed else -(edge + RIGHT_SHOULDER / 2))
        for i in range(wz.work_vehicles):
            s0 = t + wz.taper_length + (i + 0.5) * (wz.length - wz.taper_length) \
                / max(wz.work_vehicles, 1)
            self.vehicle('truck', 'vehicle_orange', str(work_d + off(s0)), s0, 0.0,
                         'vehicle_orange')
            for k in range(3):
                self.cone(s0 - 12.0 - 3.0 * k, work_d + off(s0) + float(rng.uniform(-0.8, 0.8)))

    def build_distractors(self) -> None:
        spec, rng = self.spec, self.rng
        ds, wz = spec.distractors, spec.workzone
        v_ego, s_ego, dur = spec.ego.speed, spec.ego.start_s, spec.duration
        ego = self.ego
        closed = wz.lane_closed if wz else None
        ego_lanes = {spec.ego.lane, _merge_target(spec.ego.lane, closed) or spec.ego.lane}
        other = [ln for ln in LANES if ln not in ego_lanes and ln != closed]
        same = [ln for ln in ego_lanes if ln != closed]

        placed: list[tuple[str, float, float, float]] = []    # lane, s0, speed, length
        times = np.linspace(0.0, dur, 60)
        lengths = {'car': 4.6, 'van': 5.5, 'truck': 8.5}

        def place(kind: str, material: str, rear: Optional[str]) -> None:
            for _ in range(20):                            # keep same-lane vehicles apart
                if other and (not same or rng.random() < 0.7):
                    lane = str(rng.choice(other))
                    dv = float(rng.uniform(2.0, 7.0)) * (1 if rng.random() < 0.3 else -1)
                    tm = float(rng.uniform(3.0, max(4.0, dur - 3.0)))  # alongside at tm
                    s0 = max(s_ego - dv * tm, 1.0) if ego.profile is None else \
                        max(float(ego.s(tm)) - (v_ego + dv) * tm, 1.0)
                else:                                      # ego's lane: faster, ahead
                    lane = str(rng.choice(same))
                    dv = float(rng.uniform(0.5, 3.0))
                    s0 = s_ego + float(rng.uniform(25.0, 120.0))
                v, length = v_ego + dv, lengths[kind]
                if all(ln != lane or np.abs((s0 + v * times) - (s1 + v1 * times)).min()
                       > (length + l1) / 2 + 8.0 for ln, s1, v1, l1 in placed):
                    placed.append((lane, s0, v, length))
                    self.vehicle(kind, material, lane, s0, v, rear)
                    return

        for _ in range(ds.vehicles):
            place(str(rng.choice(['car', 'car', 'van', 'truck'])), 'vehicle_paint', None)
        for _ in range(ds.orange_vehicles):
            place(str(rng.choice(['truck', 'van'])), 'vehicle_orange', 'vehicle_orange')
        for _ in range(ds.yellow_vehicles):
            place(str(rng.choice(['car', 'van', 'truck'])), 'vehicle_yellow', 'vehicle_yellow')
        lo, hi = s_ego + 40.0, self.ego_end_s + 100.0
        for _ in range(ds.cones):                          # cone clusters on the shoulder
            s0 = float(rng.uniform(lo, hi))
            for k in range(int(rng.integers(2, 5))):
                self.cone(s0 + 2.5 * k, -(ROAD_HALF_WIDTH + float(rng.uniform(0.8, 2.5))))
        for _ in range(ds.drums):                          # stray drums on the shoulder
            self.drum(float(rng.uniform(lo, hi)),
                      -(ROAD_HALF_WIDTH + float(rng.uniform(1.0, 2.6))))

    def build_roadside(self) -> None:
        spec, rng, road = self.spec, self.rng, self.road
        lo, hi = max(0.0, spec.ego.start_s - 50.0), min(road.length, self.ego_end_s + 600.0)
        if spec.road.tree_line:
            for side in (1.0, -1.0):
                s = lo
                while s < hi:
                    seg = float(rng.uniform(25.0, 45.0))
                    if rng.random() < 0.85:
                        d = side * float(rng.uniform(26.0, 34.0))
                        top = float(rng.uniform(7.0, 14.0))
                        a, b = self.world(s, d), self.world(s + seg, d)
                        corners = np.array([a + [0, 0, top], b + [0, 0, top], b, a]) if \
                            side < 0 else np.array([b + [0, 0, top], a + [0, 0, top], a, b])
                        self.objects.append(Quad(self.new_id(), 'tree_line', corners, 'tree'))
                    s += seg
            for _ in range(int((hi - lo) / 60.0)):           # single conifers nearer the road
                side = 1.0 if rng.random() < 0.4 else -1.0
                d = side * float(rng.uniform(14.0, 24.0))
                self.objects.append(Cone(self.new_id(), 'tree',
                                         self.world(float(rng.uniform(lo, hi)), d),
                                         float(rng.uniform(1.5, 2.8)),
                                         float(rng.uniform(6.0, 11.0)), 'tree'))
        if spec.road.buildings > 0:
            self.build_buildings(lo, hi)
        if spec.road.guardrails:
            s = lo + float(rng.uniform(50.0, 300.0))
            while s < hi:
                run = float(rng.uniform(120.0, 400.0))
                d = -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 0.4)
                for a in np.arange(s, min(s + run, hi), 20.0):
                    p, q = self.world(float(a), d), self.world(float(a) + 20.0, d)
                    self.objects.append(Quad(self.new_id(), 'guardrail', np.array(
                        [q + [0, 0, 0.8], p + [0, 0, 0.8], p + [0, 0, 0.45], q + [0, 0, 0.45]]),
                        'guardrail'))
                s += run + float(rng.uniform(300.0, 900.0))
        for so in spec.road.overpasses:                 # same geometry the camera draws
            for s1, d0, d1, z0, z1 in (
                    (so - 6.0, -45.0, 45.0, 5.4, 7.2),
                    (so - 5.5, -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 1.5),
                     -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 0.5), 0.0, 5.4),
                    (so - 5.5, ROAD_HALF_WIDTH + LEFT_SHOULDER + 0.5,
                     ROAD_HALF_WIDTH + LEFT_SHOULDER + 1.5, 0.0, 5.4)):
                a, b = self.world(s1, d1), self.world(s1, d0)
                self.objects.append(Quad(self.new_id(), 'overpass', np.array(
                    [a + [0, 0, z1], b + [0, 0, z1], b + [0, 0, z0], a + [0, 0, z0]]),
                    'concrete'))

    def build_buildings(self, lo: float, hi: float) -> None:
        """Building fronts (brick, beige and tan siding) facing the road, 14-24 m out, on a
        share ``road.buildings`` of 30-60 m stretches; own generator (other draws unchanged)."""
        rng = np.random.default_rng([self.seed, 7702])
        mats = ('brick', 'siding_beige', 'siding_tan')
        for side in (1.0, -1.0):
            s = lo
            while s < hi:
                seg = float(rng.uniform(30.0, 60.0))
                if rng.random() < self.spec.road.buildings:
                    width = float(rng.uniform(8.0, min(20.0, seg)))
                    d = side * float(rng.uniform(14.0, 24.0))
                    top = float(rng.uniform(4.0, 9.0))
                    s0 = s + float(rng.uniform(0.0, seg - width))
                    a, b = self.world(s0, d), self.world(s0 + width, d)
                    corners = np.array([a + [0, 0, top], b + [0, 0, top], b, a]) if \
                        side < 0 else np.array([b + [0, 0, top], a + [0, 0, top], a, b])
                    self.objects.append(Quad(self.new_id(), 'building', corners,
                                             str(rng.choice(mats))))
                s += seg

    def speed_profile(self, plan: list[_Placed]) -> Optional[SpeedProfile]:
        """The ego's slow-down (posted limit sign .. END ROAD WORK) and stop, or None."""
        eg, wz = self.spec.ego, self.spec.workzone
        zones, stops = [], []
        if eg.speed_profile == 'posted' and wz is not None and wz.speed_limit is not None:
            at = {p.event[0]: p.s for p in reversed(plan) if p.event is not None}
            zones.append(SlowZone(at['speed_limit'], at['zone_end'], wz.speed_limit * MPH))
        if eg.stop_and_go is not None:
            stops.append(Stop(eg.stop_and_go.at, eg.stop_and_go.stop_s))
        if not zones and not stops:
            return None
        try:
            return SpeedProfile(eg.start_s, eg.speed, zones, stops, eg.decel, eg.accel)
        except SpeedProfileError as exc:
            raise ScenarioError(f'scenario {self.spec.name}: ego: {exc}') from None

    def build(self) -> tuple[Scene, EgoTrajectory, list[GtEvent]]:
        spec = self.spec
        self.s_grid = np.arange(0.0, self.road.length + 1.0, 1.0)
        ego_d = lane_profile(spec.workzone, spec.ego.lane, self.s_grid)
        plan = self.plan_signs()              # the profile brakes at the signs it plans
        ego = EgoTrajectory(self.road, spec.ego.speed, spec.ego.start_s, self.s_grid, ego_d,
                            spec.ego.jitter, self.seed, self.speed_profile(plan))
        self.ego = ego
        events = []
        for p in plan:
            panel = self.add_sign(p)
            if p.event is not None:
                kind, value = p.event
                events.append(GtEvent(kind=kind, t=round(float(ego.t_at(p.s)), 6),
                                      x_m=round(p.s, 3), value=value,
                                      sign_id=panel.object_id))
        self.build_workzone()
        self.build_distractors()
        self.build_roadside()
        scene = Scene(spec.name, self.seed, self.road, self.signs, self.objects, spec.weather,
                      spec.ground_cover, list(spec.road.overpasses))
        return scene, ego, sorted(events, key=lambda e: (e.x_m, e.kind))


def build_scene(spec: ScenarioSpec, seed: int = 0
                ) -> tuple[Scene, EgoTrajectory, list[GtEvent]]:
    """Lay out the world of ``spec``.

    Args:
        spec: a validated scenario.
        seed: placement jitter, fades, distractor positions and ego jitter phases.

    Returns:
        ``(scene, ego, events)``: the world, the ego trajectory and the ground-truth events
        (zone approaching / begin / end, speed limit, lane shift, lane closed; ``t`` is the
        time the ego passes the sign, ``x_m`` its arc length), sorted along the route.

    Raises:
        ScenarioError: a layout that does not fit (e.g. a sign before the road start).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ScenarioError(f'seed must be a non-negative integer, got {seed!r}')
    if spec.workzone is not None and spec.workzone.taper_s - spec.workzone.advance < 0:
        raise ScenarioError(f'scenario {spec.name}: workzone.taper_s {spec.workzone.taper_s} '
                            f'leaves no room for the W20-1 sign {spec.workzone.advance} m '
                            'before it')
    return _Builder(spec, int(seed)).build()
