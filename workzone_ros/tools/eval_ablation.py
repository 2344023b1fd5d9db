"""``workzone-ros evaluate ablation``: what each default-on refinement of the colour stage buys.

For every switch of :class:`~workzone_ros.core.detect.DetectorConfig` that is on by default
(a boolean field whose default is ``True``), the detector is run with that one switch off,
next to the defaults, over the same frames in one pass:

* held-out synthetic bags (``--bags``): Seo et al. Table I (mean area precision and recall of
  matched warning and regulatory signs), the share of eligible signs found, and false
  detections per frame -- :func:`workzone_ros.tools.eval_color.evaluate_bags`;
* the real dashcam clips (``--real``): the share of labelled sign frames where the sign is
  detected and the orange detections per frame on the sign-free stretches --
  :func:`workzone_ros.tools.eval_color.evaluate_real`.

A switch whose removal costs less than ``--tolerance`` (0.005) in precision, recall and
found share on the renders, and nothing on the real clips (found share not lower, false
detections per frame not higher), is marked ``removable``: keeping it costs code without a
measured gain.  The detector is built as the ``color_detector`` node builds it (orange only,
the model's box scale), with ``proposals`` off as in the node's defaults.

Usage::

    workzone-ros synth --scenario random --seed 7301 --duration 20 --compressed -o /tmp/r1
    workzone-ros evaluate ablation --bags /tmp/r1 ... --real --markdown ablation.md
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any, Optional, Sequence

__all__ = ['default_on_switches', 'build_ablation', 'summarise', 'verdicts', 'markdown',
           'main']

BASELINE = 'defaults'


def default_on_switches(config_cls=None) -> list[str]:
    """Names of the boolean fields of ``DetectorConfig`` that default to True."""
    if config_cls is None:
        from workzone_ros.core.detect import DetectorConfig as config_cls
    return [f.name for f in dataclasses.fields(config_cls)
            if isinstance(f.default, bool) and f.default]


def build_ablation(model, switches: Sequence[str]) -> dict:
    """name -> (ColorDetector, uses_lidar): the node's detector, then one per switch off."""
    from workzone_ros.core.detect import ColorDetector, DetectorConfig
    bs = tuple(float(v) for v in model.extras.get('box_scale', (1.0, 1.0)))
    base = DetectorConfig(colors=('orange',), border_scale=bs)
    out = {BASELINE: (ColorDetector(model, base), False)}
    for name in switches:
        out[f'{name}=off'] = (ColorDetector(model, dataclasses.replace(base, **{name: False})),
                              False)
    return out


def _mean(values: list) -> Optional[float]:
    vals = [v for v in values if v is not None]
    return sum(vals) / len(vals) if vals else None


def summarise(synthetic: dict, real: dict) -> dict:
    """name -> the compared figures (None where a source was not run)."""
    names = set(synthetic) | {n for clip in real.values() if isinstance(clip, dict)
                              for n in clip if isinstance(clip[n], dict)}
    out = {}
    for name in sorted(names):
        row: dict[str, Any] = {}
        s = synthetic.get(name, {}).get('all')
        if s:
            w, r = s['warning'], s['regulatory']
            row['precision'] = _mean([w['precision'], r['precision']])
            row['recall'] = _mean([w['recall'], r['recall']])
            elig = (w['eligible'] or 0) + (r['eligible'] or 0)
            found = sum((k['detection_rate'] or 0) * (k['eligible'] or 0) for k in (w, r))
            row['found'] = found / elig if elig else None
            row['false_per_frame'] = s['false_per_frame']
            row['ms_p50'] = synthetic[name].get('ms_per_frame_p50')
        frames = detected = free = false = 0
        for clip in real.values():
            c = clip.get(name) if isinstance(clip, dict) else None
            if not isinstance(c, dict):
                continue
            frames += c.get('visible_frames', 0)
            detected += c.get('visible_detected', 0)
            free += c.get('free_frames', 0)
            false += c.get('false_detections', 0)
        if frames or free:
            row['real_found'] = detected / frames if frames else None
            row['real_false_per_frame'] = false / free if free else None
        out[name] = row
    return out


def _worse(base: Optional[float], value: Optional[float], tol: float,
           higher_is_better: bool = True) -> bool:
    if base is None or value is None:
        return False
    return (base - value > tol) if higher_is_better else (value - base > tol)


def verdicts(rows: dict, tolerance: float = 0.005) -> dict:
    """name -> 'removable' or what its removal costs (';'-joined)."""
    base = rows.get(BASELINE, {})
    out = {}
    for name, row in rows.items():
        if name == BASELINE:
            continue
        costs = [k for k in ('precision', 'recall', 'found')
                 if _worse(base.get(k), row.get(k), tolerance)]
        if _worse(base.get('false_per_frame'), row.get('false_per_frame'), tolerance, False):
            costs.append('false_per_frame')
        if _worse(base.get('real_found'), row.get('real_found'), 0.0):
            costs.append('real_found')
        if _worse(base.get('real_false_per_frame'), row.get('real_false_per_frame'), 0.0,
                  False):
            costs.append('real_false_per_frame')
        out[name] = 'removable' if not costs else 'costs ' + ', '.join(costs)
    return out


def _f(v: Optional[float], digits: int = 3) -> str:
    return '-' if v is None else f'{v:.{digits}f}'


def markdown(rows: dict, verdict: dict) -> str:
    """The ablation table (defaults first, then each switch off, with the difference)."""
    cols = ('precision', 'recall', 'found', 'false_per_frame', 'real_found',
            'real_false_per_frame')
    lines = ['| configuration | P | R | found | false/frame | real found | real false/frame '
             '| ms p50 | verdict |', '|---' * 9 + '|']
    base = rows.get(BASELINE, {})
    for name in [BASELINE] + sorted(n for n in rows if n != BASELINE):
        row = rows[name]
        cells = []
        for c in cols:
            v, b = row.get(c), base.get(c)
            if name == BASELINE or v is None or b is None:
                cells.append(_f(v))
            else:
                cells.append(f'{_f(v)} ({v - b:+.3f})')
        lines.append(f'| {name} | ' + ' | '.join(cells) + f" | {_f(row.get('ms_p50'), 1)} | "
                     f"{verdict.get(name, '')} |")
    return '\n'.join(lines) + '\n'


def main(argv: Optional[list[str]] = None) -> int:
    """Run the ablation; prints the Markdown table, returns the exit status."""
    from workzone_ros.core import color_model as cm
    from workzone_ros.resources import config_path
    from workzone_ros.tools import eval_color
    p = argparse.ArgumentParser(prog='workzone-ros evaluate ablation', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--model', default=str(config_path('models/color_orange.npz')))
    p.add_argument('--bags', nargs='*', default=[], help='held-out synthetic bags')
    p.add_argument('--real', nargs='?', const=str(eval_color.REALDATA / 'us_workzone_video'),
                   help='real clips folder (default ../shared/realdata/us_workzone_video)')
    p.add_argument('--switches', help='comma-separated switches (default: every default-on '
                                      'boolean of DetectorConfig)')
    p.add_argument('--tolerance', type=float, default=0.005,
                   help='largest loss in P, R or found share that still counts as none')
    p.add_argument('--min-px', type=float, default=16.0, help='eligible GT: shorter side')
    p.add_argument('--min-visible', type=float, default=0.9, help='eligible GT: visible share')
    p.add_argument('--every', type=int, default=1, help='use every n-th synthetic frame')
    p.add_argument('--json', help='write every number here')
    p.add_argument('--markdown', help='write the table here')
    args = p.parse_args(argv)
    if not args.bags and not args.real:
        p.error('nothing to measure: give --bags and/or --real')
    all_switches = default_on_switches()
    switches = all_switches if not args.switches else args.switches.split(',')
    unknown = sorted(set(switches) - set(all_switches))
    if unknown:
        p.error(f"not a default-on switch of DetectorConfig: {', '.join(unknown)}")
    try:
        model = cm.load_model(args.model)
    except cm.ModelError as exc:
        print(f'workzone-ros evaluate ablation: {exc}', file=sys.stderr)
        return 2
    import cv2
    cv2.setNumThreads(1)
    detectors = build_ablation(model, switches)
    args.sheet_method = ''
    t0 = time.time()
    synthetic = eval_color.evaluate_bags(args.bags, detectors, args, None) if args.bags else {}
    real = eval_color.evaluate_real(Path(args.real), detectors, args, None) if args.real else {}
    rows = summarise(synthetic, real)
    verdict = verdicts(rows, args.tolerance)
    table = markdown(rows, verdict)
    print(table)
    print(f'{len(detectors)} configurations in {time.time() - t0:.0f} s', file=sys.stderr)
    if args.markdown:
        Path(args.markdown).write_text(table)
    if args.json:
        Path(args.json).write_text(json.dumps(
            {'model': args.model, 'bags': args.bags, 'real': args.real,
             'tolerance': args.tolerance, 'rows': rows, 'verdicts': verdict,
             'synthetic': synthetic, 'real_clips': real}, indent=2, default=float))
    return 0


if __name__ == '__main__':
    sys.exit(main())
