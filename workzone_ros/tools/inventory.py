"""``workzone-ros inventory``: a highway sign inventory from bags (after Balali and
Golparvar-Fard).

Usage::

    workzone-ros inventory BAG [BAG ...] -o signs.csv [--geojson signs.geojson]
        [--crops DIR] [--no-lidar] [--no-general] [--general-every N] [--min-frames N]
        [--config YAML] [--color-model NPZ] [--classifier-model NPZ] [--score] [--json OUT]

Each bag runs the perception chain of ``evaluate workzone --signs pipeline`` in process
(:class:`workzone_ros.tools.workzone_pipeline.PipelineSource`: colour detector, mean-shift
tracker, sign classifier, general signs) on every camera frame; when the bag has
``/lidar/points`` the ``lidar_cluster`` chain runs too (:class:`~workzone_ros.core.lidar_stream.
LidarStream`, the node's parameters from ``--config``) and each image's candidates are
projected as the projector does (nearest scan in time, ego-motion compensated with
``/odom``).  :mod:`workzone_ros.core.inventory` turns the sightings into physical signs (one
row each) in the odometry frame; bags of the same road (one odometry frame) are merged.

Columns of the CSV: ``sign_id, class_key, category, first_seen_s, last_seen_s, frames, x_m,
y_m, z_m, position_source, best_crop, mile, sigma_m, bags`` (``position_source``: ``lidar``,
``camera`` or ``none`` without odometry; ``sigma_m`` the position's standard deviation;
``bags`` the bag names, ``;``-separated).  ``--geojson`` writes the same rows as Point
features in odometry metres (not WGS84).  ``--crops DIR`` writes each sign's best crop as
PNG.

``--score`` (synthetic bags, ``workzone-ros synth``) compares the rows with the ground
truth: every ground-truth sign legible in some frame (shorter box side >= 12 px, half
visible) should be one row (found once / duplicated / missed), rows matching no sign are
false; a row's sign is the one most of its sightings overlap (IoU >= 0.3); position error
against the face centre (``/groundtruth/lidar`` with odometry, else the GT boxes and
distances); wall time per bag.  A missing or corrupt bag, or a bag without camera, is a
one-line error (exit 2; the other bags are still inventoried).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Optional

import numpy as np

from workzone_ros.bagio import BagError
from workzone_ros.core.inventory import (
    InventoryConfig,
    Located,
    PhysicalSign,
    Sighting,
    build_inventory,
    camera_in_base,
    camera_ray,
    locate,
    match_candidate,
)
from workzone_ros.interfaces import (
    GtLidar,
    GtSigns,
    GtWorkzone,
    Header,
    PayloadError,
    Time,
    decode,
)

__all__ = ['main', 'InventoryOptions', 'InventoryError', 'BagRun', 'run_bag', 'run_inventory',
           'score', 'write_csv', 'write_geojson', 'COLUMNS']

COLUMNS = ('sign_id', 'class_key', 'category', 'first_seen_s', 'last_seen_s', 'frames', 'x_m',
           'y_m', 'z_m', 'position_source', 'best_crop', 'mile', 'sigma_m', 'bags')
IMAGE_TOPICS = ('/camera/image_raw', '/camera/image_raw/compressed')
INFO_TOPIC = '/camera/camera_info'
LEGIBLE_PX = 12.0
GT_IOU = 0.3


class InventoryError(Exception):
    """A bag that cannot be inventoried (one line)."""


@dataclass(frozen=True)
class InventoryOptions:
    """What changes the inventory (the pipeline reads ``color_model``, ``classifier_model``,
    ``general_signs``, ``general_every``)."""

    lidar: bool = True
    general_signs: bool = True
    #: general signs on every n-th frame (1: every frame; a sign seen in few frames is
    #: missed less often than with the classifier node's 3, at twice the cost)
    general_every: int = 1
    color_model: Optional[str] = None
    classifier_model: Optional[str] = None
    config: Optional[str] = None
    crops: bool = False
    score: bool = False
    inventory: InventoryConfig = InventoryConfig()


@dataclass
class BagRun:
    """What one bag gave: sightings (with positions, crops) and, with ``--score``, truth."""

    bag: str
    name: str
    start_ns: int = 0
    sightings: list[Sighting] = field(default_factory=list)
    located: list[Optional[Located]] = field(default_factory=list)
    crops: dict[int, np.ndarray] = field(default_factory=dict)
    frames: int = 0
    scans: int = 0
    lidar_sightings: int = 0
    wall_s: float = 0.0
    cpu_s: float = 0.0
    gt_key: tuple = ()
    gt_ids: list[Optional[int]] = field(default_factory=list)     # per sighting
    gt_signs: dict[int, dict] = field(default_factory=dict)       # sign_id -> class, pos...


# --- configuration --------------------------------------------------------------------------

def _geometry(config: Optional[str]) -> dict:
    """Extrinsics and LiDAR parameters from the parameters file (the nodes' own)."""
    import yaml

    from workzone_ros.core.lidar_clustering import ClusterParams
    from workzone_ros.core.projection import RoiParams, euler_matrix, extrinsics_from_list
    from workzone_ros.resources import config_path
    path = Path(config) if config else config_path('workzone.yaml')
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise InventoryError(f'cannot read parameters {path}: {exc}') from None

    def section(name: str) -> dict:
        return dict((data.get(name) or {}).get('ros__parameters', {}) or {})
    lc, pr = section('lidar_cluster'), section('projector')
    lb = list(pr.get('lidar_in_base', [1.0, 0.0, 1.95, 0.0, 0.0, 0.0])) + [0.0] * 6
    base_lidar = euler_matrix(tuple(lb[:3]), tuple(lb[3:6]))
    l2c = extrinsics_from_list(pr.get('lidar_to_camera', [0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0,
                                                          -0.5, 1.0, 0.0, 0.0, -0.6, 0, 0, 0,
                                                          1]))
    roi = RoiParams(spin_timing=bool(pr.get('spin_timing', True)),
                    lidar_rate_hz=float(pr.get('lidar_rate_hz', 10.0)))
    return {'params': ClusterParams.from_mapping(lc), 'k': int(lc.get('persistence_k', 2)),
            'n': int(lc.get('persistence_n', 3)), 'base_lidar': base_lidar,
            'lidar_to_camera': l2c, 'base_camera': camera_in_base(l2c, base_lidar),
            'roi': roi, 'slop_ns': int(float(pr.get('slop', 0.1)) * 1e9),
            'match_ns': int(float(lc.get('match_time_offset', 0.05)) * 1e9)}


# --- one bag --------------------------------------------------------------------------------

class _Progress:
    """One status line per bag on stderr (rewritten in place on a terminal)."""

    def __init__(self, label: str, total: int) -> None:
        self.label, self.total = label, max(total, 1)
        self.tty = sys.stderr.isatty()
        self.started = self.last = time.monotonic()

    def update(self, k: int, signs: int, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self.last < (0.5 if self.tty else 10.0):
            return
        self.last = now
        bar = '#' * int(20 * k / self.total)
        text = (f'{self.label} [{bar:<20}] {k}/{self.total} frames, {signs} sightings, '
                f'{now - self.started:.0f} s')
        if self.tty:
            sys.stderr.write('\r' + text + '\x1b[K')
        else:
            sys.stderr.write(text + '\n')
        sys.stderr.flush()

    def done(self, text: str) -> None:
        sys.stderr.write(('\r' if self.tty else '') + f'{self.label} {text}'
                         + ('\x1b[K' if self.tty else '') + '\n')
        sys.stderr.flush()


def _pipeline(opts: InventoryOptions):
    from workzone_ros.tools.workzone_pipeline import PipelineSource, check_available
    problem = check_available(opts)
    if problem:
        raise InventoryError(problem)
    return PipelineSource(opts)


def _camera(msg):
    from workzone_ros.core.projection import CameraModel
    return CameraModel(int(msg.width), int(msg.height), np.asarray(msg.k, float).reshape(3, 3),
                       np.asarray(msg.d, float).reshape(-1), msg.distortion_model or 'plumb_bob')


def _ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _crop(image: np.ndarray, box) -> Optional[np.ndarray]:
    h, w = image.shape[:2]
    x0, y0 = max(int(math.floor(box.x)), 0), max(int(math.floor(box.y)), 0)
    x1, y1 = min(int(math.ceil(box.x2)), w), min(int(math.ceil(box.y2)), h)
    return image[y0:y1, x0:x1].copy() if x1 > x0 and y1 > y0 else None


def run_bag(bag: str, opts: InventoryOptions, geo: dict, label: str = '',
            source=None, name: str = '') -> BagRun:
    """Sightings of one bag, positioned (module docstring).

    Raises:
        InventoryError: no camera, no CameraInfo, undecodable images or payloads.
        BagError: a missing or corrupt bag.
    """
    from workzone_ros.bagio import open_reader
    from workzone_ros.core.sync import PoseBuffer, SyncError
    started, cpu = time.monotonic(), time.process_time()
    run = BagRun(bag, name or Path(bag).name)
    with open_reader(bag) as reader:
        run.start_ns = int(reader.start_time)
        image_topic = next((t for t in IMAGE_TOPICS if t in reader.topics
                            and reader.topics[t].message_count), None)
        if image_topic is None:
            raise InventoryError('no camera images (/camera/image_raw or /camera/image_raw/'
                                 'compressed): nothing to inventory')
        info = next((reader.deserialize(m) for m in reader.messages([INFO_TOPIC])), None)
        if info is None:
            raise InventoryError(f'no {INFO_TOPIC}: the intrinsics are never guessed')
        camera = _camera(info)
        focal = float(camera.fx)
        lidar = opts.lidar and reader.topics.get('/lidar/points') is not None
        if '/odom' not in reader.topics:
            print(f'{label or run.name}: no /odom: signs get no position (position_source '
                  f'none) and are merged by track only', file=sys.stderr)
        topics = [image_topic, '/odom'] + (['/lidar/points'] if lidar else [])
        if opts.score:
            topics += ['/groundtruth/signs', '/groundtruth/lidar', '/groundtruth/workzone']
        source = source or _pipeline(opts)
        stream = _lidar_stream(geo) if lidar else None
        poses = PoseBuffer(max_age_ns=10 ** 18)
        scans: list[tuple[int, np.ndarray]] = []
        gt_frames: dict[int, GtSigns] = {}
        gt_lidar: list[GtLidar] = []
        best_q: dict[tuple, float] = {}
        bar = _Progress(label or run.name, reader.topics[image_topic].message_count)
        try:
            for m in reader.messages(topics):
                msg = reader.deserialize(m)
                if m.topic == '/odom':
                    p, q = msg.pose.pose.position, msg.pose.pose.orientation
                    try:
                        poses.add(_ns(msg), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
                    except SyncError:
                        pass                        # a bad pose: the next ones serve
                elif m.topic == '/lidar/points':
                    scans.append(_scan(msg, stream, poses, geo))
                    run.scans += 1
                elif m.topic == image_topic:
                    _frame(run, msg, source, focal, camera, best_q, opts)
                    bar.update(run.frames, len(run.sightings))
                elif m.topic == '/groundtruth/signs':
                    g = decode(msg.data, GtSigns)
                    gt_frames[g.header.stamp.to_ns()] = g
                elif m.topic == '/groundtruth/lidar':
                    gt_lidar.append(decode(msg.data, GtLidar))
                elif m.topic == '/groundtruth/workzone' and not run.gt_key:
                    w = decode(msg.data, GtWorkzone)
                    run.gt_key = (w.scenario, w.seed)
        except PayloadError as exc:
            raise InventoryError(f'bad ground-truth payload: {exc}') from None
    if stream is not None:
        _attach_lidar(run, scans, camera, poses, geo, opts.inventory)
    run.located = [locate(s, camera, geo['base_camera'], poses.at(s.stamp_ns), opts.inventory)
                   for s in run.sightings]
    if opts.score:
        _truth(run, gt_frames, gt_lidar, camera, poses, geo)
    run.wall_s = time.monotonic() - started
    run.cpu_s = time.process_time() - cpu
    bar.update(run.frames, len(run.sightings), force=True)
    bar.done(f'{run.frames} frames, {run.scans} scans, {len(run.sightings)} sightings '
             f'({run.lidar_sightings} with a LiDAR point), {run.wall_s:.1f} s wall, '
             f'{run.cpu_s:.1f} s CPU')
    return run


def _frame(run: BagRun, msg, source, focal: float, camera, best_q: dict,
           opts: InventoryOptions) -> None:
    """Run the pipeline on one image; record its sightings (and their crops)."""
    from workzone_ros.core.inventory import crop_quality
    from workzone_ros.tools.eval_workzone import EvalError, _image
    try:
        image = _image(msg)
    except EvalError as exc:
        raise InventoryError(str(exc)) from None
    stamp = _ns(msg)
    header = GtSigns(header=Header(stamp=Time.from_ns(stamp), frame_id='camera'))
    signs, _ = source(header, image, focal)
    run.frames += 1
    size = (int(image.shape[1]), int(image.shape[0]))
    for sign in signs:
        if sign.category == 'unknown':
            continue
        i = len(run.sightings)
        run.sightings.append(Sighting(stamp, sign, run.name, image_size=size))
        if opts.crops:
            key = (sign.track_id,) if sign.track_id is not None else ('s', i)
            q = crop_quality(sign.box, sign.score, size, opts.inventory.edge_px)
            if q > best_q.get(key, -1.0):
                best_q[key] = q
                crop = _crop(image, sign.box)
                if crop is not None:
                    run.crops[i] = crop


def _lidar_stream(geo: dict):
    from workzone_ros.core.lidar_stream import LidarStream
    return LidarStream(geo['params'], geo['k'], geo['n'])


def _scan(msg, stream, poses, geo: dict) -> tuple[int, np.ndarray]:
    """The ``lidar_cluster`` node's work on one scan: its published candidates."""
    from workzone_ros.core.lidar_clustering import LidarClusterError, candidates_to_array
    from workzone_ros.core.pointcloud import FieldSpec, cloud_view
    fields = [FieldSpec(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    pts = cloud_view(np.asarray(msg.data), fields, msg.point_step, msg.width, msg.height,
                     msg.row_step, bool(msg.is_bigendian))
    stamp = _ns(msg)
    base = poses.at(stamp + geo['match_ns'])
    try:
        out = stream.process(pts, None if base is None else base @ geo['base_lidar'])
    except LidarClusterError as exc:
        raise InventoryError(f'/lidar/points: {exc}') from None
    return stamp, candidates_to_array(out.candidates)


def _attach_lidar(run: BagRun, scans: list, camera, poses, geo: dict,
                  cfg: InventoryConfig) -> None:
    """Give each sighting the point of the LiDAR candidate projected into its box (the
    projector's nearest-in-time scan, ego-motion compensated to the image stamp)."""
    from workzone_ros.core.projection import candidates_to_rois, forward_time_offset
    if not scans:
        return
    fwd = forward_time_offset(geo['roi'])
    times = np.array([t + fwd for t, _ in scans], np.int64)

    def lidar_pose(t_ns: int):
        base = poses.at(int(t_ns))
        return None if base is None else base @ geo['base_lidar']
    by_stamp: dict[int, list[int]] = defaultdict(list)
    for i, s in enumerate(run.sightings):
        by_stamp[s.stamp_ns].append(i)
    for stamp, members in by_stamp.items():
        j = int(np.argmin(np.abs(times - stamp)))
        if abs(int(times[j]) - stamp) > geo['slop_ns'] or not len(scans[j][1]):
            continue
        arr = scans[j][1].copy()
        arr['z'] += arr['dz']                  # the face centre above a cut cluster
        rois, _ = candidates_to_rois(arr, scans[j][0], stamp, camera, geo['lidar_to_camera'],
                                     lidar_pose, geo['roi'])
        if not rois:
            continue
        uv = np.array([r.center for r in rois], float)
        xyz = np.array([r.position for r in rois], float)
        for i in members:
            s = run.sightings[i]
            k = match_candidate(s.sign.box, uv, xyz, s.sign.distance_m, cfg)
            if k is not None:
                run.sightings[i] = replace(s, lidar_point=tuple(float(v) for v in xyz[k]))
                run.lidar_sightings += 1


# --- ground truth (--score) -----------------------------------------------------------------

def _truth(run: BagRun, frames: dict, gt_lidar: list, camera, poses, geo: dict) -> None:
    """Per-sighting GT sign ids and each legible GT sign's class and face centre (odom)."""
    from workzone_ros.core.projection import point_times
    if not frames:
        raise InventoryError('--score: no /groundtruth/signs (not a workzone-ros synth bag?)')
    run.gt_ids = []
    for s in run.sightings:
        g = frames.get(s.stamp_ns)
        best = max(((s.sign.box.iou(x.box), x.sign_id) for x in g.signs), default=(0.0, None)) \
            if g else (0.0, None)
        run.gt_ids.append(best[1] if best[0] >= GT_IOU else None)
    seen: dict[int, dict] = {}
    cam_pos: dict[int, list] = defaultdict(list)
    for stamp, g in frames.items():
        base = poses.at(stamp)
        for x in g.signs:
            legible = min(x.box.w, x.box.h) >= LEGIBLE_PX and x.visible_fraction >= 0.5
            d = seen.setdefault(x.sign_id, {'class_key': x.class_key, 'category': x.category,
                                            'legible': False, 'xyz': None})
            d['legible'] |= legible
            if base is not None and x.visible_fraction >= 0.99:
                ray = camera_ray(x.box.x + x.box.w / 2, x.box.y + x.box.h / 2, camera)
                p = ray / np.linalg.norm(ray) * x.distance_m
                t = base @ geo['base_camera']
                cam_pos[x.sign_id].append(t[:3, :3] @ p + t[:3, 3])
    lidar_pos: dict[int, list] = defaultdict(list)
    for g in gt_lidar:
        for x in g.signs:
            c = np.array(x.center, float)
            t_fire = int(point_times(c[None], g.header.stamp.to_ns(), geo['roi'].lidar_rate_hz,
                                     geo['roi'].start_azimuth, geo['roi'].clockwise)[0])
            base = poses.at(t_fire)
            if base is not None:
                t = base @ geo['base_lidar']
                lidar_pos[x.sign_id].append(t[:3, :3] @ c + t[:3, 3])
    for sid, d in seen.items():
        pts = lidar_pos.get(sid) or cam_pos.get(sid)
        d['xyz'] = np.median(np.array(pts), axis=0) if pts else None
    run.gt_signs = seen


def _pct(v: list, q: float) -> Optional[float]:
    return round(float(np.percentile(v, q)), 3) if v else None


def score(rows: list[PhysicalSign], runs: list[BagRun]) -> dict:
    """Rows against the ground truth (module docstring), per category and pooled."""
    offsets, start = {}, 0
    for r in runs:
        offsets[r.name] = (start, r)
        start += len(r.sightings)

    def gt_of(i: int):
        for name, (o, r) in offsets.items():
            if o <= i < o + len(r.sightings):
                sid = r.gt_ids[i - o]
                return None if sid is None else (r.gt_key, sid), r
        return None, None
    truth: dict[tuple, dict] = {}
    for r in runs:
        for sid, d in r.gt_signs.items():
            key = (r.gt_key, sid)
            old = truth.get(key)
            if old is None:
                truth[key] = dict(d)
            else:
                old['legible'] |= d['legible']
    sighted = set()
    row_gt: list[Optional[tuple]] = []
    for row in rows:
        votes: Counter = Counter()
        for i in row.members:
            key, _ = gt_of(i)
            if key is not None:
                votes[key] += 1
                sighted.add(key)
        row_gt.append(votes.most_common(1)[0][0] if votes else None)
    out: dict[str, Any] = {}
    for cat in ('workzone', 'general', 'all'):
        gts = {k: d for k, d in truth.items() if d['legible'] and cat in ('all', d['category'])}
        rows_c = [(row, g) for row, g in zip(rows, row_gt)
                  if cat == 'all' or row.category == cat]
        hits: dict[tuple, list] = defaultdict(list)
        false_rows = 0
        for row, g in rows_c:
            if g is None or g not in truth:
                false_rows += 1
            else:
                hits[g].append(row)
        err: dict[str, list] = {'lidar': [], 'camera': []}
        class_ok = 0
        for key, rs in hits.items():
            d = truth[key]
            if len(rs) == 1 and rs[0].class_key == d['class_key']:
                class_ok += 1
            for row in rs:
                if row.xyz is not None and d['xyz'] is not None and row.source in err:
                    err[row.source].append(float(np.linalg.norm(row.xyz - d['xyz'])))
        once = sum(1 for k in gts if len(hits.get(k, ())) == 1)
        out[cat] = {
            'gt_signs': len(gts), 'sighted': sum(1 for k in gts if k in sighted),
            'found_once': once, 'found_once_right_class': class_ok,
            'duplicated': sum(1 for k in gts if len(hits.get(k, ())) > 1),
            'extra_rows': sum(len(v) - 1 for k, v in hits.items() if len(v) > 1),
            'missed': sum(1 for k in gts if k not in hits),
            'missed_never_sighted': sum(1 for k in gts if k not in hits and k not in sighted),
            'false_rows': false_rows, 'rows': len(rows_c),
            'error_lidar_m': {'n': len(err['lidar']), 'median': _pct(err['lidar'], 50),
                              'p90': _pct(err['lidar'], 90)},
            'error_camera_m': {'n': len(err['camera']), 'median': _pct(err['camera'], 50),
                               'p90': _pct(err['camera'], 90)},
        }
    out['bags'] = [{'bag': r.bag, 'frames': r.frames, 'scans': r.scans,
                    'wall_s': round(r.wall_s, 2), 'cpu_s': round(r.cpu_s, 2),
                    'duration_s': round(_duration(r), 2)} for r in runs]
    return out


def _duration(run: BagRun) -> float:
    if not run.sightings:
        return 0.0
    stamps = [s.stamp_ns for s in run.sightings]
    return (max(stamps) - min(stamps)) * 1e-9


# --- the whole run and its outputs ----------------------------------------------------------

def run_inventory(bags: list[str], opts: InventoryOptions
                  ) -> tuple[list[PhysicalSign], list[BagRun], list[tuple[str, str]]]:
    """Every bag in order, then the merged inventory; ``(rows, runs, errors)``."""
    geo = _geometry(opts.config)
    runs, errors = [], []
    source = None
    for k, bag in enumerate(bags, 1):
        label = f'[{k}/{len(bags)}] {Path(bag).name}'
        try:
            if not Path(bag).exists():
                raise InventoryError('no such bag')
            source = _pipeline(opts)            # a fresh tracker per bag
            name = Path(bag).name
            while name in {r.name for r in runs}:   # two bags of one name: keep them apart
                name += "'"
            runs.append(run_bag(bag, opts, geo, label, source, name))
        except (BagError, InventoryError) as exc:
            errors.append((bag, ' '.join(str(exc).split())))
            print(f'{label}: ERROR {errors[-1][1]}', file=sys.stderr)
    sightings = [s for r in runs for s in r.sightings]
    located = [p for r in runs for p in r.located]
    rows = build_inventory(sightings, located, opts.inventory)
    return rows, runs, errors


def _row_dict(row: PhysicalSign, crop: str, starts: dict[str, int]) -> dict:
    xyz = [''] * 3 if row.xyz is None else [round(float(v), 3) for v in row.xyz]
    t0 = starts.get(row.bags[0], 0)
    return {'sign_id': row.sign_id, 'class_key': row.class_key, 'category': row.category,
            'first_seen_s': round((row.first_ns - t0) * 1e-9, 3),
            'last_seen_s': round((row.last_ns - t0) * 1e-9, 3), 'frames': row.frames,
            'x_m': xyz[0], 'y_m': xyz[1], 'z_m': xyz[2], 'position_source': row.source,
            'best_crop': crop, 'mile': '' if row.mile is None else row.mile,
            'sigma_m': '' if not math.isfinite(row.sigma_m) else round(row.sigma_m, 2),
            'bags': ';'.join(row.bags)}


def write_crops(rows: list[PhysicalSign], runs: list[BagRun], folder: str) -> dict[int, str]:
    """Each row's best crop as ``folder/sign_NNNN_<class>.png``; sign_id -> path."""
    import cv2
    crops: dict[int, np.ndarray] = {}
    start = 0
    for r in runs:
        for i, c in r.crops.items():
            crops[start + i] = c
        start += len(r.sightings)
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for row in rows:
        best = row.best if row.best in crops else next(
            (i for i in sorted(row.members, key=lambda i: -crops[i].size if i in crops else 0)
             if i in crops), None)
        if best is None:
            continue
        path = out / f'sign_{row.sign_id:04d}_{row.class_key}.png'
        cv2.imwrite(str(path), crops[best])
        paths[row.sign_id] = str(path)
    return paths


def write_csv(rows: list[PhysicalSign], path: str, crops: Optional[dict] = None,
              starts: Optional[dict[str, int]] = None) -> None:
    """The inventory as CSV (:data:`COLUMNS`); ``starts``: bag name -> start stamp (ns),
    so that times are bag time (seconds since the start of the sign's first bag)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open('w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for row in rows:
            w.writerow(_row_dict(row, (crops or {}).get(row.sign_id, ''), starts or {}))


def write_geojson(rows: list[PhysicalSign], path: str, crops: Optional[dict] = None,
                  starts: Optional[dict[str, int]] = None) -> None:
    """Rows with a position as GeoJSON Points (odometry-frame metres, not WGS84)."""
    feats = []
    for row in rows:
        if row.xyz is None:
            continue
        props = _row_dict(row, (crops or {}).get(row.sign_id, ''), starts or {})
        feats.append({'type': 'Feature', 'properties': props, 'geometry': {
            'type': 'Point', 'coordinates': [round(float(v), 3) for v in row.xyz]}})
    doc = {'type': 'FeatureCollection', 'name': 'workzone-ros sign inventory',
           'crs': {'type': 'name', 'properties': {'name': 'odom (local metres, not WGS84)'}},
           'features': feats}
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1))


def _summary(rows: list[PhysicalSign], runs: list[BagRun]) -> str:
    by_class = Counter(r.class_key for r in rows)
    by_source = Counter(r.source for r in rows)
    frames = sum(r.frames for r in runs)
    wall = sum(r.wall_s for r in runs)
    lines = [f'{len(rows)} signs from {len(runs)} bag(s), {frames} frames in {wall:.1f} s; '
             'position: ' + ', '.join(f'{k} {v}' for k, v in sorted(by_source.items()))]
    lines += [f'  {k:<26s} {v}' for k, v in sorted(by_class.items())]
    return '\n'.join(lines)


def _print_score(s: dict) -> None:
    print('score against the ground truth:')
    for cat in ('workzone', 'general', 'all'):
        c = s[cat]
        el, ec = c['error_lidar_m'], c['error_camera_m']
        print(f"  {cat:<8s} GT signs {c['gt_signs']} (sighted {c['sighted']}): found once "
              f"{c['found_once']} (right class {c['found_once_right_class']}), duplicated "
              f"{c['duplicated']} (+{c['extra_rows']} rows), missed {c['missed']} "
              f"(never sighted {c['missed_never_sighted']}), false rows {c['false_rows']} of "
              f"{c['rows']}")
        print(f"           position error lidar median {el['median']} m p90 {el['p90']} m "
              f"(n={el['n']}); camera median {ec['median']} m p90 {ec['p90']} m (n={ec['n']})")
    for b in s['bags']:
        print(f"  {Path(b['bag']).name}: {b['frames']} frames, {b['scans']} scans, "
              f"{b['wall_s']} s wall, {b['cpu_s']} s CPU")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='workzone-ros inventory', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bags', nargs='+', help='bags of one road (camera, CameraInfo; /odom and '
                   '/lidar/points when there are)')
    p.add_argument('-o', '--output', required=True, help='CSV file to write')
    p.add_argument('--geojson', help='also write the rows as GeoJSON points (odom metres)')
    p.add_argument('--crops', help="write each sign's best crop (PNG) in this folder")
    p.add_argument('--no-lidar', action='store_true',
                   help='position every sign from the camera (monocular distance)')
    p.add_argument('--no-general', action='store_true',
                   help='work-zone signs only (no general-sign recogniser)')
    p.add_argument('--general-every', type=int, default=InventoryOptions().general_every,
                   metavar='N', help='search every N-th frame for general signs (default '
                   '%(default)s; the classifier node uses 3: about half the time, but a sign '
                   'seen in few frames can be missed)')
    p.add_argument('--min-frames', type=int, default=InventoryConfig().min_frames,
                   help='drop signs seen in fewer frames (default %(default)s)')
    p.add_argument('--config', help='parameters file (default: config/workzone.yaml): '
                   'extrinsics and the lidar_cluster parameters')
    p.add_argument('--color-model', help='colour model (.npz)')
    p.add_argument('--classifier-model', help='sign classifier (.npz)')
    p.add_argument('--score', action='store_true',
                   help='compare with the ground truth of synthetic bags')
    p.add_argument('--json', help='write the score (and the summary) here')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Inventory the signs of the bags; exit 2 when a bag could not be read."""
    args = _parser().parse_args(argv)
    if args.min_frames < 1 or args.general_every < 1:
        print('workzone-ros inventory: --min-frames and --general-every must be >= 1',
              file=sys.stderr)
        return 2
    opts = InventoryOptions(lidar=not args.no_lidar, general_signs=not args.no_general,
                            general_every=args.general_every,
                            color_model=args.color_model,
                            classifier_model=args.classifier_model, config=args.config,
                            crops=bool(args.crops), score=args.score,
                            inventory=InventoryConfig(min_frames=args.min_frames))
    if opts.general_signs:
        try:
            from workzone_ros.core.general import GeneralSignDetector  # noqa: F401
        except ImportError:
            print('workzone-ros inventory: no general-sign recogniser (workzone_ros.core.'
                  'general) in this build: work-zone signs only', file=sys.stderr)
            opts = replace(opts, general_signs=False)
    try:
        rows, runs, errors = run_inventory(args.bags, opts)
    except InventoryError as exc:
        print(f'workzone-ros inventory: {exc}', file=sys.stderr)
        return 2
    crops = write_crops(rows, runs, args.crops) if args.crops else {}
    starts = {r.name: r.start_ns for r in runs}
    write_csv(rows, args.output, crops, starts)
    if args.geojson:
        write_geojson(rows, args.geojson, crops, starts)
    print(_summary(rows, runs))
    print(f'inventory written to {args.output}')
    result: dict[str, Any] = {'rows': len(rows), 'errors': errors}
    if args.score and runs:
        result['score'] = score(rows, runs)
        _print_score(result['score'])
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2))
    for bag, err in errors:
        print(f'{bag}: {err}', file=sys.stderr)
    return 2 if errors else 0


if __name__ == '__main__':
    sys.exit(main())
