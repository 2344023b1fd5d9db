"""Fixtures for test/tools (the helpers live in wz_tools_helpers.py)."""
from wz_tools_helpers import ros_context  # noqa: F401 - pytest fixture
