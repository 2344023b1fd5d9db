"""Fixtures of test/reliability, and the ``soak`` marker.

The ``ros`` fixture is the node tests' (test/nodes/conftest.py: a private context and
executor per test); the helpers of test/tools (small bags, the CLI) are importable as
``wz_tools_helpers``.  Tests marked ``soak`` (minutes of live graph: ``make soak``) run only
when ``-m`` selects them.
"""
import importlib.util
import sys
from pathlib import Path

import pytest

_TEST = Path(__file__).resolve().parents[1]
if str(_TEST / 'tools') not in sys.path:
    sys.path.insert(0, str(_TEST / 'tools'))

_spec = importlib.util.spec_from_file_location('wz_nodes_conftest',
                                               _TEST / 'nodes' / 'conftest.py')
_nodes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_nodes)
ros = _nodes.ros
from wz_tools_helpers import ros_context  # noqa: E402,F401 - pytest fixture


def pytest_collection_modifyitems(config, items):
    """Skip ``soak`` tests unless the ``-m`` expression names them (``make soak``)."""
    if 'soak' in (config.getoption('-m') or ''):
        return
    skip = pytest.mark.skip(reason='soak: minutes of live graph; `make soak` runs it')
    for item in items:
        if item.get_closest_marker('soak') is not None:
            item.add_marker(skip)
