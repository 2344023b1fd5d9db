"""``workzone-ros <subcommand>``: one entry point for the tools.

Each subcommand lives in its own module with a ``main(argv) -> int``; it is imported only when
used, so ``workzone-ros echo`` does not pay for OpenCV and ``synth`` does not pay for rclpy.
"""
from __future__ import annotations

import importlib
import sys

__all__ = ['SUBCOMMANDS', 'main', 'dispatch', 'single_threaded_math', 'THREAD_VARIABLES']

#: name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    'launch': ('workzone_ros.tools.launcher', 'run the node graph (optionally replaying a bag)'),
    'play': ('workzone_ros.tools.player', 'replay a rosbag2 / ROS 1 bag with /clock'),
    'record': ('workzone_ros.tools.recorder', 'record topics to an MCAP bag'),
    'echo': ('workzone_ros.tools.echo', 'print a topic (our JSON payloads readably)'),
    'synth': ('workzone_ros.sim.cli', 'write a synthetic work-zone bag with ground truth'),
    'train': ('workzone_ros.tools.train', 'train a model (color, ...)'),
    'evaluate': ('workzone_ros.tools.evaluate', 'accuracy reports against ground truth'),
    'bench': ('workzone_ros.tools.bench', 'benchmarks (transport, lidar, color, tracker)'),
    'bag-from-video': ('workzone_ros.tools.bag_from_video', 'a video file -> camera-only bag'),
    'mine-background': ('workzone_ros.tools.mine_background',
                        'hard-negative crops for the classifier from real video'),
    'make-crops': ('workzone_ros.tools.make_crops',
                   'classifier training crops from signs labelled in videos'),
    'real-pixels': ('workzone_ros.tools.real_pixels',
                    'colour-training images and masks from labelled video frames'),
    'inventory': ('workzone_ros.tools.inventory',
                  'sign inventory (CSV / GeoJSON, one row per physical sign) from bags'),
}


def _usage() -> str:
    lines = ['usage: workzone-ros <subcommand> [options]', '', 'subcommands:']
    lines += [f'  {name:<9} {text}' for name, (_, text) in SUBCOMMANDS.items()]
    lines += ['', "'workzone-ros <subcommand> --help' for its options."]
    return '\n'.join(lines)


def dispatch(prog: str, what: str, table: dict[str, str], module_prefix: str,
             argv: list[str]) -> int:
    """Run ``<module_prefix><name>.main(rest)`` for ``argv = [name, *rest]``.

    Used by ``workzone-ros train`` and ``workzone-ros evaluate``: usage (exit 0 for --help,
    2 otherwise) when the name is missing or unknown.
    """
    if not argv or argv[0] in ('-h', '--help') or argv[0] not in table:
        if argv and argv[0] not in ('-h', '--help'):
            print(f'{prog}: unknown {what} {argv[0]!r}', file=sys.stderr)
        print(f'usage: {prog} <{what}> [options]\n\n{what}s:')
        for name, text in table.items():
            print(f'  {name:<8} {text}')
        return 0 if argv and argv[0] in ('-h', '--help') else 2
    return int(importlib.import_module(module_prefix + argv[0]).main(argv[1:]) or 0)


#: thread-pool variables of the numeric libraries (read once, when they load)
THREAD_VARIABLES = ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')


def single_threaded_math() -> None:
    """One BLAS / OpenMP thread unless the user set otherwise (before numpy loads).

    Our tools run many small linear-algebra calls (a 1,300 x 9 SVD per least-squares step)
    per frame, often next to other processes: a multi-threaded BLAS then spends its time
    waiting for its threads (measured: 30 ms per SVD instead of 0.3 ms on a loaded 2-core
    machine, a 1.5 s frame).  ``train`` keeps the libraries' defaults.
    """
    import os
    for var in THREAD_VARIABLES:
        os.environ.setdefault(var, '1')


def main(argv: list[str] | None = None) -> int:
    """Dispatch to a subcommand's ``main``; returns its exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help', 'help'):
        print(_usage())
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in SUBCOMMANDS:
        print(f'workzone-ros: unknown subcommand {name!r}\n\n{_usage()}', file=sys.stderr)
        return 2
    if name != 'train':
        single_threaded_math()
    module = importlib.import_module(SUBCOMMANDS[name][0])
    try:
        return int(module.main(rest) or 0)
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
