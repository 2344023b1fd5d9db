"""``workzone-ros bench <name> [--json OUT]``: benchmarks, not tests.

Each benchmark is a module ``workzone_ros.tools.bench_<name>`` with
``add_arguments(parser)`` and ``run(args) -> dict`` (figures, machine-readable).  This
dispatcher prints the figures and writes them to ``--json`` when asked.
"""
from __future__ import annotations

import argparse
import importlib
import json
import sys

__all__ = ['BENCHES', 'main']

BENCHES: dict[str, str] = {
    'transport': 'Image 15 Hz + 130k-point cloud 10 Hz between processes; player at 1x and max',
    'lidar': 'LiDAR message -> candidates per scan; ours vs scikit-learn DBSCAN',
    'color': 'color detector per 640x480 frame; LUT vs boosted predict_proba per pixel',
    'tracker': 'mean-shift tracker ms per track per frame; vs OpenCV CamShift',
    'classifier': 'sign classifier ms per crop, single and batched; vs raw intensity + PCA',
}


def _load(name: str):
    return importlib.import_module(f'workzone_ros.tools.bench_{name}')


def main(argv: list[str] | None = None) -> int:
    """Run one benchmark (or ``all``) and print / save its figures."""
    parser = argparse.ArgumentParser(prog='workzone-ros bench', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='name', required=True)
    for name, text in BENCHES.items():
        p = sub.add_parser(name, help=text)
        p.add_argument('--json', metavar='OUT', help='write the figures to this JSON file')
        try:
            _load(name).add_arguments(p)
        except ModuleNotFoundError:
            pass
    p = sub.add_parser('all', help='every benchmark with its defaults')
    p.add_argument('--json', metavar='OUT', help='write the figures to this JSON file')
    args = parser.parse_args(argv)
    names = list(BENCHES) if args.name == 'all' else [args.name]
    results = {}
    for name in names:
        try:
            mod = _load(name)
        except ModuleNotFoundError:
            print(f'bench {name}: not available in this build', file=sys.stderr)
            continue
        if args.name == 'all':
            sub_args = argparse.Namespace(json=None)
            p = argparse.ArgumentParser()
            mod.add_arguments(p)
            sub_args = p.parse_args([])
        else:
            sub_args = args
        print(f'== bench {name}', flush=True)
        results[name] = mod.run(sub_args)
        print(json.dumps(results[name], indent=2), flush=True)
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump(results if args.name == 'all' else results.get(args.name, {}), fh,
                      indent=2)
        print(f'figures written to {args.json}')
    return 0
