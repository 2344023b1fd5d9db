"""The simulator's sensor frames agree with the parameters the nodes run with."""
import numpy as np
import yaml

from workzone_ros.resources import config_path
from workzone_ros.sim.world import CAMERA_IN_BASE, LIDAR_IN_BASE, LIDAR_TO_CAMERA


def test_simulator_extrinsics_equal_the_config_defaults():
    params = yaml.safe_load(config_path('workzone.yaml').read_text())
    matrix = np.array(params['projector']['ros__parameters']['lidar_to_camera']).reshape(4, 4)
    np.testing.assert_allclose(matrix, LIDAR_TO_CAMERA, atol=1e-12)


def test_lidar_to_camera_maps_the_lidar_origin_to_its_mount_offset():
    # The LiDAR origin seen from the camera: 0.6 m behind (z) and 0.5 m above (-y).
    origin_cam = LIDAR_TO_CAMERA @ np.array([0.0, 0.0, 0.0, 1.0])
    d = LIDAR_IN_BASE - CAMERA_IN_BASE
    np.testing.assert_allclose(origin_cam[:3], [-d[1], -d[2], d[0]])
    # A point 10 m ahead of the LiDAR at its height is 10.6 m in front of the camera.
    ahead = LIDAR_TO_CAMERA @ np.array([10.0, 0.0, 0.0, 1.0])
    assert np.isclose(ahead[2], 10.0 + d[0])
