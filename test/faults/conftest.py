"""Fault tests: one node per target, in the private context of the node tests' ``ros``
fixture (test/nodes/conftest.py: a unique ROS_DOMAIN_ID, localhost discovery), kept for all
the tests of that target."""
import importlib.util
from pathlib import Path

import pytest

from workzone_ros.tools.eval_faults import Harness, targets

_spec = importlib.util.spec_from_file_location(
    'workzone_test_nodes_conftest', Path(__file__).parents[1] / 'nodes' / 'conftest.py')
_nodes_conftest = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_nodes_conftest)

#: every node, and each image node once more reading CompressedImage
TARGETS = ('lidar_cluster', 'projector', 'projector/compressed', 'color_detector',
           'color_detector/compressed', 'tracker', 'tracker/compressed', 'classifier',
           'classifier/compressed', 'fusion')


@pytest.fixture(scope='module', params=TARGETS)
def harness(request):
    """A started :class:`Harness` (node + feeding peer, reference output taken)."""
    ros = _nodes_conftest.Ros()
    h = Harness(targets()[request.param], ros=ros)
    try:
        h.start()
        yield h
    finally:
        ros.close()
