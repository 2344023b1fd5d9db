"""``evaluate lidar sensors``: the candidate stage across simulated LiDARs and mountings.

Scans are cast in process from library scenarios (the simulator's ray caster and world; no
camera, no bag) for every combination of

* **sensor** (:data:`SENSORS`): the simulator's VLP-16, HDL-32E and HDL-64E presets and a
  128-beam sensor (Ouster OS1-128-like: +-22.5 deg, 0.35 deg apart, 1024 columns at 10 Hz,
  120 m);
* **mounting height** above the road (``--heights``; the simulator mounts every preset at
  1.95 m, here the sensor pose is raised or lowered and ``lidar_in_base`` follows);
* **intensity encoding** (:data:`ENCODINGS`): float 0-255 (Velodyne driver, simulator),
  float reflectance 0-1 (KITTI), uint8 0-255 (Livox, Hesai), uint16 0-65535;
* **axes** (:data:`AXES`): x forward / y left, or x right / y forward (nuScenes), with
  ``lidar_in_base`` saying so;

and each stream runs the node's code (:class:`~workzone_ros.core.lidar_stream.LidarStream`:
learned intensity scale, ground fit, persistence with odometry).  Scored like
``evaluate lidar synthetic``: a sign counts in a scan with 3+ returns on its face inside the
region, is found when a published candidate lies within ``max(1, 1.5 radius)`` of its face
centre; a published candidate near no sign is a false one.  For the found signs within
60 m, the camera ROI (the simulator's 640x480 camera) as the projector sizes it today and
sized by the cluster: width relative to the sign's and whether it covers the whole face.

The scenarios (``--scenarios name:seed``) default to a random work zone, the distractors
scenario (hard negatives, no work zone) and a left-lane closure with its signs repeated on
the left (median) side (``left:seed``), which the library does not place.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Callable, Optional

import numpy as np

__all__ = ['SENSORS', 'ENCODINGS', 'AXES', 'add_arguments', 'run', 'encode', 'sweep']

#: Sensor name -> ``sim.lidar.LidarModel`` keyword arguments (``preset`` names a preset).
SENSORS = {
    'vlp16': {'preset': 'vlp16'},
    'hdl32': {'preset': 'hdl32'},
    'hdl64': {'preset': 'hdl64'},
    'os128': {'n_beams': 128, 'fov_up_deg': 22.5, 'fov_down_deg': -22.5,
              'azimuth_res_deg': 0.35, 'max_range': 120.0, 'range_noise_m': 0.03},
}
ENCODINGS = ('float255', 'unit', 'uint8', 'uint16')
#: Axis convention -> yaw of the lidar in base_link.
AXES = {'x-forward': 0.0, 'x-right': -math.pi / 2}


def add_arguments(parser) -> None:
    """Options of ``evaluate lidar sensors``."""
    parser.add_argument('--scenarios', nargs='+',
                        default=['random:1350', 'distractors:1354', 'left:1355'],
                        help='name:seed (library scenario, random, or left = a left-lane '
                             'closure with left-side signs)')
    parser.add_argument('--duration', type=float, default=15.0, help='seconds per scenario')
    parser.add_argument('--sensors', nargs='+', default=list(SENSORS), choices=list(SENSORS))
    parser.add_argument('--heights', nargs='+', type=float, default=[1.95, 1.5, 2.5],
                        help='mounting heights above the road, m')
    parser.add_argument('--encodings', nargs='+', default=list(ENCODINGS),
                        choices=list(ENCODINGS))
    parser.add_argument('--axes', nargs='+', default=list(AXES), choices=list(AXES))
    parser.add_argument('--config', default='config/workzone.yaml',
                        help='parameters file (lidar_cluster section)')
    parser.add_argument('--json', help='write the figures to this JSON file')


def encode(points: np.ndarray, encoding: str, yaw: float) -> np.ndarray:
    """The simulator's scan (x forward, y left, float 0-255) as another sensor sends it."""
    from workzone_ros.core.pointcloud import make_points
    x, y, z = points['x'], points['y'], points['z']
    if yaw:
        c, s = math.cos(yaw), math.sin(yaw)            # lidar = R(yaw)^T base
        x, y = (c * x + s * y).astype(np.float32), (-s * x + c * y).astype(np.float32)
    v = points['intensity'].astype(np.float64)
    inten = {'float255': v.astype(np.float32),
             'unit': (v / 255.0).astype(np.float32),
             'uint8': np.clip(np.rint(v), 0, 255).astype(np.uint8),
             'uint16': np.clip(np.rint(v * 257.0), 0, 65535).astype(np.uint16)}[encoding]
    return make_points(x=x, y=y, z=z, intensity=inten, ring=points['ring'])


def _scenario(name: str, seed: int):
    from workzone_ros.sim.scenario_spec import SignSpec, load_scenario
    if name != 'left':
        return load_scenario(name, seed=seed)
    spec = load_scenario('paper_b', seed=seed)
    s0 = spec.ego.start_s
    left = tuple(SignSpec(k, s0 + ds, side='left') for k, ds in (
        ('left_lane_closed_ahead', 120.0), ('left_lane_ends', 230.0),
        ('work_zone_speed_limit', 330.0)))
    return replace(spec, name='left', signs=spec.signs + left)


def _model(name: str):
    from workzone_ros.sim.lidar import LidarModel, lidar_preset
    kw = dict(SENSORS[name])
    return lidar_preset(kw.pop('preset')) if 'preset' in kw else LidarModel(**kw)


def _pose4(p) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = p.R, p.position
    return t


def sweep(scenarios: list[tuple[str, int]], duration: float, sensors, heights, encodings,
          axes, base_params, k: int = 2, n: int = 3,
          stream_factory: Optional[Callable] = None, log=print) -> list[dict]:
    """Run every combination; one result row (dict) per sensor x height x encoding x axes.

    ``stream_factory(params, k, n)`` builds the per-stream processor (default
    :class:`LidarStream`); it needs ``.process(points, pose) -> .candidates``.
    """
    from workzone_ros.core.lidar_clustering import candidates_to_array
    from workzone_ros.core.lidar_rois import size_rois
    from workzone_ros.core.lidar_stream import LidarStream
    from workzone_ros.core.projection import (
        CameraModel,
        RoiParams,
        candidates_to_rois,
        project_points,
    )
    from workzone_ros.sim.lidar import cast_scan
    from workzone_ros.sim.scenario import build_scene
    from workzone_ros.sim.world import (
        BASE_TO_CAMERA_ROT,
        CAMERA_IN_BASE,
        DEFAULT_CAMERA,
        Pose,
        rot_zyx,
    )
    from workzone_ros.sim.writer import lidar_scene
    from workzone_ros.tools.eval_lidar import in_region
    factory = stream_factory or (lambda p, k_, n_: LidarStream(p, k_, n_))
    cam = CameraModel(DEFAULT_CAMERA.width, DEFAULT_CAMERA.height, DEFAULT_CAMERA.K,
                      DEFAULT_CAMERA.D)
    cam_from_base = np.eye(4)
    cam_from_base[:3, :3] = BASE_TO_CAMERA_ROT
    cam_from_base[:3, 3] = -BASE_TO_CAMERA_ROT @ np.asarray(CAMERA_IN_BASE, float)
    rows = {}
    for sensor in sensors:
        model = _model(sensor)
        spin = 1.0 / model.rate_hz
        for h in heights:
            combos = [(e, a) for e in encodings for a in axes]
            for name, seed in scenarios:
                spec = _scenario(name, seed)
                scene, ego, _ = build_scene(spec, seed)
                signs = {sp.object_id: sp for sp in scene.signs}
                mount = np.array([1.0, 0.0, h])

                def lidar_pose(t, _ego=ego, _m=mount):
                    b = _ego.base_pose(t)
                    return Pose(b.to_world(_m), b.yaw, b.pitch, b.roll)
                streams = {}
                for e, a in combos:
                    yaw = AXES[a]
                    params = base_params.with_(lidar_in_base=(1.0, 0.0, h, 0.0, 0.0, yaw))
                    b2l = np.eye(4)
                    b2l[:3, :3] = rot_zyx(yaw, 0.0, 0.0)
                    b2l[:3, 3] = mount
                    streams[(e, a)] = (factory(params, k, n), params, b2l)
                    rows.setdefault((sensor, h, e, a), _empty_row(sensor, h, e, a))
                t0 = time.time()
                times = np.arange(1.0, 1.0 + duration, spin)
                for j, t in enumerate(times):
                    sc = cast_scan(lidar_scene(scene, float(t)), float(t), lidar_pose, model,
                                   seed=seed, scan_index=j)
                    gts = []
                    for sid, idx in sc.sign_hits.items():
                        sp = signs.get(sid)
                        if sp is None:
                            continue
                        c = _center_in_lidar(sp.center, lidar_pose, float(t), spin)
                        gts.append((c, len(idx), sp))
                    base4 = _pose4(ego.base_pose(float(t) + spin / 2))
                    for (e, a), (stream, params, b2l) in streams.items():
                        pts = encode(sc.points, e, AXES[a])
                        cands = stream.process(pts, base4 @ b2l).candidates
                        if j < k - 1:
                            continue
                        _score(rows[(sensor, h, e, a)], cands, gts, params, b2l, cam,
                               cam_from_base @ b2l, candidates_to_array, candidates_to_rois,
                               size_rois, project_points, RoiParams(), in_region)
                log(f'  {sensor} at {h:.2f} m, {name}:{seed}: {len(times)} scans x '
                    f'{len(combos)} streams in {time.time() - t0:.0f} s')
    return [_finish(r) for r in rows.values()]


def _empty_row(sensor, h, e, a) -> dict:
    return {'sensor': sensor, 'height': h, 'encoding': e, 'axes': a, 'scans': 0,
            'signs60': 0, 'missed60': 0, 'signs60_left': 0, 'missed60_left': 0,
            'published': 0, 'fp': 0, 'fp_left': 0, 'roi_today': [], 'roi_sized': [],
            'cover_today': [], 'cover_sized': [], 'measured': 0}


def _center_in_lidar(center, lidar_pose, t0: float, spin: float) -> np.ndarray:
    """Face centre in the lidar (base-axes) frame when the spin sweeps over it (as the
    simulator's writer computes its ground truth)."""
    t = t0 + spin / 2
    for _ in range(2):
        p = lidar_pose(t).to_body(np.asarray(center, float))
        frac = ((math.pi - math.atan2(p[1], p[0])) / (2 * math.pi)) % 1.0
        t = t0 + frac * spin
    return lidar_pose(t).to_body(np.asarray(center, float))


def _score(row, cands, gts, params, b2l, cam, l2c, to_array, to_rois, size_rois, project,
           roi_params, in_region) -> None:
    rot = b2l[:3, :3]
    row['scans'] += 1
    pub = cands.subset(cands.confirmed)
    row['published'] += len(pub)
    if gts:
        gc_base = np.array([g[0] for g in gts])
        gc = gc_base @ rot                       # base axes -> this sensor's axes
    else:
        gc_base = gc = np.zeros((0, 3))
    ok = np.zeros(len(pub), bool)
    found = np.zeros(len(gts), bool)
    for i in range(len(pub)):
        if not len(gts):
            break
        hit = np.linalg.norm(gc - pub.center[i], axis=1) <= max(1.0, 1.5 * float(pub.radius[i]))
        ok[i] = hit.any()
        found |= hit
    left_c = (pub.center @ rot.T)[:, 1] > 4.0 if len(pub) else np.zeros(0, bool)
    row['fp'] += int((~ok).sum())
    row['fp_left'] += int((~ok & left_c).sum())
    if not gts:
        return
    n_pts = np.array([g[1] for g in gts])
    rng = np.hypot(gc_base[:, 0], gc_base[:, 1])
    counted = (n_pts >= 3) & in_region(gc, params) & (rng < 60.0)
    left = gc_base[:, 1] > 4.0
    row['signs60'] += int(counted.sum())
    row['missed60'] += int((counted & ~found).sum())
    row['signs60_left'] += int((counted & left).sum())
    row['missed60_left'] += int((counted & left & ~found).sum())
    # ROIs of the found signs: today's sizing and sized by the cluster, vs the sign's face.
    arr = to_array(pub, only_confirmed=False)
    if not len(arr):
        return
    today, _ = to_rois(arr, 0, 0, cam, l2c, None, replace(roi_params, spin_timing=False))
    sized = size_rois(today, arr, cam)
    by_id = {int(r.candidate_id): (r, q) for r, q in zip(today, sized)}
    for j in np.flatnonzero(counted & found):
        i = int(np.argmin(np.linalg.norm(pub.center - gc[j], axis=1)))
        pair = by_id.get(int(pub.ids[i]))
        if pair is None:
            continue
        sp = gts[j][2]
        face = project(gc[j:j + 1], l2c, cam)
        if not face.in_image[0]:
            continue
        d = float(face.xyz_cam[0, 2])
        w_px, h_px = sp.width * cam.fx / d, sp.height * cam.fy / d
        u, v = face.uv[0]
        rect = (u - w_px / 2, v - h_px / 2, u + w_px / 2, v + h_px / 2)
        for key, r in (('today', pair[0]), ('sized', pair[1])):
            b = r.box
            iw = max(0.0, min(b.x + b.w, rect[2]) - max(b.x, rect[0]))
            ih = max(0.0, min(b.y + b.h, rect[3]) - max(b.y, rect[1]))
            row[f'roi_{key}'].append(b.w / max(w_px, 1e-6))
            row[f'cover_{key}'].append(iw * ih / max(w_px * h_px, 1e-6))
        row['measured'] += int(pub.half_size[i, 0] > 0)


def _finish(row: dict) -> dict:
    out = {k: v for k, v in row.items() if not isinstance(v, list)}
    for key in ('today', 'sized'):
        r, c = row[f'roi_{key}'], row[f'cover_{key}']
        out[f'roi_width_ratio_{key}'] = float(np.median(r)) if r else float('nan')
        out[f'covered90_{key}'] = float(np.mean(np.array(c) >= 0.9)) if c else float('nan')
    out['rois'] = len(row['roi_today'])
    return out


def print_table(rows: list[dict], log=print) -> None:
    """One line per combination."""
    log(f'{"sensor":<6} {"height":>6} {"intensity":<9} {"axes":<9} {"scans":>5} '
        f'{"missed <60 m":>16} {"left: missed":>13} {"false":>10} {"left":>4} '
        f'{"ROI/sign width":>15} {"covers face":>12} {"measured":>8}')
    for r in rows:
        m = f'{r["missed60"]}/{r["signs60"]} ({100 * r["missed60"] / max(r["signs60"], 1):.1f}%)'
        ml = f'{r["missed60_left"]}/{r["signs60_left"]}'
        fp = f'{r["fp"]}/{r["published"]}'
        roi = f'{r["roi_width_ratio_today"]:.1f} -> {r["roi_width_ratio_sized"]:.1f}'
        cov = f'{r["covered90_today"]:.2f} -> {r["covered90_sized"]:.2f}'
        log(f'{r["sensor"]:<6} {r["height"]:6.2f} {r["encoding"]:<9} {r["axes"]:<9} '
            f'{r["scans"]:5d} {m:>16} {ml:>13} {fp:>10} {r["fp_left"]:4d} {roi:>15} '
            f'{cov:>12} {r["measured"] / max(r["rois"], 1):8.2f}')


def run(args) -> int:
    """``evaluate lidar sensors``."""
    import json
    from pathlib import Path

    from workzone_ros.core.lidar_clustering import ClusterParams
    from workzone_ros.tools.eval_lidar import _config
    cfg, _ = _config(args)
    params = ClusterParams.from_mapping(cfg)
    scen = []
    for item in args.scenarios:
        name, _, seed = item.partition(':')
        scen.append((name, int(seed or 0)))
    rows = sweep(scen, args.duration, args.sensors, args.heights, args.encodings, args.axes,
                 params, int(cfg.get('persistence_k', 2)), int(cfg.get('persistence_n', 3)))
    print_table(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0
