"""One LiDAR scan explained: what the candidate stage inferred and why each cluster went.

Used by ``workzone-ros evaluate lidar scan FILE`` (a user's own scan: ``.pcd``, a KITTI-style
``.bin`` of float32 x y z intensity, a ``.npy`` structured array, or a rosbag2 / ROS 1 bag
whose first PointCloud2 on ``--topic`` is taken) and ``evaluate lidar realdata`` (the PJLab
scenes with their camera): the intensity encoding, the mounting and the road, where the
points went (bright, in the region, in the height band), every cluster of 3 points or more
with its measurements and the first test that rejected it, the candidates with their ROI
sizes, and that a live node holds a candidate until persistence confirms it.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional, TextIO

import numpy as np

from workzone_ros.core.lidar_clustering import REJECT_REASONS, ClusterParams, ClusterResult
from workzone_ros.core.lidar_intensity import ENCODINGS, infer_encoding, intensity_summary

__all__ = ['load_scan', 'explain', 'ScanFormatError']


class ScanFormatError(ValueError):
    """A file the scan loader cannot read; the message says what it expected."""


def load_scan(path: str, topic: str = '/lidar/points', index: int = 0) -> np.ndarray:
    """Read one scan into a structured array (x, y, z, intensity, ...).

    Raises:
        ScanFormatError: unknown extension, a malformed file, or a bag without the topic.
    """
    p = Path(path)
    if p.is_dir() or p.suffix in ('.mcap', '.db3', '.bag'):
        from workzone_ros import bagio
        from workzone_ros.core.pointcloud import FieldSpec, cloud_view
        seen = 0
        for _, _, msg in bagio.read_messages(str(p), topics=[topic]):
            if seen == index:
                fields = [FieldSpec(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
                return cloud_view(np.asarray(msg.data), fields, msg.point_step, msg.width,
                                  msg.height, msg.row_step, bool(msg.is_bigendian)).copy()
            seen += 1
        raise ScanFormatError(f'{p}: no message {index} on {topic} ({seen} found)')
    if p.suffix == '.pcd':
        from workzone_ros.core.pcd import read_pcd
        return read_pcd(p)
    if p.suffix == '.bin':
        raw = np.fromfile(p, dtype='<f4')
        if raw.size % 4:
            raise ScanFormatError(f'{p}: a .bin scan is float32 x y z intensity per point; '
                                  f'{raw.size} values is not a multiple of 4')
        a = raw.reshape(-1, 4)
        out = np.zeros(a.shape[0], [('x', '<f4'), ('y', '<f4'), ('z', '<f4'),
                                    ('intensity', '<f4')])
        out['x'], out['y'], out['z'], out['intensity'] = a.T
        return out
    if p.suffix == '.npy':
        a = np.load(p, allow_pickle=False)
        if a.dtype.names is None:
            raise ScanFormatError(f'{p}: expected a structured array with x, y, z, intensity')
        return a
    raise ScanFormatError(f'{p}: unknown scan format (.pcd, .bin, .npy, or a bag)')


def _f(v: float, fmt: str = '.2f') -> str:
    return '-' if v is None or not np.isfinite(v) else format(v, fmt)


def explain(points: np.ndarray, res: ClusterResult, params: ClusterParams,
            persistence: tuple[int, int] = (2, 3), out: Optional[TextIO] = None,
            min_points: int = 3) -> None:
    """Print what the stage inferred and why each cluster was kept or rejected."""
    import sys
    w = (out or sys.stdout).write
    raw = points['intensity'] if 'intensity' in (points.dtype.names or ()) else None
    if raw is not None:
        s = intensity_summary(raw)
        enc = ENCODINGS[infer_encoding(raw.dtype, s[3] if s else float('nan'))]
        how = 'intensity_scale' if params.intensity_scale else f'inferred: {enc.name}'
        w(f'intensity: {raw.dtype}, raw {_f(s[0] if s else None, "g")}..'
          f'{_f(s[3] if s else None, "g")} (median {_f(s[1] if s else None, "g")}), scale '
          f'x{res.scale:.6g} ({how}); min_intensity {params.min_intensity:g} in 0-255 units\n')
    w(f'mounting: {res.mount.describe() if res.mount else "?"}\n')
    w(f'road: {res.ground.describe()}\n')
    spacing = '-' if not np.isfinite(res.beam_spacing) else \
        f'{math.degrees(res.beam_spacing):.2f} deg'
    w(f'beam spacing (ring field): {spacing}\n')
    f = res.funnel
    w(f'points {f.get("points", 0)} -> bright {f.get("bright", 0)} -> in region '
      f'{f.get("region", 0)} (ahead >= {params.x_min:g} m, {params.range_min:g}-'
      f'{params.range_max:g} m, {params.right_max:g} m right / {params.left_max:g} m left) '
      f'-> in height band {f.get("height", 0)} ({params.min_point_height:g}-'
      f'{params.max_point_height:g} m above the road) -> {res.n_clusters} clusters\n')
    t = res.clusters
    shown = [c for c in range(res.n_clusters) if t['count'][c] >= min_points]
    if shown:
        w(f'clusters of {min_points}+ points (lidar frame; top above the road; contrast = '
          f'median / p90 of the dull returns around):\n')
        w(f'  {"#":>4} {"x":>7} {"y":>7} {"z":>6} {"pts":>4} {"rows":>4} {"top":>5} '
          f'{"width":>5} {"height":>6} {"int.":>5} {"contr.":>6} {"incid.":>6}  verdict\n')
    for c in shown:
        x, y, z = t['center'][c]
        why = 'CANDIDATE' if res.reason[c] < 0 else REJECT_REASONS[res.reason[c]]
        w(f'  {c:4d} {x:7.1f} {y:7.1f} {z:6.2f} {t["count"][c]:4d} {t["rows"][c]:4d} '
          f'{t["top"][c]:5.2f} {t["width"][c]:5.2f} {t["height"][c]:6.2f} '
          f'{t["intensity"][c]:5.0f} {_f(t["contrast"][c]):>6} {_f(t["incidence"][c], ".0f"):>6}'
          f'  {why}\n')
    hidden = res.n_clusters - len(shown)
    if hidden:
        w(f'  ({hidden} clusters of fewer than {min_points} points not listed)\n')
    c = res.candidates
    w(f'candidates: {len(c)}' + (f' -- {res.why_empty()}' if not len(c) else '') + '\n')
    for i in range(len(c)):
        hw, hh, dz = c.half_size[i]
        above = f', box centre {dz:.2f} m higher (cut by the top ring)' if dz > 0 else ''
        size = f'measured half size {hw:.2f} x {hh:.2f} m{above}' if hw > 0 else \
            'single ring: size not measured (ROI from the radius, minimum 0.6 m)'
        w(f'  #{int(c.ids[i])}: {c.count[i]} pts on {c.rows[i]} ring(s) at '
          f'({c.center[i, 0]:.1f}, {c.center[i, 1]:.1f}, {c.center[i, 2]:.2f}), {size}\n')
    k, n = persistence
    if len(c) and k > 1:
        w(f'note: a live lidar_cluster publishes a candidate once it was seen in {k} of the '
          f'last {n} scans (persistence_k / persistence_n); from this one scan it publishes '
          f'nothing (persistence_k 1 publishes single scans)\n')
