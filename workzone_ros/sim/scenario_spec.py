"""Scenario YAML: the specification dataclasses, the parser and the scenario library.

:mod:`workzone_ros.sim.scenario` builds the scene from a :class:`ScenarioSpec` (and re-exports
every public name here); the schema is in its module docstring.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Optional

import numpy as np
import yaml

from workzone_ros.core import signs as catalogue
from workzone_ros.sim.lidar import (
    DEFAULT_PRESET,
    LIDAR_PRESETS,
    LidarError,
    LidarModel,
    lidar_preset,
)
from workzone_ros.sim.speed_profile import (
    MPH,
    SlowZone,
    SpeedProfile,
    Stop,
)
from workzone_ros.sim.world import (
    LANE_WIDTH,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
    SIGN_LATERAL,
)

FPS = 15.0
WEATHERS = ('winter_overcast', 'spring_sunny', 'spring_rain', 'dusk')
LANES = ('left', 'middle', 'right')
SIDES = ('right', 'left', 'side_road')
SHIFT_DIRECTIONS = ('left', 'right', 'unknown')
DEFAULT_SPEED = 22.4            # m/s = 50 mph
SPEED_PROFILES = ('constant', 'posted')
DEFAULT_DECEL = 1.2             # m/s^2: a comfortable slow-down
DEFAULT_ACCEL = 1.0             # m/s^2: a comfortable speed-up
#: Share of ``random`` scenarios with a stop-and-go episode (and the posted profile).
RANDOM_STOP_PROBABILITY = 0.25
ADVANCE_DEFAULT = 450.0         # W20-1 distance before the taper (m)
BEGIN_SIGN_LEAD = 40.0          # R22-1 this far before the taper
END_SIGN_LAG = 60.0             # G20-2 this far after the activity area
SHIFT_SIGN_LEAD = 120.0         # W1-4 this far before the shift starts
SHIFT_LENGTH = 80.0             # length of a lane-shift transition
MIN_SIGN_GAP = 30.0             # right-shoulder signs at least this far apart
SIDE_ROAD_LATERAL = SIGN_LATERAL - 11.0
LEFT_SIGN_LATERAL = ROAD_HALF_WIDTH + 1.5 + 1.0
MOUNTS = ('post', 'stand')
#: Face bottom above the ground (m) of a sign on a portable stand: MUTCD minimum 1 ft .. 1.5 m.
STAND_BOTTOM_RANGE = (0.3, 1.5)
#: Lateral offset (m) of a right-shoulder stand: shoulder edge (-8.55) -0.35 .. +0.25 m.
STAND_LATERAL_RANGE = (-(ROAD_HALF_WIDTH + RIGHT_SHOULDER) - 0.35,
                       -(ROAD_HALF_WIDTH + RIGHT_SHOULDER) + 0.25)
#: Chance that an orange work-zone warning diamond stands on a stand in random scenarios.
RANDOM_STAND_PROBABILITY = 0.4
STAND_FLAG_PROBABILITY = 0.35
_GUARDRAIL_D = -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 0.4)      # as build_roadside places them
_GUARDRAIL_TOP = 0.8


class ScenarioError(ValueError):
    """A scenario that cannot be loaded or built; the message is one line naming the key."""


# --- spec dataclasses -----------------------------------------------------------------------

@dataclass(frozen=True)
class LaneShift:
    """A lane shift: a W1-4(L/R) sign, then all lanes move sideways by ``offset`` metres.

    ``at`` is measured from the taper start; ``direction`` is what the sign says
    (``unknown`` = the W1-4 sign without direction); ``move`` is where the lanes go.
    """

    at: float
    direction: str
    offset: float = LANE_WIDTH / 2
    move: Optional[str] = None


@dataclass(frozen=True)
class WorkzoneSpec:
    """One work zone (see the module docstring for the keys)."""

    taper_s: float
    length: float = 500.0
    advance: float = ADVANCE_DEFAULT
    speed_limit: Optional[int] = None
    lane_closed: Optional[str] = None
    taper_length: float = 150.0
    drum_spacing: float = 15.0
    lane_shifts: tuple[LaneShift, ...] = ()
    other_signs: int = 0
    work_vehicles: int = 1
    mounts: tuple[tuple[str, str], ...] = ()       # (class key, 'post' | 'stand')
    stand_probability: float = 0.0

    @property
    def end_s(self) -> float:
        """Arc length of the end of the activity area."""
        return self.taper_s + self.length


@dataclass(frozen=True)
class SignSpec:
    """An explicitly placed sign."""

    class_key: str
    s: float
    side: str = 'right'
    d: Optional[float] = None
    speed_value: Optional[int] = None
    fade: Optional[float] = None
    tilt_deg: Optional[float] = None
    mount: str = 'post'
    bottom: Optional[float] = None                 # stand only: face bottom above ground (m)


@dataclass(frozen=True)
class RoadSpec:
    """Road shape and roadside dressing."""

    curves: tuple[tuple[float, float], ...] = ()
    guardrails: bool = True
    tree_line: bool = True
    overpasses: tuple[float, ...] = ()
    buildings: float = 0.0          # share of roadside stretches with a building front


@dataclass(frozen=True)
class StopAndGo:
    """A standstill in traffic: brake to 0 at arc length ``at``, stand ``stop_s`` seconds."""

    at: float
    stop_s: float = 8.0


@dataclass(frozen=True)
class EgoSpec:
    """Ego lane, speed (cruise, profile, stop-and-go) and motion jitter."""

    speed: float = DEFAULT_SPEED
    lane: str = 'middle'
    start_s: float = 0.0
    jitter: float = 1.0
    speed_profile: str = 'constant'
    decel: float = DEFAULT_DECEL
    accel: float = DEFAULT_ACCEL
    stop_and_go: Optional[StopAndGo] = None


@dataclass(frozen=True)
class DistractorSpec:
    """How many hard negatives to scatter along the route (placed by the seed)."""

    vehicles: int = 3
    orange_vehicles: int = 1
    yellow_vehicles: int = 1
    cones: int = 2
    drums: int = 1
    general_signs: int = 2
    mile_markers: bool = True


@dataclass(frozen=True)
class LidarSpec:
    """Which simulated LiDAR the scenario carries (``lidar:`` in the YAML)."""

    model: str = DEFAULT_PRESET
    max_range: Optional[float] = None              # None: the preset's datasheet range

    def sensor(self) -> LidarModel:
        """The ray caster's sensor model."""
        return lidar_preset(self.model, self.max_range)


@dataclass(frozen=True)
class ScenarioSpec:
    """A validated scenario."""

    name: str
    description: str = ''
    duration: float = 40.0
    weather: str = 'spring_sunny'
    ground_cover: str = 'grass'
    road: RoadSpec = field(default_factory=RoadSpec)
    ego: EgoSpec = field(default_factory=EgoSpec)
    workzone: Optional[WorkzoneSpec] = None
    signs: tuple[SignSpec, ...] = ()
    distractors: DistractorSpec = field(default_factory=DistractorSpec)
    source: str = ''
    lidar: LidarSpec = field(default_factory=LidarSpec)

    @property
    def frames(self) -> int:
        """Camera frames at 15 fps."""
        return int(round(self.duration * FPS))

    def with_overrides(self, duration: Optional[float] = None,
                       speed: Optional[float] = None) -> 'ScenarioSpec':
        """A copy with a shorter/longer duration or another ego speed."""
        out = self
        if duration is not None:
            if not duration > 0:
                raise ScenarioError(f'duration must be > 0, got {duration}')
            out = replace(out, duration=float(duration))
        if speed is not None:
            if not 0 < speed <= 60:
                raise ScenarioError(f'ego speed must be in (0, 60] m/s, got {speed}')
            out = replace(out, ego=replace(out.ego, speed=float(speed)))
        return out


# --- loading --------------------------------------------------------------------------------

def _err(where: str, msg: str) -> ScenarioError:
    return ScenarioError(f'{where}: {msg}')


def _check_keys(d: Any, allowed: tuple[str, ...], where: str) -> dict:
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise _err(where, f'must be a mapping, got {type(d).__name__}')
    unknown = [k for k in d if k not in allowed]
    if unknown:
        raise _err(where, f'unknown key {unknown[0]!r}; allowed: {", ".join(allowed)}')
    return d


def _num(d: dict, key: str, where: str, default, lo=None, hi=None, integer=False,
         allow_none=False):
    v = d.get(key, default)
    if v is None:
        if allow_none or default is None:
            return None
        raise _err(where, f'{key} must be a number, got null')
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _err(where, f'{key} must be a number, got {v!r}')
    if integer and int(v) != v:
        raise _err(where, f'{key} must be an integer, got {v!r}')
    if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
        raise _err(where, f'{key} must be in [{lo}, {hi}], got {v!r}')
    return int(v) if integer else float(v)


def _choice(d: dict, key: str, where: str, default, choices, allow_none=False):
    v = d.get(key, default)
    if v is None and allow_none:
        return None
    if v not in choices:
        raise _err(where, f'{key} must be one of {", ".join(map(str, choices))}, got {v!r}')
    return v


def _bool(d: dict, key: str, where: str, default: bool) -> bool:
    v = d.get(key, default)
    if not isinstance(v, bool):
        raise _err(where, f'{key} must be true or false, got {v!r}')
    return v


def _sign_class(key: Any, where: str) -> str:
    if key == 'background' or not isinstance(key, str):
        raise _err(where, f'unknown sign class {key!r}')
    try:
        catalogue.get(key)
    except catalogue.UnknownSignError:
        raise _err(where, f'unknown sign class {key!r}; known: '
                   f'{", ".join(k for k in catalogue.BY_KEY if k != "background")}') from None
    return key


def _mounts(d: Any, where: str) -> tuple[tuple[str, str], ...]:
    """``workzone.mounts``: a mapping class key -> post | stand."""
    if d is None:
        return ()
    if not isinstance(d, dict):
        raise _err(where, f'mounts must be a mapping class -> post|stand, got {d!r}')
    out = []
    for key, mount in d.items():
        _sign_class(key, f'{where}.mounts')
        if mount not in MOUNTS:
            raise _err(f'{where}.mounts', f'{key} must be one of {", ".join(MOUNTS)}, '
                       f'got {mount!r}')
        out.append((str(key), str(mount)))
    return tuple(sorted(out))


def _duration(top: dict, w: str) -> float:
    """The scenario's length in seconds: ``duration``, or ``frames`` at :data:`FPS`."""
    if 'duration' in top and 'frames' in top:
        raise _err(w, 'give duration or frames, not both')
    if 'frames' in top:
        return _num(top, 'frames', w, None, lo=1, hi=10 ** 6, integer=True) / FPS
    return _num(top, 'duration', w, 40.0, lo=0.1, hi=3600.0)


def _curves(rd: dict, w: str) -> list[tuple[float, float]]:
    """``road.curves``: ``[length_m, curvature]`` segments."""
    curves = []
    for i, seg in enumerate(rd.get('curves') or []):
        if (not isinstance(seg, (list, tuple)) or len(seg) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                           for x in seg)):
            raise _err(f'{w}: road.curves[{i}]', f'must be [length_m, curvature], got {seg!r}')
        if not 0 < seg[0] <= 20000 or abs(seg[1]) > 0.005:
            raise _err(f'{w}: road.curves[{i}]', 'length must be in (0, 20000] m and '
                       f'|curvature| <= 0.005 1/m, got {seg!r}')
        curves.append((float(seg[0]), float(seg[1])))
    return curves


def _road(top: dict, w: str) -> RoadSpec:
    """The ``road`` section."""
    rd = _check_keys(top.get('road'), ('curves', 'guardrails', 'tree_line', 'overpasses',
                                       'buildings'), f'{w}: road')
    curves = _curves(rd, w)
    overpasses = rd.get('overpasses') or []
    if not isinstance(overpasses, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and x >= 0
            for x in overpasses):
        raise _err(f'{w}: road', f'overpasses must be a list of arc lengths, got {overpasses!r}')
    return RoadSpec(tuple(curves), _bool(rd, 'guardrails', f'{w}: road', True),
                    _bool(rd, 'tree_line', f'{w}: road', True),
                    tuple(float(x) for x in overpasses),
                    _num(rd, 'buildings', f'{w}: road', 0.0, lo=0.0, hi=1.0))


def _ego(top: dict, w: str) -> EgoSpec:
    """The ``ego`` section (its stop-and-go episode after the start)."""
    ew = f'{w}: ego'
    eg = _check_keys(top.get('ego'), ('speed', 'lane', 'start_s', 'jitter', 'speed_profile',
                                      'decel', 'accel', 'stop_and_go'), ew)
    stop = None
    if eg.get('stop_and_go') is not None:
        sg = _check_keys(eg['stop_and_go'], ('at', 'stop_s'), f'{ew}.stop_and_go')
        if sg.get('at') is None:
            raise _err(f'{ew}.stop_and_go', 'at (arc length of the standstill, m) is required')
        stop = StopAndGo(_num(sg, 'at', f'{ew}.stop_and_go', None, lo=0.0, hi=1e5),
                         _num(sg, 'stop_s', f'{ew}.stop_and_go', 8.0, lo=0.0, hi=600.0))
    ego = EgoSpec(_num(eg, 'speed', ew, DEFAULT_SPEED, lo=1.0, hi=60.0),
                  _choice(eg, 'lane', ew, 'middle', LANES),
                  _num(eg, 'start_s', ew, 0.0, lo=0.0, hi=1e5),
                  _num(eg, 'jitter', ew, 1.0, lo=0.0, hi=5.0),
                  _choice(eg, 'speed_profile', ew, 'constant', SPEED_PROFILES),
                  _num(eg, 'decel', ew, DEFAULT_DECEL, lo=0.3, hi=5.0),
                  _num(eg, 'accel', ew, DEFAULT_ACCEL, lo=0.3, hi=5.0), stop)
    if stop is not None and stop.at <= ego.start_s:
        raise _err(f'{ew}.stop_and_go', f'at {stop.at} must lie after start_s {ego.start_s}')
    return ego


def _lane_shifts(z: dict, ww: str) -> list[LaneShift]:
    """``workzone.lane_shifts``, in the order given."""
    shifts = []
    raw_shifts = z.get('lane_shifts') or []
    if not isinstance(raw_shifts, list):
        raise _err(ww, f'lane_shifts must be a list, got {raw_shifts!r}')
    for i, sh in enumerate(raw_shifts):
        sw = f'{ww}.lane_shifts[{i}]'
        sh = _check_keys(sh, ('at', 'direction', 'offset', 'move'), sw)
        if 'at' not in sh:
            raise _err(sw, 'at (metres after the taper start) is required')
        shifts.append(LaneShift(_num(sh, 'at', sw, None, lo=-300.0, hi=1e4),
                                _choice(sh, 'direction', sw, 'unknown', SHIFT_DIRECTIONS),
                                _num(sh, 'offset', sw, LANE_WIDTH / 2, lo=0.3, hi=4.0),
                                _choice(sh, 'move', sw, None, ('left', 'right'),
                                        allow_none=True)))
    return shifts


def _workzone(top: dict, w: str) -> Optional[WorkzoneSpec]:
    """The ``workzone`` section (None without one)."""
    if top.get('workzone') is None:
        return None
    ww = f'{w}: workzone'
    z = _check_keys(top['workzone'], ('taper_s', 'length', 'advance', 'speed_limit',
                                      'lane_closed', 'taper_length', 'drum_spacing',
                                      'lane_shifts', 'other_signs', 'work_vehicles',
                                      'mounts', 'stand_probability'), ww)
    if 'taper_s' not in z:
        raise _err(ww, 'taper_s (arc length of the taper start) is required')
    shifts = _lane_shifts(z, ww)
    speed_limit = z.get('speed_limit')
    if speed_limit is not None:
        speed_limit = _num(z, 'speed_limit', ww, None, lo=5, hi=85, integer=True)
        if speed_limit % 5:
            raise _err(ww, f'speed_limit must be a multiple of 5 mph, got {speed_limit}')
    wz = WorkzoneSpec(
        taper_s=_num(z, 'taper_s', ww, None, lo=0.0, hi=1e5),
        length=_num(z, 'length', ww, 500.0, lo=50.0, hi=2e4),
        advance=_num(z, 'advance', ww, ADVANCE_DEFAULT, lo=100.0, hi=2000.0),
        speed_limit=speed_limit,
        lane_closed=_choice(z, 'lane_closed', ww, None, ('left', 'right'), allow_none=True),
        taper_length=_num(z, 'taper_length', ww, 150.0, lo=20.0, hi=400.0),
        drum_spacing=_num(z, 'drum_spacing', ww, 15.0, lo=12.0, hi=20.0),
        lane_shifts=tuple(sorted(shifts, key=lambda x: x.at)),
        other_signs=_num(z, 'other_signs', ww, 0, lo=0, hi=20, integer=True),
        work_vehicles=_num(z, 'work_vehicles', ww, 1, lo=0, hi=10, integer=True),
        mounts=_mounts(z.get('mounts'), ww),
        stand_probability=_num(z, 'stand_probability', ww, 0.0, lo=0.0, hi=1.0))
    if wz.taper_length > wz.length:
        raise _err(ww, f'taper_length {wz.taper_length} exceeds length {wz.length}')
    for sh in wz.lane_shifts:
        if sh.at + SHIFT_LENGTH > wz.length:
            raise _err(ww, f'lane shift at {sh.at} m ends after the activity area '
                       f'({wz.length} m)')
    return wz


def _signs(top: dict, w: str) -> tuple[SignSpec, ...]:
    """The ``signs`` list (signs placed by hand)."""
    raw_signs = top.get('signs') or []
    if not isinstance(raw_signs, list):
        raise _err(w, f'signs must be a list, got {raw_signs!r}')
    sign_specs = []
    for i, sg in enumerate(raw_signs):
        sw = f'{w}: signs[{i}]'
        sg = _check_keys(sg, ('class', 's', 'side', 'd', 'speed_value', 'fade', 'tilt_deg',
                              'mount', 'bottom'), sw)
        if 'class' not in sg or 's' not in sg:
            raise _err(sw, 'class and s are required')
        mount = _choice(sg, 'mount', sw, 'post', MOUNTS)
        bottom = _num(sg, 'bottom', sw, None, lo=STAND_BOTTOM_RANGE[0],
                      hi=STAND_BOTTOM_RANGE[1])
        if bottom is not None and mount != 'stand':
            raise _err(sw, 'bottom is for mount: stand (a post puts the face at 2.1 m)')
        sign_specs.append(SignSpec(
            _sign_class(sg['class'], sw), _num(sg, 's', sw, None, lo=0.0, hi=1e5),
            _choice(sg, 'side', sw, 'right', SIDES), _num(sg, 'd', sw, None, lo=-60, hi=60),
            _num(sg, 'speed_value', sw, None, lo=5, hi=85, integer=True),
            _num(sg, 'fade', sw, None, lo=0.0, hi=1.0),
            _num(sg, 'tilt_deg', sw, None, lo=-15.0, hi=15.0), mount, bottom))
    return tuple(sign_specs)


def _distractors(top: dict, w: str) -> DistractorSpec:
    """The ``distractors`` section (counts)."""
    ds = _check_keys(top.get('distractors'), ('vehicles', 'orange_vehicles', 'yellow_vehicles',
                                             'cones', 'drums', 'general_signs',
                                             'mile_markers'), f'{w}: distractors')
    dw = f'{w}: distractors'
    return DistractorSpec(
        *(_num(ds, k, dw, getattr(DistractorSpec, k), lo=0, hi=200, integer=True)
          for k in ('vehicles', 'orange_vehicles', 'yellow_vehicles', 'cones', 'drums',
                    'general_signs')),
        _bool(ds, 'mile_markers', dw, True))


def _lidar(top: dict, w: str) -> LidarSpec:
    """The ``lidar`` section, checked by building its sensor."""
    lw = f'{w}: lidar'
    ld = _check_keys(top.get('lidar'), ('model', 'max_range'), lw)
    lidar = LidarSpec(_choice(ld, 'model', lw, DEFAULT_PRESET, tuple(LIDAR_PRESETS)),
                      _num(ld, 'max_range', lw, None, lo=5.0, hi=300.0))
    try:
        lidar.sensor()
    except LidarError as exc:
        raise _err(lw, str(exc)) from None
    return lidar


def parse_scenario(data: Any, name: str = 'scenario', source: str = '') -> ScenarioSpec:
    """Validate a scenario mapping (as loaded from YAML).

    Args:
        data: the mapping.
        name: name used when the mapping has no ``name``.
        source: where it came from (for messages).

    Returns:
        The validated spec.

    Raises:
        ScenarioError: unknown keys, unknown sign classes, bad values (one line).
    """
    top = _check_keys(data, ('name', 'description', 'duration', 'frames', 'weather',
                             'ground_cover', 'road', 'ego', 'workzone', 'signs', 'distractors',
                             'lidar'),
                      f'scenario {name}')
    name = str(top.get('name', name))
    w = f'scenario {name}'
    duration = _duration(top, w)
    weather = _choice(top, 'weather', w, 'spring_sunny', WEATHERS)
    cover = _choice(top, 'ground_cover', w, 'snow' if weather.startswith('winter') else 'grass',
                    ('grass', 'dry_grass', 'snow'))
    road = _road(top, w)
    ego = _ego(top, w)
    wz = _workzone(top, w)
    if ego.speed_profile == 'posted' and (wz is None or wz.speed_limit is None):
        raise _err(f'{w}: ego',
                   'speed_profile: posted needs workzone.speed_limit (the limit to slow to)')
    sign_specs = _signs(top, w)
    distractors = _distractors(top, w)
    lidar = _lidar(top, w)
    desc = top.get('description', '')
    if not isinstance(desc, str):
        raise _err(w, f'description must be a string, got {desc!r}')
    return ScenarioSpec(name, ' '.join(desc.split()), float(duration), weather, cover, road,
                        ego, wz, sign_specs, distractors, source, lidar)


def scenario_dir() -> Path:
    """The scenario library: config/scenarios in the source tree or the installed share/."""
    from workzone_ros.resources import config_path
    return config_path('scenarios')


def list_scenarios() -> dict[str, str]:
    """Library scenario names -> descriptions (sorted by name; ``random`` included)."""
    out = {}
    for p in sorted(scenario_dir().glob('*.yaml')):
        try:
            out[p.stem] = load_scenario(p.stem).description
        except ScenarioError as exc:
            out[p.stem] = f'(invalid: {exc})'
    out['random'] = 'a random scenario drawn from the same rules (use --seed N)'
    return dict(sorted(out.items()))


def load_scenario(name_or_path: str, seed: int = 0) -> ScenarioSpec:
    """Load a library scenario by name, ``random`` (drawn from ``seed``) or a YAML path.

    Raises:
        ScenarioError: unknown scenario, unreadable or invalid YAML (one line).
    """
    if name_or_path == 'random':
        return random_scenario(seed)
    path = Path(name_or_path)
    if path.suffix not in ('.yaml', '.yml'):
        path = scenario_dir() / f'{name_or_path}.yaml'
        if not path.is_file():
            known = ', '.join(sorted(p.stem for p in scenario_dir().glob('*.yaml')))
            raise ScenarioError(f'unknown scenario {name_or_path!r}; known: {known}, random '
                                f'(or a path to a .yaml file)')
    if not path.is_file():
        raise ScenarioError(f'scenario file {path} not found')
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ScenarioError(f'cannot read scenario {path}: {" ".join(str(exc).split())}') \
            from None
    return parse_scenario(data, name=path.stem, source=str(path))


def random_scenario(seed: int) -> ScenarioSpec:
    """A random scenario with the same layout rules: events, weather, road, distractors."""
    rng = np.random.default_rng([seed, 0x5eed])
    duration = float(rng.uniform(45.0, 90.0))
    speed = float(rng.choice([20.1, 22.4, 24.6, 26.8]))
    route = duration * speed
    advance = ADVANCE_DEFAULT
    w20_1 = float(rng.uniform(40.0, max(60.0, route * 0.15)))
    taper = w20_1 + advance
    length = float(max(200.0, min(route - taper - 120.0, rng.uniform(300.0, 900.0))))
    closed = rng.choice(['left', 'right', None, None]) if rng.random() < 0.7 else None
    shifts = []
    n_shift = int(rng.integers(0, 3))
    for i in range(n_shift):
        at = float((i + 1) * length / (n_shift + 1)) - SHIFT_LENGTH / 2
        shifts.append({'at': round(at, 1), 'direction': str(rng.choice(SHIFT_DIRECTIONS))})
    curves = []
    total = 0.0
    while total < route + 800:
        seg = float(rng.uniform(200.0, 900.0))
        curves.append([round(seg, 1), float(rng.choice([0.0, 0.0, 1 / 1500, -1 / 1500,
                                                          1 / 900, -1 / 900]))])
        total += seg
    data = {
        'name': f'random_{seed}',
        'description': f'random scenario drawn from seed {seed}',
        'duration': round(duration, 3),
        'weather': str(rng.choice(WEATHERS)),
        'road': {'curves': curves,
                 'overpasses': [round(float(rng.uniform(100, route)), 1)]
                 if rng.random() < 0.5 else []},
        'ego': {'speed': speed, 'lane': str(rng.choice(LANES))},
        'workzone': {'taper_s': round(taper, 1), 'length': round(length, 1),
                     'speed_limit': int(rng.choice([35, 40, 45, 50, 55]))
                     if rng.random() < 0.7 else None,
                     'lane_closed': None if closed is None else str(closed),
                     'taper_length': float(min(150.0, length / 3)),
                     'drum_spacing': float(rng.uniform(12.0, 20.0)),
                     'lane_shifts': shifts, 'other_signs': int(rng.integers(0, 3)),
                     'stand_probability': RANDOM_STAND_PROBABILITY},
        'distractors': {'vehicles': int(rng.integers(1, 6)),
                        'orange_vehicles': int(rng.integers(0, 3)),
                        'yellow_vehicles': int(rng.integers(0, 3)),
                        'cones': int(rng.integers(0, 4)), 'drums': int(rng.integers(0, 3)),
                        'general_signs': int(rng.integers(1, 6))},
    }
    # Roadside dressing from its own generator (the draws above keep their layouts):
    # warm mid-saturation surfaces (dry grass, brick and beige fronts) are the colour
    # model's hard negatives on real roads.
    dress = np.random.default_rng([int(seed), 7701])
    if not data['weather'].startswith('winter') and dress.random() < 0.4:
        data['ground_cover'] = 'dry_grass'
    if dress.random() < 0.5:
        data['road']['buildings'] = round(float(dress.uniform(0.1, 0.5)), 2)
    # Stop-and-go traffic queued at the work zone, from its own generator too (the other
    # seeds keep their scenarios): a standstill between 250 m before the taper and the end
    # of the activity area, the posted limit when there is one, and the duration stretched
    # to the time the slowed ego needs for the same route (an upper bound: the slow zone
    # from W20-1, where the limit sign can stand at the earliest), so it still leaves the zone.
    jam = np.random.default_rng([int(seed), 7704])
    if jam.random() < RANDOM_STOP_PROBABILITY:
        wz = data['workzone']
        at = round(float(jam.uniform(taper - 250.0, taper + length)), 1)
        stop_s = round(float(jam.uniform(3.0, 20.0)), 1)
        data['ego']['stop_and_go'] = {'at': at, 'stop_s': stop_s}
        zones = []
        if wz['speed_limit'] is not None:
            data['ego']['speed_profile'] = 'posted'
            zones.append(SlowZone(w20_1, taper + length + END_SIGN_LAG,
                                  wz['speed_limit'] * MPH))
        slowed = SpeedProfile(0.0, speed, zones, [Stop(at, stop_s)], DEFAULT_DECEL,
                              DEFAULT_ACCEL)
        data['duration'] = round(float(slowed.t_at(route)), 3)
    return parse_scenario(data, name=data['name'], source=f'random:{seed}')


# --- sign mounts ----------------------------------------------------------------------------
