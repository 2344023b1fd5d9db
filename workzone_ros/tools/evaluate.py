"""``workzone-ros evaluate <stage> ...``: accuracy reports against a bag's ground truth.

Each evaluation is a module ``workzone_ros.tools.eval_<stage>`` with ``main(argv) -> int``.
"""
from __future__ import annotations

import importlib
import sys

__all__ = ['EVALUATIONS', 'main']

EVALUATIONS: dict[str, str] = {
    'lidar': 'LiDAR candidates (FP/FN by range band) and projection error (seed 004)',
    'color': 'color detection, seed 000 Table I metrics per weather; real clips',
    'tracker': 'tracking, seed 001 Table II quantities; CamShift peer',
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch to an evaluation."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help') or argv[0] not in EVALUATIONS:
        if argv and argv[0] not in ('-h', '--help'):
            print(f'workzone-ros evaluate: unknown stage {argv[0]!r}', file=sys.stderr)
        print('usage: workzone-ros evaluate <stage> [options]\n\nstages:')
        for name, text in EVALUATIONS.items():
            print(f'  {name:<8} {text}')
        return 0 if argv and argv[0] in ('-h', '--help') else 2
    return int(importlib.import_module(f'workzone_ros.tools.eval_{argv[0]}').main(argv[1:]) or 0)
