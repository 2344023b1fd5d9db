"""LiDAR candidate and projection evaluation (``workzone-ros evaluate lidar``).

Every mode runs the node's own code (:class:`~workzone_ros.core.lidar_stream.LidarStream`
or :func:`~workzone_ros.core.lidar_clustering.cluster_cloud`) with the ``lidar_cluster``
parameters of ``--config``, changed with ``--set key=value``.

``synthetic BAG [BAG ...]``
    On bags written by ``workzone-ros synth`` (ground truth in ``/groundtruth/lidar``):

    * candidate false positives per scan and missed signs, by range band (0-30, 30-60,
      60-90 m).  A ground-truth sign counts when it has at least ``--min-gt-points`` returns
      on its face in the scan and lies in the pre-filter region; it is found when a published
      (persistent) candidate lies within ``max(1.0, 1.5 * radius)`` of its face centre.
      The first ``k - 1`` scans of a bag are skipped (persistence cannot confirm yet).
      A candidate matching no sign is a false positive.  Rates: FP = false candidates /
      all published candidates; missed = missed signs / counted signs.
    * projection error of the sign centre in pixels (median, p95) with and without ego-motion
      compensation: each published candidate matched to a sign is projected into an image
      taken ``--offset-ms`` after the LiDAR fired at that sign, with the bag's odometry
      (compensated: spin timing + interpolated poses) or as is (uncompensated), against the
      true pixel of the sign's face centre (ground-truth centre moved with the simulator's
      exact pose at the image time).  The error therefore includes the candidate-centre
      error of the clustering.  Speeds come from the bags (``synth --speed``).

``sync BAG [BAG ...]``
    Compares the projector's synchronisation policies (``approximate``, ``latest``,
    ``nearest``; see :mod:`workzone_ros.core.sync`) on synth bags.  The bag is replayed as
    the projector sees it: candidates (clustering + persistence, as ``lidar_cluster``) arrive
    ``--cloud-delay-ms`` after their scan stamp (a whole spin plus processing), images
    ``--image-delay-ms`` after theirs; each policy pairs them in arrival order, and every pair
    is projected with ego-motion compensation.  Per policy: the fraction of camera
    sign-frames (a ground-truth sign within ``--max-range`` in ``/groundtruth/signs``) whose
    GT box centre lies inside an ROI, over all such signs and over the signs the LiDAR chain
    detects at all (matched by a confirmed candidate in some scan); the ROI centre error vs
    the GT box centre (median, p95; with and without compensation); the mean
    ``|image stamp - lidar stamp|`` of the pairs and of the forward firing time (stamp +
    half a spin); the mean wait from the image's arrival to its pairing.

``realdata [DIR]``
    Runs the chain on the three PJLab scenes (``shared/realdata/lidar_camera_pjlab``): what
    was inferred (intensity encoding, road), every cluster and the test that rejected it,
    the ROIs as the projector sizes them today and sized by the cluster, how they cover the
    signs labelled by eye (:data:`PJLAB_SIGNS`), and overlays (PNG) in ``--out``.

``scan FILE``
    One scan of your own (``.pcd``, KITTI-style ``.bin``, ``.npy`` or a bag): the same
    explanation, and what persistence would do with it in a live node.

``sensors``
    Simulated LiDARs (16 to 128 beams) x mounting heights x intensity encodings x axis
    conventions, cast in process from library scenarios (no bags; see
    :mod:`workzone_ros.tools.eval_lidar_sensors`).

Report on scenarios you did not tune on; the command line names them.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Optional

import numpy as np

from workzone_ros.core.lidar_clustering import (
    ClusterParams,
    LidarClusterError,
    candidates_to_array,
    cluster_cloud,
)
from workzone_ros.core.lidar_rois import size_rois
from workzone_ros.core.lidar_stream import LidarStream
from workzone_ros.core.pcd import PcdError, read_pcd
from workzone_ros.core.projection import (
    CameraModel,
    RoiParams,
    candidates_to_rois,
    compensate,
    extrinsics_from_list,
    forward_time_offset,
    point_times,
    project_points,
)
from workzone_ros.core.sync import ApproximateTimeSync, LatestSync, NearestSync
from workzone_ros.tools.lidar_report import ScanFormatError, explain, load_scan

__all__ = ['main', 'load_pjlab_scene', 'PJLAB_SCENES', 'PJLAB_SIGNS', 'REAL_PARAMS',
           'run_scene', 'in_region', 'BANDS']

PJLAB_SCENES = ('scene_sign_board', 'scene_round_sign_traffic_lights',
                'scene_truck_reflectors')
#: The real scenes run with the node's defaults (left side included, the road from the
#: ground fit: the PJLab sensor sits ~2.0 m up, pitched ~1 deg).
REAL_PARAMS = ClusterParams()
BANDS = ((0.0, 30.0), (30.0, 60.0), (60.0, 90.0))


def load_pjlab_scene(folder) -> dict:
    """Cloud, image and calibration of one PJLab scene folder.

    Returns:
        dict with ``points`` (structured), ``image`` (BGR), ``camera`` (CameraModel),
        ``lidar_to_camera`` (4x4).
    """
    import cv2
    folder = Path(folder)
    points = read_pcd(folder / 'calib.pcd')
    intr = folder / 'center_camera-intrinsic.json'
    if intr.exists():
        p = json.loads(intr.read_text())['center_camera-intrinsic']['param']
        k = np.array(p['cam_K']['data'], float)
        d = np.array(p['cam_dist']['data'], float).reshape(-1)
        e = json.loads((folder / 'top_center_lidar-to-center_camera-extrinsic.json')
                       .read_text())['top_center_lidar-to-center_camera-extrinsic']
        t = extrinsics_from_list(np.array(e['param']['sensor_calib']['data']).ravel())
        image = cv2.imread(str(folder / 'calib.png'))
    else:
        vals = {}
        for line in (folder / 'calib.txt').read_text().splitlines():
            if ':' in line:
                key, rest = line.split(':', 1)
                vals[key.strip()] = np.array(rest.split(), float)
        k, d = vals['K'].reshape(3, 3), vals['D']
        t = extrinsics_from_list(vals['T'])
        image = cv2.imread(str(folder / 'calib.jpg'))
    if image is None:
        raise FileNotFoundError(f'no readable image in {folder}')
    cam = CameraModel(image.shape[1], image.shape[0], k, d)
    return {'points': points, 'image': image, 'camera': cam, 'lidar_to_camera': t}


#: Signs in the PJLab images, read by eye (pixels x0, y0, x1, y1): the guide board
#: ~97 m ahead; the round sign ~30 m ahead, 10 m left (no LiDAR return on its face; the
#: plate on its mast is hit); the text plate beside the left signal head, ~33 m.
PJLAB_SIGNS = {
    'scene_sign_board': (('guide board', (872, 477, 966, 530)),),
    'scene_round_sign_traffic_lights': (('round sign', (300, 230, 380, 303)),
                                        ('text plate', (40, 340, 73, 445))),
    'scene_truck_reflectors': (),
}


def run_scene(scene: dict, params: ClusterParams = REAL_PARAMS,
              roi_params: RoiParams = RoiParams()):
    """Clustering -> candidates -> ROIs on one real scene (single scan: no persistence).

    Returns:
        ``(result, candidate rows, ROIs as the projector sizes them today, ROIs sized by
        the cluster)``.
    """
    res = cluster_cloud(scene['points'], params)
    arr = candidates_to_array(res.candidates)
    rois, _ = candidates_to_rois(arr, 0, 0, scene['camera'], scene['lidar_to_camera'],
                                 None, roi_params)
    return res, arr, rois, size_rois(rois, arr, scene['camera'])


def _overlap(box, sign) -> tuple[float, float]:
    """(share of the sign rectangle inside the ROI, ROI width / sign width)."""
    x0, y0, x1, y1 = sign
    iw = max(0.0, min(box.x + box.w, x1) - max(box.x, x0))
    ih = max(0.0, min(box.y + box.h, y1) - max(box.y, y0))
    return iw * ih / ((x1 - x0) * (y1 - y0)), box.w / (x1 - x0)


def draw_overlay(scene: dict, res, rois, path, sized=()) -> None:
    """Write the image with the pre-filtered points (dots; red: kept clusters), the ROIs as
    the projector sizes them (red) and sized by the cluster (green)."""
    import cv2
    img = scene['image'].copy()
    proj = project_points(res.points, scene['lidar_to_camera'], scene['camera'])
    clustered = res.clustered_mask()
    for (u, v), ok, inside in zip(proj.uv, clustered, proj.in_image):
        if inside:
            cv2.circle(img, (int(u), int(v)), 3, (0, 0, 255) if ok else (255, 160, 0), -1)
    for colour, boxes in (((0, 0, 255), rois), ((0, 200, 0), sized)):
        for r in boxes:
            b = r.box
            cv2.rectangle(img, (int(b.x), int(b.y)), (int(b.x + b.w), int(b.y + b.h)),
                          colour, 3)
    for r in rois:
        cv2.putText(img, f'#{r.candidate_id} {r.range_m:.0f} m {r.points} pts',
                    (int(r.box.x), max(int(r.box.y) - 8, 20)), cv2.FONT_HERSHEY_SIMPLEX, 1.0,
                    (0, 0, 255), 2)
    cv2.imwrite(str(path), img)


def _realdata(args) -> int:
    root = Path(args.dir)
    if not root.is_dir():
        print(f'no real data at {root}', file=sys.stderr)
        return 2
    params = _params(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in PJLAB_SCENES:
        scene = load_pjlab_scene(root / name)
        res, arr, rois, sized = run_scene(scene, params)
        print(f'== {name}')
        explain(scene['points'], res, params)
        for r, q in zip(rois, sized):
            print(f'  ROI #{r.candidate_id}: {r.points} pts at {r.range_m:.1f} m: projector '
                  f'today {r.box.w:.0f} x {r.box.h:.0f} px, sized by the cluster '
                  f'{q.box.w:.0f} x {q.box.h:.0f} px')
        for label, sign in PJLAB_SIGNS[name]:
            for what, boxes in (('today', rois), ('sized', sized)):
                best = max(((_overlap(q.box, sign), q) for q in boxes), default=None,
                           key=lambda t: t[0][0])
                if best is None or best[0][0] == 0:
                    print(f'  {label}: no ROI ({what})')
                    continue
                (cov, ratio), q = best
                print(f'  {label} ({sign[2] - sign[0]} px wide): ROI #{q.candidate_id} '
                      f'({what}) covers {100 * cov:.0f} %, {ratio:.1f}x its width')
        draw_overlay(scene, res, rois, out / f'{name}_rois.png', sized)
        print(f'  overlay: {out / (name + "_rois.png")}')
    return 0


def _params(args) -> ClusterParams:
    """The lidar_cluster section of ``--config`` with ``--set key=value`` applied."""
    return ClusterParams.from_mapping(_config(args)[0])


def _config(args) -> tuple[dict, dict]:
    """(lidar_cluster, projector) parameters from ``--config`` and ``--set``."""
    import yaml
    data = (yaml.safe_load(Path(args.config).read_text()) or {}) \
        if getattr(args, 'config', None) else {}
    cfg = dict((data.get('lidar_cluster') or {}).get('ros__parameters', {}) or {})
    pcfg = (data.get('projector') or {}).get('ros__parameters', {}) or {}
    for item in getattr(args, 'set', None) or []:
        key, sep, value = item.partition('=')
        if not sep:
            raise LidarClusterError(f'--set needs key=value, got {item!r}')
        cfg[key.strip()] = yaml.safe_load(value)
    return cfg, pcfg


def _scan(args) -> int:
    params = _params(args)
    points = load_scan(args.file, args.topic, args.index)
    res = cluster_cloud(points, params)
    cfg = _config(args)[0]
    explain(points, res, params, (int(cfg.get('persistence_k', 2)),
                                  int(cfg.get('persistence_n', 3))))
    return 0


# --- synthetic bags ----------------------------------------------------------------------

def _odom_pose(msg) -> tuple[int, np.ndarray]:
    from workzone_ros.core.sync import pose_matrix
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    t = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    return t, pose_matrix([p.x, p.y, p.z], [q.x, q.y, q.z, q.w])


def _load_bag(path: Path, frames: Optional[list] = None):
    """Scans (stamp, points), GT per scan stamp, odometry, camera info from a synth bag.

    With ``frames`` (a list), the ``/groundtruth/signs`` payloads (one per camera frame,
    stamped like the image) are appended to it as ``(stamp_ns, GtSigns)``.
    """
    from workzone_ros import bagio, interfaces
    from workzone_ros.core.pointcloud import FieldSpec, cloud_view
    scans, gts, odom, info = [], {}, [], None
    topics = ['/lidar/points', '/groundtruth/lidar', '/odom', '/camera/camera_info']
    if frames is not None:
        topics.append('/groundtruth/signs')
    for item in bagio.read_messages(str(path), topics=topics):
        topic, msg = _topic_msg(item)
        if topic == '/lidar/points':
            fields = [FieldSpec(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
            pts = cloud_view(np.asarray(msg.data), fields, msg.point_step, msg.width,
                             msg.height, msg.row_step, bool(msg.is_bigendian)).copy()
            t = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            scans.append((t, pts))
        elif topic == '/groundtruth/lidar':
            gt = interfaces.decode(msg.data, interfaces.GtLidar)
            gts[gt.header.stamp.to_ns()] = gt
        elif topic == '/odom':
            odom.append(_odom_pose(msg))
        elif topic == '/camera/camera_info' and info is None:
            info = msg
        elif topic == '/groundtruth/signs':
            gs = interfaces.decode(msg.data, interfaces.GtSigns)
            frames.append((gs.header.stamp.to_ns(), gs))
    return scans, gts, odom, info


def _topic_msg(item):
    """bagio.read_messages items: (topic, msg, ...) tuples or objects with .topic/.msg."""
    if isinstance(item, tuple):
        return item[0], item[-1]
    return getattr(item, 'topic'), getattr(item, 'msg', getattr(item, 'message', None))


class _Odom:
    """Pose lookup (odom <- base) from a list of (t, 4x4), interpolated."""

    def __init__(self, odom, base_to_lidar: np.ndarray):
        from workzone_ros.core.sync import PoseBuffer, matrix_to_quat
        self.buf = PoseBuffer(max_age_ns=10 ** 15)
        for t, m in odom:
            self.buf.add(t, m[:3, 3], matrix_to_quat(m[:3, :3]))
        self.b2l = base_to_lidar
        self.speed_mps = _mean_speed(odom)

    def lidar(self, t_ns: int) -> Optional[np.ndarray]:
        m = self.buf.at(int(t_ns))
        return None if m is None else m @ self.b2l


def _open_bag(path: Path, camera: CameraModel, base_to_lidar: np.ndarray, params: ClusterParams,
              k: int, n: int, frames: Optional[list] = None):
    """Scans, ground truth, the bag's camera (else ``camera``), odometry and a fresh
    :class:`LidarStream` (the node's clustering + persistence state)."""
    scans, gts, odom, info = _load_bag(path, frames)
    if info is not None:
        camera = CameraModel(int(info.width), int(info.height),
                             np.asarray(info.k, float).reshape(3, 3),
                             np.asarray(info.d, float), info.distortion_model or 'plumb_bob')
    return scans, gts, camera, _Odom(odom, base_to_lidar), LidarStream(params, k, n)


def in_region(xyz_lidar: np.ndarray, params: ClusterParams) -> np.ndarray:
    """Which lidar-frame points lie in the pre-filter region (ahead, range, left/right)."""
    lvl = params.mount.to_level(np.asarray(xyz_lidar, float).reshape(-1, 3))
    rng = np.hypot(lvl[:, 0], lvl[:, 1])
    return ((lvl[:, 0] >= params.x_min) & (lvl[:, 1] >= -params.right_max)
            & (lvl[:, 1] <= params.left_max) & (rng >= params.range_min)
            & (rng <= params.range_max))


def evaluate_bag(path: Path, params: ClusterParams, k: int, n: int, offset_ms: float,
                 min_gt_points: int, roi_params: RoiParams, camera: CameraModel,
                 lidar_to_camera: np.ndarray, base_to_lidar: np.ndarray) -> dict:
    """Detection and projection figures for one bag (see the module docstring)."""
    scans, gts, camera, od, stream = _open_bag(path, camera, base_to_lidar, params, k, n)
    bands = {b: {'signs': 0, 'missed': 0, 'cands': 0, 'fp': 0} for b in BANDS}
    total = {'scans': 0, 'cands': 0, 'fp': 0, 'signs60': 0, 'missed60': 0}
    err = {'comp': [], 'raw': []}
    offset_ns = int(offset_ms * 1e6)
    for index, (stamp, pts) in enumerate(scans):
        gt = gts.get(stamp)
        cands = stream.process(pts, od.lidar(stamp + 50_000_000)).candidates
        if gt is None or index < k - 1:
            continue            # warm-up: persistence cannot confirm before k scans
        total['scans'] += 1
        pub = cands.subset(cands.confirmed)
        gt_c = np.array([s.center for s in gt.signs], float).reshape(-1, 3)
        gt_n = np.array([len(s.indices) for s in gt.signs], int)
        rng = np.hypot(gt_c[:, 0], gt_c[:, 1]) if len(gt_c) else np.zeros(0)
        counted = (gt_n >= min_gt_points) & in_region(gt_c, params)
        found = np.zeros(len(gt_c), bool)
        cand_ok = np.zeros(len(pub), bool)
        for i in range(len(pub)):
            if len(gt_c) == 0:
                break
            d = np.linalg.norm(gt_c - pub.center[i], axis=1)
            tol = max(1.0, 1.5 * float(pub.radius[i]))
            hit = d <= tol
            cand_ok[i] = hit.any()
            found |= hit
        crng = pub.range
        for lo, hi in BANDS:
            inb = counted & (rng >= lo) & (rng < hi)
            bands[(lo, hi)]['signs'] += int(inb.sum())
            bands[(lo, hi)]['missed'] += int((inb & ~found).sum())
            cb = (crng >= lo) & (crng < hi)
            bands[(lo, hi)]['cands'] += int(cb.sum())
            bands[(lo, hi)]['fp'] += int((cb & ~cand_ok).sum())
        total['cands'] += len(pub)
        total['fp'] += int((~cand_ok).sum())
        total['signs60'] += int((counted & (rng < 60)).sum())
        total['missed60'] += int((counted & (rng < 60) & ~found).sum())
        # Projection error of the sign centre: each published candidate matched to a sign
        # is projected into an image taken offset_ms after the LiDAR fired at the sign.
        for i in range(len(pub)):
            if len(gt_c) == 0 or not cand_ok[i]:
                continue
            j = int(np.argmin(np.linalg.norm(gt_c - pub.center[i], axis=1)))
            if not counted[j]:
                continue
            t_fire = int(point_times(gt_c[j:j + 1], stamp, roi_params.lidar_rate_hz,
                                     roi_params.start_azimuth, roi_params.clockwise)[0])
            t_img = t_fire + offset_ns
            l_fire, l_img = od.lidar(t_fire), od.lidar(t_img)
            if l_fire is None or l_img is None:
                continue
            # Truth: the ground-truth face centre (lidar frame at its firing time) moved to
            # the lidar frame at the image time with the simulator's exact odometry.
            truth = compensate(gt_c[j:j + 1], l_fire, l_img)
            p_true = project_points(truth, lidar_to_camera, camera)
            if not p_true.in_image[0]:
                continue
            arr = np.zeros(1, [('x', 'f8'), ('y', 'f8'), ('z', 'f8'), ('radius', 'f8')])
            arr['x'], arr['y'], arr['z'] = pub.center[i]
            arr['radius'] = pub.radius[i]
            for key, fn in (('comp', od.lidar), ('raw', None)):
                rois, ok = candidates_to_rois(arr, stamp, t_img, camera, lidar_to_camera, fn,
                                              roi_params)
                if rois and (ok or fn is None):
                    err[key].append(float(np.hypot(*(np.array(rois[0].center)
                                                     - p_true.uv[0]))))
    speed = od.speed_mps
    return {'bag': str(path), 'speed_mps': speed, 'bands': bands, 'total': total,
            'err': err, 'why': stream.summary()}


def _mean_speed(odom) -> float:
    if len(odom) < 2:
        return 0.0
    (t0, a), (t1, b) = odom[0], odom[-1]
    return float(np.linalg.norm(b[:3, 3] - a[:3, 3]) / max((t1 - t0) * 1e-9, 1e-9))


def _pct(a, q):
    return float(np.percentile(a, q)) if len(a) else float('nan')


def _synthetic(args) -> int:
    cfg, pcfg = _config(args)
    params = ClusterParams.from_mapping(cfg)
    k = int(cfg.get('persistence_k', 2))
    n = int(cfg.get('persistence_n', 3))
    t_l2c = extrinsics_from_list(pcfg.get('lidar_to_camera', list(np.array(
        [[0, -1, 0, 0], [0, 0, -1, -0.5], [1, 0, 0, -0.6], [0, 0, 0, 1]], float).ravel())))
    b2l = np.eye(4)
    b2l[:3, 3] = pcfg.get('lidar_in_base', [1.0, 0.0, 1.95])[:3]
    from workzone_ros.sim.world import DEFAULT_CAMERA
    cam = CameraModel(DEFAULT_CAMERA.width, DEFAULT_CAMERA.height, DEFAULT_CAMERA.K,
                      DEFAULT_CAMERA.D)
    results = []
    for bag in args.bags:
        r = evaluate_bag(Path(bag), params, k, n, args.offset_ms, args.min_gt_points,
                         RoiParams(), cam, t_l2c, b2l)
        results.append(r)
        _print_result(r, args.offset_ms)
    if len(results) > 1:
        merged = _merge(results)
        print('== all bags')
        _print_result(merged, args.offset_ms)
        results.append(merged)
    if args.json:
        Path(args.json).write_text(json.dumps(_jsonable(results), indent=2))
    return 0


def _merge(results):
    bands = {b: {k: sum(r['bands'][b][k] for r in results) for k in
                 ('signs', 'missed', 'cands', 'fp')} for b in BANDS}
    total = {k: sum(r['total'][k] for r in results) for k in results[0]['total']}
    err = {k: sum((r['err'][k] for r in results), []) for k in ('comp', 'raw')}
    return {'bag': 'all', 'speed_mps': float('nan'), 'bands': bands, 'total': total,
            'err': err}


def _print_result(r, offset_ms):
    t = r['total']
    fp = t['fp'] / max(t['cands'], 1)
    miss = t['missed60'] / max(t['signs60'], 1)
    print(f'== {r["bag"]} (ego {r["speed_mps"]:.1f} m/s): {t["scans"]} scans, '
          f'{t["cands"]} published candidates, FP {t["fp"]} ({100 * fp:.2f} %), '
          f'FP per scan {t["fp"] / max(t["scans"], 1):.3f}; within 60 m: '
          f'{t["signs60"]} sign-scans, missed {t["missed60"]} ({100 * miss:.2f} %)')
    for (lo, hi), b in r['bands'].items():
        print(f'   {lo:>4.0f}-{hi:<3.0f} m: signs {b["signs"]:5d} missed {b["missed"]:4d} '
              f'({100 * b["missed"] / max(b["signs"], 1):5.1f} %)   candidates '
              f'{b["cands"]:5d} FP {b["fp"]:4d} ({100 * b["fp"] / max(b["cands"], 1):5.1f} %)')
    if r.get('why'):
        print(f'   {r["why"]}')
    for key, name in (('comp', 'with compensation'), ('raw', 'without')):
        e = r['err'][key]
        print(f'   projection error {name} (image {offset_ms:.0f} ms after the firing): '
              f'median {_pct(e, 50):.2f} px, p95 {_pct(e, 95):.2f} px, n={len(e)}')


def _jsonable(obj):
    if isinstance(obj, dict):
        return {(f'{k[0]:.0f}-{k[1]:.0f}' if isinstance(k, tuple) else k): _jsonable(v)
                for k, v in obj.items()}
    if isinstance(obj, list):
        if obj and isinstance(obj[0], float) and len(obj) > 20:
            return {'n': len(obj), 'median': _pct(obj, 50), 'p95': _pct(obj, 95)}
        return [_jsonable(v) for v in obj]
    return obj


# --- synchronisation policies --------------------------------------------------------------

#: Policies compared by ``sync``: name -> (policy, overrides).  ``forward`` = the projector's
#: ``sync_forward_time`` (match the time the spin looks forward, not the cloud stamp).
SYNC_VARIANTS = {
    'approximate': ('approximate', {}),
    'latest': ('latest', {}),
    'nearest-stamp': ('nearest', {'forward': False}),
    'nearest': ('nearest', {'forward': True}),            # the projector's default
    'nearest-nowait': ('nearest', {'forward': True, 'max_wait_ns': 0}),
}


def pair_stream(events, policy: str, slop_ns: int, queue_size: int = 5,
                age_penalty: float = 0.1, period_ns: int = 100_000_000,
                max_wait_ns: int = 150_000_000, time_offset_ns: int = 0) -> dict:
    """Run one synchronisation policy over arrival-ordered events.

    Args:
        events: ``(arrival_ns, kind, stamp_ns, payload)`` sorted by arrival; kind 'image' or
            'cands'.
        policy: 'approximate', 'latest' or 'nearest' (as the projector's ``sync_policy``).

    Returns:
        ``{image_stamp: (set_stamp, set, decided_at_ns)}`` for the images that got a set.
    """
    out: dict = {}
    if policy == 'approximate':
        sync = ApproximateTimeSync(2, queue_size, slop_ns, age_penalty)
        for arrival, kind, stamp, payload in events:
            for (t_img, t_set), (_, cands) in sync.add(0 if kind == 'image' else 1, stamp,
                                                       payload):
                out[t_img] = (t_set, cands, arrival)
    elif policy == 'latest':
        latest = LatestSync()
        for arrival, kind, stamp, payload in events:
            if kind == 'cands':
                latest.add_cloud(stamp, payload)
            else:
                got = latest.add_image(stamp)
                if got is not None:
                    out[stamp] = (got[0], got[1], arrival)
    elif policy == 'nearest':
        near = NearestSync(slop_ns, period_ns, max_wait_ns, time_offset_ns,
                           history=max(queue_size, 2), max_pending=max(queue_size, 2))
        for arrival, kind, stamp, payload in events:
            got = near.add_image(stamp) if kind == 'image' else \
                near.add_candidates(stamp, payload)
            for t_img, _, t_set, cands in got:
                if cands is not None:
                    out[t_img] = (t_set, cands, arrival)
    else:
        raise ValueError(f'unknown policy {policy!r}')
    return out


def evaluate_sync(path: Path, params: ClusterParams, k: int, n: int, variants: dict,
                  slop_ns: int, cloud_delay_ns: int, image_delay_ns: int, max_range: float,
                  roi_params: RoiParams, camera: CameraModel, lidar_to_camera: np.ndarray,
                  base_to_lidar: np.ndarray, sync_kw: dict) -> dict:
    """Per-policy ROI coverage, centre error and stamp gaps on one bag (module docstring)."""
    frames: list = []
    scans, gts, camera, od, stream = _open_bag(path, camera, base_to_lidar, params, k, n,
                                               frames)
    half_spin = forward_time_offset(roi_params) or int(0.5e9 / roi_params.lidar_rate_hz)
    events, detected = [], set()
    for stamp, pts in scans:             # as lidar_cluster: clustering + persistence
        cands = stream.process(pts, od.lidar(stamp + half_spin)).candidates
        arr = candidates_to_array(cands)
        gt = gts.get(stamp)
        if gt is not None and len(gt.signs) and len(arr):
            gt_c = np.array([s.center for s in gt.signs], float)
            xyz = np.column_stack([arr['x'], arr['y'], arr['z']]).astype(float)
            d = np.linalg.norm(gt_c[:, None, :] - xyz[None, :, :], axis=2)
            hit = (d <= np.maximum(1.0, 1.5 * arr['radius'].astype(float))[None, :]).any(1)
            detected.update(s.sign_id for s, h in zip(gt.signs, hit) if h)
        events.append((stamp + cloud_delay_ns, 0, 'cands', stamp, arr))
    for stamp, gs in frames:
        events.append((stamp + image_delay_ns, 1, 'image', stamp, gs))
    events.sort(key=lambda e: (e[0], e[1], e[3]))
    events = [(a, kind, t, p) for a, _, kind, t, p in events]
    out = {'bag': str(path), 'speed_mps': od.speed_mps, 'frames': len(frames),
           'policies': {}}
    for name, (policy, over) in variants.items():
        kw = dict(sync_kw)
        kw.update(over)
        if kw.pop('forward', False):
            kw['time_offset_ns'] = forward_time_offset(roi_params)
        pairs = pair_stream(events, policy, slop_ns, **kw)
        r = {'paired': len(pairs), 'sign_frames': 0, 'covered': 0, 'det_sign_frames': 0,
             'det_covered': 0, 'err': [], 'err_raw': [], 'dt': [], 'dt_fwd': [], 'wait': []}
        for t_img, gs in frames:
            signs = [s for s in gs.signs if s.distance_m <= max_range]
            got = pairs.get(t_img)
            rois, rois_raw = [], []
            if got is not None:
                t_set, arr, decided = got
                r['dt'].append(abs(t_img - t_set) * 1e-6)
                r['dt_fwd'].append(abs(t_img - t_set - half_spin) * 1e-6)
                r['wait'].append((decided - t_img - image_delay_ns) * 1e-6)
                if signs:
                    rois, _ = candidates_to_rois(arr, t_set, t_img, camera, lidar_to_camera,
                                                 od.lidar, roi_params)
                    rois_raw, _ = candidates_to_rois(arr, t_set, t_img, camera,
                                                     lidar_to_camera, None, roi_params)
            for s in signs:
                det = s.sign_id in detected
                r['sign_frames'] += 1
                r['det_sign_frames'] += det
                c = np.array([s.box.x + s.box.w / 2, s.box.y + s.box.h / 2])
                for key, rs in (('err', rois), ('err_raw', rois_raw)):
                    inside = [np.hypot(*(np.array(q.center) - c)) for q in rs
                              if q.box.x <= c[0] <= q.box.x + q.box.w
                              and q.box.y <= c[1] <= q.box.y + q.box.h]
                    if inside:
                        r[key].append(float(min(inside)))
                        if key == 'err':
                            r['covered'] += 1
                            r['det_covered'] += det
        out['policies'][name] = r
    return out


def _sync(args) -> int:
    cfg, pcfg = _config(args)
    params = ClusterParams.from_mapping(cfg)
    k = int(cfg.get('persistence_k', 2))
    n = int(cfg.get('persistence_n', 3))
    t_l2c = extrinsics_from_list(pcfg['lidar_to_camera']) if 'lidar_to_camera' in pcfg else \
        extrinsics_from_list(list(np.array([[0, -1, 0, 0], [0, 0, -1, -0.5], [1, 0, 0, -0.6],
                                            [0, 0, 0, 1]], float).ravel()))
    b2l = np.eye(4)
    b2l[:3, 3] = pcfg.get('lidar_in_base', [1.0, 0.0, 1.95])[:3]
    from workzone_ros.sim.world import DEFAULT_CAMERA
    cam = CameraModel(DEFAULT_CAMERA.width, DEFAULT_CAMERA.height, DEFAULT_CAMERA.K,
                      DEFAULT_CAMERA.D)
    variants = {k_: v for k_, v in SYNC_VARIANTS.items()
                if not args.policies or k_ in args.policies}
    sync_kw = dict(queue_size=args.queue_size, age_penalty=args.age_penalty,
                   period_ns=int(1e9 / RoiParams().lidar_rate_hz),
                   max_wait_ns=int(args.max_wait * 1e9))
    results = []
    for bag in args.bags:
        r = evaluate_sync(Path(bag), params, k, n, variants, int(args.slop * 1e9),
                          int(args.cloud_delay_ms * 1e6), int(args.image_delay_ms * 1e6),
                          args.max_range, RoiParams(), cam, t_l2c, b2l, sync_kw)
        results.append(r)
        _print_sync(r, args)
    if len(results) > 1:
        merged = {'bag': 'all bags', 'speed_mps': float('nan'),
                  'frames': sum(r['frames'] for r in results), 'policies': {}}
        for name in variants:
            rs = [r['policies'][name] for r in results]
            merged['policies'][name] = {key: (sum((x[key] for x in rs), []) if isinstance(
                rs[0][key], list) else sum(x[key] for x in rs)) for key in rs[0]}
        _print_sync(merged, args)
        results.append(merged)
    if args.json:
        Path(args.json).write_text(json.dumps(_jsonable(results), indent=2))
    return 0


def _print_sync(r, args) -> None:
    print(f'== {r["bag"]} (ego {r["speed_mps"]:.1f} m/s): {r["frames"]} camera frames, slop '
          f'{args.slop * 1e3:.0f} ms, candidates arrive {args.cloud_delay_ms:.0f} ms after the '
          f'scan stamp, images {args.image_delay_ms:.0f} ms after theirs')
    print(f'   {"policy":<20} {"frames w/ ROIs":>14} {"covered (all)":>18} '
          f'{"covered (LiDAR-det.)":>20} {"err med/p95 px":>15} {"uncomp med/p95":>15} '
          f'{"|dt| ms":>8} {"|dt fwd|":>8} {"wait ms":>8}')
    for name, p in r['policies'].items():
        f = r['frames']
        cov = f'{p["covered"]}/{p["sign_frames"]} ' \
              f'{100 * p["covered"] / max(p["sign_frames"], 1):5.1f}%'
        det = f'{p["det_covered"]}/{p["det_sign_frames"]} ' \
              f'{100 * p["det_covered"] / max(p["det_sign_frames"], 1):5.1f}%'
        print(f'   {name:<20} {100 * p["paired"] / max(f, 1):13.1f}% {cov:>18} {det:>20} '
              f'{_pct(p["err"], 50):6.2f}/{_pct(p["err"], 95):<8.2f} '
              f'{_pct(p["err_raw"], 50):6.2f}/{_pct(p["err_raw"], 95):<8.2f} '
              f'{np.mean(p["dt"]) if p["dt"] else float("nan"):8.1f} '
              f'{np.mean(p["dt_fwd"]) if p["dt_fwd"] else float("nan"):8.1f} '
              f'{np.mean(p["wait"]) if p["wait"] else float("nan"):8.1f}')


def main(argv: Optional[list[str]] = None) -> int:
    """``workzone-ros evaluate lidar {synthetic,sync,realdata,scan,sensors} ...``."""
    parser = argparse.ArgumentParser(prog='workzone-ros evaluate lidar', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='mode', required=True)
    sets = dict(action='append', metavar='KEY=VALUE',
                help='override a lidar_cluster parameter (repeatable), e.g. left_max=4')
    s = sub.add_parser('synthetic', help='FP / missed by range band and projection error')
    s.add_argument('bags', nargs='+', help='bags written by workzone-ros synth')
    s.add_argument('--config', default='config/workzone.yaml',
                   help='parameters file (lidar_cluster and projector sections)')
    s.add_argument('--set', **sets)
    s.add_argument('--offset-ms', type=float, default=50.0,
                   help='image time after the scan stamp for the projection error')
    s.add_argument('--min-gt-points', type=int, default=3,
                   help='a sign counts in a scan with at least this many face returns')
    s.add_argument('--json', help='write the figures to this JSON file')
    y = sub.add_parser('sync', help='compare the projector synchronisation policies')
    y.add_argument('bags', nargs='+', help='bags written by workzone-ros synth')
    y.add_argument('--config', default='config/workzone.yaml',
                   help='parameters file (lidar_cluster and projector sections)')
    y.add_argument('--set', **sets)
    y.add_argument('--policies', nargs='*', choices=list(SYNC_VARIANTS),
                   help='variants to compare (default: all)')
    y.add_argument('--slop', type=float, default=0.1, help='s (the projector default)')
    y.add_argument('--max-wait', type=float, default=0.15, help='nearest: s (image clock)')
    y.add_argument('--queue-size', type=int, default=5)
    y.add_argument('--age-penalty', type=float, default=0.1)
    y.add_argument('--cloud-delay-ms', type=float, default=110.0,
                   help='candidates arrive this long after their scan stamp (spin + work)')
    y.add_argument('--image-delay-ms', type=float, default=5.0,
                   help='images arrive this long after their stamp')
    y.add_argument('--max-range', type=float, default=60.0, help='GT signs up to this far, m')
    y.add_argument('--json', help='write the figures to this JSON file')
    r = sub.add_parser('realdata', help='the PJLab scenes: every cluster and why, ROIs, '
                                        'overlays')
    here = Path(__file__).resolve().parents[2]
    r.add_argument('dir', nargs='?', default=str(here.parent / 'shared' / 'realdata'
                                                 / 'lidar_camera_pjlab'))
    r.add_argument('--config', help='parameters file (default: the built-in defaults)')
    r.add_argument('--set', **sets)
    r.add_argument('--out', default='/tmp/workzone_lidar_realdata')
    c = sub.add_parser('scan', help='one scan of yours: what was inferred, every cluster and '
                                    'why it was kept or rejected')
    c.add_argument('file', help='.pcd, .bin (float32 x y z intensity), .npy (structured) or '
                                'a bag')
    c.add_argument('--topic', default='/lidar/points', help='bag topic')
    c.add_argument('--index', type=int, default=0, help='which message of the bag topic')
    c.add_argument('--config', help='parameters file (lidar_cluster section)')
    c.add_argument('--set', **sets)
    from workzone_ros.tools import eval_lidar_sensors
    w = sub.add_parser('sensors', help='simulated LiDARs x mounting heights x intensity '
                                       'encodings x axes, in process (no bags)')
    eval_lidar_sensors.add_arguments(w)
    w.add_argument('--set', **sets)
    args = parser.parse_args(argv)
    modes = {'synthetic': _synthetic, 'sync': _sync, 'realdata': _realdata, 'scan': _scan,
             'sensors': eval_lidar_sensors.run}
    try:
        return modes[args.mode](args)
    except (LidarClusterError, ScanFormatError, PcdError, OSError) as exc:
        print(f'evaluate lidar {args.mode}: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
