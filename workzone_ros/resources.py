"""Where the package's data files are: a source checkout, an ament install, or a pip install.

``config/`` (parameters, scenarios, models) sits next to the Python package in a checkout;
colcon and pip install it under ``share/workzone_ros/config``.
"""
from __future__ import annotations

import sys
from pathlib import Path

__all__ = ['PACKAGE', 'config_path']

PACKAGE = 'workzone_ros'


def _candidates(relative: str):
    yield Path(__file__).resolve().parents[1] / 'config' / relative
    try:
        from ament_index_python.packages import get_package_share_directory
        yield Path(get_package_share_directory(PACKAGE)) / 'config' / relative
    except Exception:  # noqa: BLE001 - PackageNotFoundError, or no ament_index at all
        pass
    yield Path(sys.prefix) / 'share' / PACKAGE / 'config' / relative


def config_path(relative: str) -> Path:
    """The first existing ``config/<relative>`` (checkout, ament share, ``sys.prefix``).

    Returns the checkout path when none exists, so error messages name a sensible place.
    """
    first = None
    for path in _candidates(relative):
        first = first or path
        if path.exists():
            return path
    return first
