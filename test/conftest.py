"""Test-session setup: isolate DDS before anything imports rclpy.

Each pytest session gets its own ROS_DOMAIN_ID (derived from the process id, so parallel
sessions on one machine do not see each other) and localhost-only discovery.
"""
import os
import sys
from pathlib import Path

_domain = os.environ.get('WORKZONE_TEST_DOMAIN_ID') or str(1 + os.getpid() % 100)
os.environ['ROS_DOMAIN_ID'] = _domain
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / 'shared'
REALDATA = SHARED / 'realdata'
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# the detector's compiled kernels, compiled once here (or loaded from their cache) rather
# than in whichever node process of a test first reaches them
from workzone_ros.core import kernels  # noqa: E402

kernels.warm()
