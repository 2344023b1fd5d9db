"""``workzone-ros synth``: synthetic work-zone bags, training exports and the contact sheet.

Usage::

    workzone-ros synth --scenario NAME|PATH.yaml [--seed N] [--duration S] [--compressed]
                       [--speed MPS] [--latency-ms MS] [--workers N] [--overwrite] -o OUT_BAG
    workzone-ros synth crops -o DIR [--scenario NAME ...] [--seed N] [--per-class N] [--size 64]
    workzone-ros synth pixels -o DIR [--scenario NAME ...] [--seed N] [--frames N]
    workzone-ros synth sheet -o PNG [--seed N]
    workzone-ros synth list

Errors (unknown scenario, existing output without ``--overwrite``, bad seed, ...) are one line
on stderr and exit status 2.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Optional

__all__ = ['main']

_SUBCOMMANDS = ('crops', 'pixels', 'sheet', 'list')


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        print(f'{self.prog}: {message}', file=sys.stderr)
        raise SystemExit(2)


def _seed(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f'seed must be a non-negative integer, got {text!r}') \
            from None
    if not 0 <= value < 2 ** 32:
        raise argparse.ArgumentTypeError(f'seed must be in [0, 2^32), got {text!r}')
    return value


def _positive(kind: type, name: str):
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{name} must be a number, got {text!r}') from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f'{name} must be > 0, got {text!r}')
        return value
    return parse


def _bag_parser() -> argparse.ArgumentParser:
    p = _Parser(prog='workzone-ros synth',
                description='Write a synthetic highway work-zone rosbag2 (MCAP) with camera, '
                'LiDAR, odometry and exact ground truth.  Other commands: '
                'crops, pixels, sheet, list.')
    p.add_argument('--scenario', default='demo',
                   help='library name (see `synth list`), `random`, or a .yaml path')
    p.add_argument('--seed', type=_seed, default=0, help='placement / noise seed (default 0)')
    p.add_argument('--duration', type=_positive(float, 'duration'),
                   help='seconds to write (default: the scenario duration)')
    p.add_argument('--speed', type=_positive(float, 'speed'), help='ego speed in m/s')
    p.add_argument('--latency-ms', type=float, default=50.0,
                   help='LiDAR clock offset after the camera clock (default 50 ms)')
    p.add_argument('--compressed', action='store_true',
                   help='write /camera/image_raw/compressed (JPEG) instead of raw images')
    p.add_argument('--workers', type=int, default=2, help='worker processes (default 2)')
    p.add_argument('--overwrite', action='store_true', help='replace an existing bag')
    p.add_argument('-o', '--output', required=True, help='output bag directory')
    p.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return p


def _sub_parser(cmd: str) -> argparse.ArgumentParser:
    p = _Parser(prog=f'workzone-ros synth {cmd}')
    if cmd == 'list':
        return p
    p.add_argument('-o', '--output', required=True,
                   help='output PNG' if cmd == 'sheet' else 'output directory')
    p.add_argument('--seed', type=_seed, default=0)
    if cmd in ('crops', 'pixels'):
        p.add_argument('--scenario', action='append',
                       help='scenario(s) to render (repeatable; default: the whole library)')
        p.add_argument('--overwrite', action='store_true', help='write into an existing DIR')
    if cmd == 'crops':
        p.add_argument('--per-class', type=_positive(int, 'per-class'), default=50)
        p.add_argument('--size', type=_positive(int, 'size'), default=64)
    if cmd == 'pixels':
        p.add_argument('--frames', type=_positive(int, 'frames'), default=100)
        p.add_argument('--fixed-camera', action='store_true',
                       help='render from our camera mount only (default: height and pitch '
                            'jittered per frame, so the colour prior generalises)')
    return p


def _fail(msg: str) -> int:
    print(f'workzone-ros synth: {" ".join(str(msg).split())}', file=sys.stderr)
    return 2


def _library_specs(names: Optional[list[str]], seed: int):
    from workzone_ros.sim.scenario import list_scenarios, load_scenario
    if not names:
        names = [n for n in list_scenarios() if n != 'random']
    return [load_scenario(n, seed) for n in names]


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros synth``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    from workzone_ros.sim.scenario import ScenarioError
    from workzone_ros.sim.writer import SynthError

    cmd = argv[0] if argv and argv[0] in _SUBCOMMANDS else None
    try:
        if cmd is None:
            args = _bag_parser().parse_args(argv)
            return _write(args)
        args = _sub_parser(cmd).parse_args(argv[1:])
        if cmd == 'list':
            from workzone_ros.sim.scenario import list_scenarios
            items = list_scenarios()
            width = max(len(n) for n in items)
            for name, desc in items.items():
                print(f'{name:<{width}}  {desc}')
            return 0
        if cmd == 'sheet':
            try:
                from workzone_ros.sim.sheet import make_contact_sheet
            except ImportError as exc:
                return _fail(f'contact sheet unavailable: {exc}')
            out = Path(args.output)
            out.parent.mkdir(parents=True, exist_ok=True)
            make_contact_sheet(str(out), seed=args.seed)
            print(out)
            return 0
        out = Path(args.output)
        if out.exists() and any(out.iterdir()) and not args.overwrite:
            return _fail(f'{out} exists and is not empty (use --overwrite)')
        specs = _library_specs(args.scenario, args.seed)
        from workzone_ros.sim import writer
        if cmd == 'crops':
            counts = writer.export_crops(out, specs, args.seed, args.per_class, args.size)
            print(f'{sum(counts.values())} crops in {out} '
                  f'({len(counts)} classes, index {out / "index.csv"})')
        else:
            n = writer.export_pixels(out, specs, args.seed, args.frames,
                                     camera_jitter=not args.fixed_camera)
            print(f'{n} images and masks in {out}')
        return 0
    except (ScenarioError, SynthError, OSError) as exc:
        return _fail(str(exc))


def _write(args) -> int:
    from workzone_ros.sim.scenario import load_scenario
    from workzone_ros.sim.writer import SynthOptions, write_bag
    spec = load_scenario(args.scenario, args.seed)
    opts = SynthOptions(seed=args.seed, duration=args.duration, speed=args.speed,
                        compressed=args.compressed, latency_ms=args.latency_ms,
                        workers=max(0, args.workers))
    summary = write_bag(spec, args.output, opts, overwrite=args.overwrite,
                        progress=None if args.quiet else
                        (lambda line: print(line, file=sys.stderr, flush=True)))
    print(f'wrote {summary.path}: {summary.frames} frames, {summary.scans} scans, '
          f'{summary.odom} odom, {summary.bytes / 1e6:.1f} MB in {summary.seconds:.1f} s')
    return 0
