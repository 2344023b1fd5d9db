"""workzone_ros: highway work-zone perception from camera and LiDAR on ROS 2 Jazzy."""

__version__ = '0.1.0'
