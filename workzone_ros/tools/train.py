"""``workzone-ros train <model> ...``: train a model and write it to config/models/.

Each trainer is a module ``workzone_ros.tools.train_<model>`` with ``main(argv) -> int``.
"""
from __future__ import annotations

import importlib
import sys

__all__ = ['TRAINERS', 'main']

TRAINERS: dict[str, str] = {
    'color': 'boosted hue/saturation color model (seed 000) from `synth pixels` or images+masks',
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch to a trainer."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help') or argv[0] not in TRAINERS:
        if argv and argv[0] not in ('-h', '--help'):
            print(f'workzone-ros train: unknown model {argv[0]!r}', file=sys.stderr)
        print('usage: workzone-ros train <model> [options]\n\nmodels:')
        for name, text in TRAINERS.items():
            print(f'  {name:<8} {text}')
        return 0 if argv and argv[0] in ('-h', '--help') else 2
    return int(importlib.import_module(f'workzone_ros.tools.train_{argv[0]}').main(argv[1:]) or 0)
