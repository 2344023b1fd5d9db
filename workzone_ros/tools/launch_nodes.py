"""The nodes the launcher runs: node names and modules (:func:`resolve_nodes`), the default
params file, and the ROS command-line arguments each node gets.
"""
from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

__all__ = ['PLANNED_NODES', 'PACKAGE', 'LaunchError', 'NodeSpec', 'default_params_file',
           'resolve_nodes']

#: Nodes launched by default when their module exists, in data-flow order.
PLANNED_NODES = ('lidar_cluster', 'projector', 'color_detector', 'tracker', 'classifier',
                 'fusion')
PACKAGE = 'workzone_ros'

# Runs a node module's main() when the module has no ``if __name__ == '__main__'`` block.
_RUNNER = ('import importlib, sys; m = sys.argv[1]; sys.argv = [m] + sys.argv[2:]; '
           'sys.exit(importlib.import_module(m).main(sys.argv) or 0)')


class LaunchError(Exception):
    """A launch configuration problem (bad node name, missing params file)."""


@dataclass(frozen=True)
class NodeSpec:
    """One node to run: its ROS node name and its Python module."""

    name: str
    module: str


def default_params_file() -> Optional[Path]:
    """``config/workzone.yaml`` next to the package (source checkout) or in the share dir."""
    from workzone_ros.resources import config_path
    path = config_path('workzone.yaml')
    return path if path.is_file() else None


def _module_exists(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def resolve_nodes(text: Optional[str]) -> list[NodeSpec]:
    """Parse ``--nodes`` (default: every planned node whose module exists).

    Raises:
        LaunchError: a node whose module cannot be found, or a duplicate name.
    """
    if text is None:
        return [NodeSpec(n, f'{PACKAGE}.nodes.{n}') for n in PLANNED_NODES
                if _module_exists(f'{PACKAGE}.nodes.{n}')]
    specs: list[NodeSpec] = []
    for item in (s.strip() for s in text.split(',')):
        if not item or item == 'none':
            continue
        alias, _, target = item.rpartition('=')
        module = target if '.' in target else f'{PACKAGE}.nodes.{target}'
        name = alias or target.rsplit('.', 1)[-1]
        if not _module_exists(module):
            raise LaunchError(f'node {item!r}: module {module} not found')
        if any(s.name == name for s in specs):
            raise LaunchError(f'node name {name!r} given twice (use alias=module)')
        specs.append(NodeSpec(name, module))
    return specs


def _has_main_block(module: str) -> bool:
    try:
        spec = importlib.util.find_spec(module)
        origin = spec.origin if spec else None
        return bool(origin) and '__main__' in Path(origin).read_text(errors='replace')
    except (ImportError, ValueError, OSError):
        return False


def _declares(module: str, param: str) -> bool:
    """True when the node class of ``module`` declares the parameter ``param``."""
    try:
        cls = getattr(importlib.import_module(module), 'NODE_CLASS', None)
    except Exception:  # noqa: BLE001 - the node's own start reports import problems
        return False
    return any(p.name == param for p in getattr(cls, 'PARAMS', ()))


def _ros_args(spec: NodeSpec, params: Path, sim_time: bool, log_level: Optional[str],
              compressed: bool = False) -> list[str]:
    args = ['--ros-args', '--params-file', str(params), '-r', f'__node:={spec.name}']
    if sim_time:
        args += ['-p', 'use_sim_time:=true']
    if compressed and _declares(spec.module, 'compressed'):
        args += ['-p', 'compressed:=true']
    if log_level:
        args += ['--log-level', log_level]
    return args
