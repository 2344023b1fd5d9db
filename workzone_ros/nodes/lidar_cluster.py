"""``lidar_cluster`` node: ``/lidar/points`` -> ``/workzone/lidar/candidates`` (Cahail et al. s1).

Thin wrapper around :class:`workzone_ros.core.lidar_stream.LidarStream`: view the cloud
without copies, then the intensity scale (learned from the field's datatype and values, or
``intensity_scale``; logged), the sensor's mounting and the road (``lidar_in_base`` plus a
per-scan ground-plane fit), pre-filter, region-grow, check-to-add, and persistence k of n with
stable ids (matched in the odometry frame when ``/odom`` is available).  Publishes the
confirmed candidates as a PointCloud2 with fields x, y, z, radius, intensity (float32,
0-255 units), count, id (uint32), half_w, half_h (float32: the measured half size for the
camera ROI, 0 when the cluster is too sparse to measure), stamped like the scan, and
optionally the clustered points (x, y, z, intensity, label) for RViz.

What it says when nothing comes out: the log names the intensity encoding it chose, warns
with the observed intensity range when no point is bright enough for 20 scans, and says once
that candidates are held for persistence; ``/diagnostics`` carries the last scan's funnel
(bright, in region, in height band), the clusters rejected per reason, the candidates held
for persistence and a one-line "why nothing published".
"""
from __future__ import annotations

import re
from dataclasses import fields
from typing import Any, Optional

import numpy as np
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from sensor_msgs.msg import PointCloud2

from workzone_ros.core.lidar_clustering import (
    RENAMED,
    ClusterParams,
    LidarClusterError,
    PersistenceError,
    candidates_to_array,
)
from workzone_ros.core.lidar_stream import LidarStream
from workzone_ros.core.pointcloud import make_points
from workzone_ros.core.projection import euler_matrix
from workzone_ros.core.sync import PoseBuffer, SyncError
from workzone_ros.nodes.base import ConfigError, InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import array_to_pointcloud2, pointcloud2_to_array
from workzone_ros.nodes.params import params_from_dataclass

__all__ = ['LidarClusterNode', 'NODE_CLASS', 'main', 'CORE_PARAMS']

#: One parameter per ClusterParams field: default, description and range from its knob().
CORE_PARAMS = params_from_dataclass(ClusterParams)
_UNDECLARED = re.compile(r"'(\w+)' is not a parameter")


class LidarClusterNode(WorkzoneNode):
    """PointCloud2 in, sign candidates out (Cahail et al. s1.3 + persistence)."""

    PARAMS = (
        Param('points_topic', '/lidar/points', 'input cloud (x, y, z, intensity)', read_only=True),
        Param('candidates_topic', '/workzone/lidar/candidates', 'output candidates',
              read_only=True),
        Param('clustered_topic', '', 'optional clustered points for RViz ("" = off)',
              read_only=True),
        Param('odom_topic', '/odom', 'odometry for persistence while moving ("" = off)',
              read_only=True),
        Param('persistence_k', 2, 'a candidate is published when seen in k ... (1 publishes '
              'single scans)', min=1, max=50),
        Param('persistence_n', 3, '... of the last n scans', min=1, max=50),
        Param('track_gate', 1.0, 'persistence match distance with odometry, m', min=0.0,
              max=50.0),
        Param('track_gate_k', 0.01, 'gate growth per metre of range', min=0.0, max=1.0),
        Param('track_gate_no_odom', 3.5, 'match distance without odometry, m', min=0.0,
              max=100.0),
        Param('match_time_offset', 0.05, 'pose time for matching after the scan stamp, s '
              '(half a spin: the forward points)', min=-1.0, max=1.0),
        Param('silent_scans', 20, 'warn when this many non-empty scans in a row have no point '
              'at min_intensity', min=1, max=100000),
    ) + CORE_PARAMS
    INPUT_TOPICS = ('points_topic', 'odom_topic')

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('lidar_cluster', **kwargs)
        self._renamed_keys()
        try:
            self._configure(self.params)
        except (LidarClusterError, PersistenceError) as exc:
            name = self.get_fully_qualified_name()
            self.destroy_node()
            raise ConfigError(f'node {name}: {exc}') from None
        self.add_on_set_parameters_callback(self._check_together)
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

    def _renamed_keys(self) -> None:
        """Parameters of an older release: say what replaced them (the base only warns)."""
        self.renamed_params: list[str] = []
        for text in list(self.config_warnings):
            m = _UNDECLARED.search(text)
            if m and m.group(1) in RENAMED:
                line = (f'parameter {m.group(1)!r} no longer exists and is ignored: use '
                        f'{RENAMED[m.group(1)]}')
                self.renamed_params.append(line)
                self.get_logger().error(line)

    def _configure(self, p: Any) -> None:
        """Build the stage from parameters (raises LidarClusterError / PersistenceError)."""
        core = ClusterParams.from_mapping({f.name: getattr(p, f.name)
                                           for f in fields(ClusterParams)})
        self._stream = LidarStream(core, p.persistence_k, p.persistence_n, p.track_gate,
                                   p.track_gate_k, p.track_gate_no_odom, p.silent_scans)
        self._base_to_lidar = euler_matrix(tuple(core.lidar_in_base[:3]),
                                           tuple(core.lidar_in_base[3:]))
        self.get_logger().info(f'LiDAR: {core.mount.describe()}; ground fit '
                               f'{"on" if core.ground_fit else "off"}; intensity scale '
                               f'{core.intensity_scale or "learned from the first scans"}')

    def _check_together(self, parameters: list) -> SetParametersResult:
        """Reject a live change that makes the thresholds inconsistent, with the reason."""
        values = {f.name: getattr(self.params, f.name) for f in fields(ClusterParams)}
        values.update({x.name: x.value for x in parameters if x.name in values})
        try:
            ClusterParams.from_mapping(values)
        except LidarClusterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        k = next((x.value for x in parameters if x.name == 'persistence_k'),
                 self.params.persistence_k)
        n = next((x.value for x in parameters if x.name == 'persistence_n'),
                 self.params.persistence_n)
        if k > n:
            return SetParametersResult(successful=False,
                                       reason=f'persistence_k {k} > persistence_n {n}')
        return SetParametersResult(successful=True)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Rebuild the stage after an accepted live change (the learned state restarts)."""
        self._configure(self.params)

    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """The last scan's funnel, rejections, persistence and why nothing was published."""
        return self._stream.status()

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: forget the poses and the persistence tracks (the learned intensity
        scale and the road plane belong to the sensor, not to the time, and are kept)."""
        self._poses = PoseBuffer()
        self._stream.tracker.reset()

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
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        try:
            out = self._stream.process(points, self._lidar_pose(stamp_ns))
        except LidarClusterError as exc:
            raise InputError(str(exc)) from None
        for line in out.info:
            self.get_logger().info(line)
        for line in out.warnings:
            self.warn_throttled(line[:25], line, period_s=30.0)
        self._cand_pub.publish(array_to_pointcloud2(candidates_to_array(out.candidates),
                                                    msg.header))
        if self._clustered_pub is not None:
            res = out.result
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
