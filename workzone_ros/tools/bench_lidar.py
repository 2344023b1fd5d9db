"""``workzone-ros bench lidar``: LiDAR message -> sign candidates per scan, on one core.

Per scan of ~130k points (a simulator scan of a work-zone scenario, ``sim.lidar.cast_scan``,
or a synthetic cloud with ``--synthetic``): the PointCloud2 message bytes are viewed as a
structured array (zero copy, ``core.pointcloud.cloud_view``) and run through the node's path
(``core.lidar_stream.LidarStream``: intensity scale, ground-plane fit, pre-filter, region
growing on the voxel graph, check-to-add with the plate, contrast, hollow and reflectors
tests, persistence), then packed into the candidates layout.  Reported: p50 / p99 ms over
``--repeat`` runs of every scan, wall clock and process CPU time (on a shared machine the
wall clock includes waiting for the core).

In the same run, clustering alone with a fixed radius against scikit-learn's DBSCAN (same
radius, ``min_samples=1``, same pre-filtered points): the two partitions are checked to be
identical (pairwise label agreement) and the speed ratio is reported.

Thread pools are limited to one thread (OMP/OpenBLAS/MKL) before numpy is imported when
this module is the first to import it; the figures are for one core.
"""
from __future__ import annotations

import os
import time

for _v in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_v, '1')

import numpy as np  # noqa: E402

__all__ = ['add_arguments', 'run', 'make_scans']


def add_arguments(parser) -> None:
    """Options of ``bench lidar``."""
    parser.add_argument('--scenario', default='demo', help='simulator scenario for the scans')
    parser.add_argument('--scans', type=int, default=6, help='distinct scans')
    parser.add_argument('--repeat', type=int, default=30, help='runs per scan')
    parser.add_argument('--radius', type=float, default=0.3,
                        help='fixed radius for the DBSCAN comparison, m')
    parser.add_argument('--synthetic', action='store_true',
                        help='a synthetic 130k-point cloud instead of the simulator')


def _synthetic_scan(seed: int) -> np.ndarray:
    """A 64-ring x 2118-column cloud: ground, a few sign plates, drum bands, a guardrail."""
    from workzone_ros.core.pointcloud import make_points
    rng = np.random.default_rng(seed)
    el = np.radians(np.linspace(-24.8, 2.0, 64))
    az = np.pi - 2 * np.pi * np.arange(2118) / 2118
    e, a = np.meshgrid(el, az)
    d = np.column_stack([np.cos(e).ravel() * np.cos(a).ravel(),
                         np.cos(e).ravel() * np.sin(a).ravel(), np.sin(e).ravel()])
    r = np.where(d[:, 2] < -1e-3, 1.95 / np.maximum(-d[:, 2], 1e-3), 100.0)
    r = np.minimum(r, 100.0) + rng.normal(0, 0.02, r.size)
    xyz = d * r[:, None]
    inten = rng.uniform(2, 40, r.size)
    for k in range(5):                             # sign plates at the right shoulder
        x0, y0 = 15 + 15 * k, -10.3
        hit = (np.abs(xyz[:, 0] - x0) < 60) & (d[:, 0] > 0)
        t = (x0 - 0.0) / np.maximum(d[:, 0], 1e-6)
        py, pz = d[:, 1] * t, d[:, 2] * t
        face = hit & (np.abs(py - y0) < 0.6) & (np.abs(pz - 0.8) < 0.6) & (t < r)
        xyz[face] = d[face] * t[face, None]
        inten[face] = rng.uniform(190, 240, face.sum())
    keep = rng.random(r.size) > 0.02
    xyz, inten = xyz[keep].astype(np.float32), inten[keep].astype(np.float32)
    ring = np.tile(np.arange(64, dtype=np.uint16), 2118)[keep]
    return make_points(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], intensity=inten, ring=ring)


def make_scans(scenario: str, n: int, synthetic: bool = False) -> tuple[list, str]:
    """``n`` scans (structured arrays) and a description of where they come from."""
    if not synthetic:
        try:
            from workzone_ros.sim.lidar import cast_scan
            from workzone_ros.sim.scenario import build_scene, load_scenario
            from workzone_ros.sim.writer import lidar_scene
            spec = load_scenario(scenario)
            scene, ego, _ = build_scene(spec, 0)
            # Scans spread over the run, so signs and drums are in view at several ranges.
            times = np.linspace(2.0, max(spec.duration - 2.0, 3.0), n)
            scans = [cast_scan(lidar_scene(scene, float(t)), float(t), ego.lidar_pose,
                               seed=0, scan_index=i).points for i, t in enumerate(times)]
            return scans, f'simulator scenario {scenario!r}, t = {times.round(1).tolist()} s'
        except Exception as exc:  # noqa: BLE001 - the simulator is optional here
            print(f'simulator unavailable ({exc}); using synthetic clouds')
    return [_synthetic_scan(i) for i in range(n)], 'synthetic clouds'


def _to_message_bytes(points: np.ndarray):
    """The PointCloud2 wire layout (x, y, z, intensity float32, ring uint16; padded)."""
    from workzone_ros.core.pointcloud import FieldSpec
    dt = np.dtype({'names': ['x', 'y', 'z', 'intensity', 'ring'],
                   'formats': ['<f4', '<f4', '<f4', '<f4', '<u2'],
                   'offsets': [0, 4, 8, 12, 16], 'itemsize': 32})
    arr = np.zeros(points.shape[0], dt)
    for name in dt.names:
        arr[name] = points[name]
    fields = [FieldSpec('x', 0, 7), FieldSpec('y', 4, 7), FieldSpec('z', 8, 7),
              FieldSpec('intensity', 12, 7), FieldSpec('ring', 16, 4)]
    return arr.tobytes(), fields, 32, arr.shape[0]


def _same_partition(a: np.ndarray, b: np.ndarray) -> bool:
    pairs = np.unique(np.column_stack([a, b]), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


def run(args) -> dict:
    """Measure and return the figures."""
    from workzone_ros.core.lidar_clustering import (
        ClusterParams,
        candidates_to_array,
        prefilter,
        region_grow,
        scan_geometry,
    )
    from workzone_ros.core.lidar_stream import LidarStream
    from workzone_ros.core.pointcloud import cloud_view
    params = ClusterParams()
    scans, source = make_scans(args.scenario, args.scans, args.synthetic)
    msgs = [_to_message_bytes(s) for s in scans]
    stream = LidarStream(params)          # the node's path: scale, ground fit, persistence
    times, cpu = [], []
    n_points, n_filtered, n_cands = [], [], []
    for data, fields, step, n in msgs:
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            pts = cloud_view(data, fields, step, n, 1, n * step)
            out = stream.process(pts)
            res = out.result
            candidates_to_array(out.candidates, only_confirmed=False)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        n_points.append(n)
        n_filtered.append(len(res.points))
        n_cands.append(len(res.candidates))
    ms = np.array(times) * 1e3
    cpu_ms = np.array(cpu) * 1e3

    # Ours (fixed radius) vs scikit-learn DBSCAN(min_samples=1) on the same filtered points.
    # The pre-filter is opened up (lower intensity, no region limit) so the comparison runs
    # on a few thousand points, dense sign faces included.
    from sklearn.cluster import DBSCAN
    wide = params.with_(min_intensity=60.0)
    ours_t, sk_t, same, sizes = [], [], True, []
    for data, fields, step, n in msgs:
        pts = cloud_view(data, fields, step, n, 1, n * step)
        mount, ground, _, _ = scan_geometry(pts, wide)
        xyz = prefilter(pts, wide, 1.0, mount, ground).level
        sizes.append(len(xyz))
        if len(xyz) < 2:
            continue
        reps = max(3, args.repeat // 5)
        for _ in range(reps):
            t0 = time.perf_counter()
            a = region_grow(xyz, args.radius)
            ours_t.append(time.perf_counter() - t0)
        for _ in range(max(1, reps // 3)):
            t0 = time.perf_counter()
            b = DBSCAN(eps=args.radius, min_samples=1, algorithm='kd_tree',
                       n_jobs=1).fit_predict(xyz)
            sk_t.append(time.perf_counter() - t0)
        same &= _same_partition(a, b)
    ours_ms, sk_ms = float(np.median(ours_t) * 1e3), float(np.median(sk_t) * 1e3)
    return {
        'source': source,
        'points_per_scan': int(np.mean(n_points)),
        'prefiltered_points_per_scan': float(np.mean(n_filtered)),
        'candidates_per_scan': float(np.mean(n_cands)),
        'runs': int(ms.size),
        'message_to_candidates_ms_p50': round(float(np.percentile(ms, 50)), 3),
        'message_to_candidates_ms_p99': round(float(np.percentile(ms, 99)), 3),
        'message_to_candidates_ms_max': round(float(ms.max()), 3),
        # CPU time of this process (same runs): what the scan costs when the core is shared.
        'message_to_candidates_cpu_ms_p50': round(float(np.percentile(cpu_ms, 50)), 3),
        'message_to_candidates_cpu_ms_p99': round(float(np.percentile(cpu_ms, 99)), 3),
        'dbscan_compare_points_per_scan': float(np.mean(sizes)),
        'dbscan_radius_m': args.radius,
        'ours_fixed_radius_ms_median': round(ours_ms, 3),
        'sklearn_dbscan_ms_median': round(sk_ms, 3),
        'speedup_vs_dbscan': round(sk_ms / max(ours_ms, 1e-9), 2),
        'same_partition': bool(same),
    }
