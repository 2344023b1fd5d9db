"""``lidar_cluster`` node: ``/lidar/points`` -> ``/workzone/lidar/candidates`` (seed 004 s1).

Thin wrapper around :mod:`workzone_ros.core.lidar_clustering`: view the cloud without copies,
pre-filter, region-grow, check-to-add, then persistence k of n with stable ids (matched in
the odometry frame when ``/odom`` is available).  Publishes the confirmed candidates as a
PointCloud2 with fields x, y, z, radius, intensity (float32), count, id (uint32), stamped
like the scan, and optionally the clustered points (x, y, z, intensity, label) for RViz.
"""
from __future__ import annotations

from dataclasses import fields
from typing import Any, Optional

import numpy as np
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2

from workzone_ros.core.lidar_clustering import (
    CandidateTracker,
    ClusterParams,
    LidarClusterError,
    candidates_to_array,
    cluster_cloud,
)
from workzone_ros.core.pointcloud import make_points
from workzone_ros.core.projection import euler_matrix
from workzone_ros.core.sync import PoseBuffer, SyncError
from workzone_ros.nodes.base import InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import array_to_pointcloud2, pointcloud2_to_array

__all__ = ['LidarClusterNode', 'NODE_CLASS', 'main', 'CORE_PARAMS']

_D = ClusterParams()
_HELP = {
    'min_intensity': ('pre-filter: minimum intensity (sensor units)', 0.0, 65535.0),
    'z_min': ('pre-filter: lowest z in the lidar frame, m (per point)', -20.0, 20.0),
    'min_top': ('check-to-add: the cluster top must reach this z (sign height), m', -20.0,
                50.0),
    'thin_height': ('check-to-add: clusters taller than this are tested for poles, m', 0.0,
                    100.0),
    'max_aspect': ('check-to-add: a pole is taller than max_aspect x its width', 0.0, 1000.0),
    'z_max': ('pre-filter: highest z in the lidar frame, m', -20.0, 50.0),
    'range_min': ('pre-filter: nearest horizontal range, m', 0.0, 500.0),
    'range_max': ('pre-filter: farthest horizontal range, m', 0.0, 500.0),
    'x_min': ('pre-filter: only points at least this far ahead, m', -500.0, 500.0),
    'right_max': ('pre-filter: reach of the region to the right, m', 0.0, 500.0),
    'center_left': ('pre-filter: reach to the left without include_left (overhead), m',
                    -500.0, 500.0),
    'include_left': ('pre-filter: also keep left-side signs', None, None),
    'left_max': ('pre-filter: reach to the left with include_left, m', 0.0, 500.0),
    'cluster_d0': ('region growing: distance threshold at range 0, m', 0.01, 10.0),
    'cluster_k': ('region growing: threshold growth per metre of range', 0.0, 1.0),
    'min_points': ('check-to-add: minimum points per cluster', 1, 100000),
    'max_width': ('check-to-add: maximum horizontal bbox diagonal, m', 0.0, 100.0),
    'max_height': ('check-to-add: maximum vertical extent, m', 0.0, 100.0),
    'min_size': ('check-to-add: minimum of the largest extent, m', 0.0, 100.0),
    'flat_min_points': ('flatness: points needed to test', 3, 100000),
    'flat_min_spread': ('flatness: second PCA axis std needed to test, m', 0.0, 10.0),
    'flat_thickness': ('flatness: max plate thickness (third-axis std) at range 0, m', 0.0,
                       10.0),
    'flat_thickness_k': ('flatness: thickness allowance per metre of range', 0.0, 1.0),
    'max_normal_z': ('flatness: max |normal z| of a (vertical) sign plate', 0.0, 1.0),
    'hollow_gap': ('hollow test: widest inner gap in a row at range 0, m', 0.0, 100.0),
    'hollow_gap_k': ('hollow test: gap growth per metre of range', 0.0, 1.0),
    'hollow_frac': ('hollow test: gap must also exceed this fraction of the width '
                    '(>= 1 disables)', 0.0, 10.0),
    'hollow_row': ('hollow test: row height, m', 0.01, 10.0),
    'ground_z': ('road height in the lidar frame, m', -20.0, 20.0),
    'below_clearance': ('reflectors test: ignore bright returns this close to the road, m',
                        0.0, 10.0),
    'below_margin': ('reflectors test: footprint margin, m', 0.0, 10.0),
    'below_gap': ('reflectors test: counted only this far below the cluster bottom, m', 0.0,
                  10.0),
    'max_bright_below': ('reflectors test: reject with more bright returns under the '
                         'cluster (-1 disables)', -1, 100000),
    'voxel': ('voxel side of the clustering graph (0 = d0/sqrt(3))', 0.0, 10.0),
}
CORE_PARAMS = tuple(
    Param(f.name, getattr(_D, f.name), _HELP[f.name][0], min=_HELP[f.name][1],
          max=_HELP[f.name][2]) for f in fields(ClusterParams))


class LidarClusterNode(WorkzoneNode):
    """PointCloud2 in, sign candidates out (seed 004 s1.3 + persistence)."""

    PARAMS = (
        Param('points_topic', '/lidar/points', 'input cloud (x, y, z, intensity)'),
        Param('candidates_topic', '/workzone/lidar/candidates', 'output candidates'),
        Param('clustered_topic', '', 'optional clustered points for RViz ("" = off)'),
        Param('odom_topic', '/odom', 'odometry for persistence while moving ("" = off)'),
        Param('lidar_in_base', [1.0, 0.0, 1.95, 0.0, 0.0, 0.0],
              'lidar pose in base_link: x y z roll pitch yaw'),
        Param('persistence_k', 2, 'a candidate is published when seen in k ...', min=1,
              max=50),
        Param('persistence_n', 3, '... of the last n scans', min=1, max=50),
        Param('track_gate', 1.0, 'persistence match distance with odometry, m', min=0.0,
              max=50.0),
        Param('track_gate_k', 0.01, 'gate growth per metre of range', min=0.0, max=1.0),
        Param('track_gate_no_odom', 3.5, 'match distance without odometry, m', min=0.0,
              max=100.0),
        Param('match_time_offset', 0.05, 'pose time for matching after the scan stamp, s '
              '(half a spin: the forward points)', min=-1.0, max=1.0),
    ) + CORE_PARAMS
    INPUT_TOPICS = ('points_topic', 'odom_topic')

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('lidar_cluster', **kwargs)
        self._configure()
        self._poses = PoseBuffer()
        self._cand_pub = self.reliable_publisher(PointCloud2, self.params.candidates_topic,
                                                 depth=5)
        self._clustered_pub = None
        if self.params.clustered_topic:
            self._clustered_pub = self.sensor_publisher(PointCloud2,
                                                        self.params.clustered_topic)
        self._points_sub = self.sensor_subscription(PointCloud2, self.params.points_topic,
                                                    self._on_points, depth=1)
        self._odom_sub = None
        if self.params.odom_topic:
            self._odom_sub = self.reliable_subscription(Odometry, self.params.odom_topic,
                                                        self._on_odom, depth=50)

    def _configure(self) -> None:
        p = self.params
        self._core = ClusterParams.from_mapping(
            {f.name: getattr(p, f.name) for f in fields(ClusterParams)})
        if p.persistence_k > p.persistence_n:
            self.get_logger().error(f'persistence_k {p.persistence_k} > persistence_n '
                                    f'{p.persistence_n}: using k = n')
        self._tracker = CandidateTracker(min(p.persistence_k, p.persistence_n),
                                         p.persistence_n, p.track_gate, p.track_gate_k,
                                         p.track_gate_no_odom)
        lb = list(p.lidar_in_base) + [0.0] * 6
        self._base_to_lidar = euler_matrix(tuple(lb[:3]), tuple(lb[3:6]))

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Rebuild the thresholds and the tracker after a live change."""
        try:
            self._configure()
        except LidarClusterError as exc:
            self.get_logger().error(f'parameters not applied: {exc}')

    def _on_odom(self, msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        t = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        try:
            self._poses.add(t, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        except SyncError as exc:
            raise InputError(f'odometry: {exc}') from None

    def _lidar_pose(self, stamp_ns: int) -> Optional[np.ndarray]:
        if self._odom_sub is None:
            return None
        base = self._poses.at(stamp_ns + int(self.params.match_time_offset * 1e9))
        return None if base is None else base @ self._base_to_lidar

    def _on_points(self, msg: PointCloud2) -> None:
        points = pointcloud2_to_array(msg)
        try:
            res = cluster_cloud(points, self._core)
        except LidarClusterError as exc:
            raise InputError(str(exc)) from None
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        cands = self._tracker.update(res.candidates, self._lidar_pose(stamp_ns))
        self._cand_pub.publish(array_to_pointcloud2(candidates_to_array(cands), msg.header))
        if self._clustered_pub is not None:
            mask = res.clustered_mask()
            xyz = res.points[mask].astype(np.float32)
            pts = make_points(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2],
                              intensity=res.intensity[mask].astype(np.float32),
                              label=res.labels[mask].astype(np.uint32))
            self._clustered_pub.publish(array_to_pointcloud2(pts, msg.header))


NODE_CLASS = LidarClusterNode


def main(args: Optional[list[str]] = None) -> int:
    """Console entry point ``lidar_cluster``."""
    return run_node(LidarClusterNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
