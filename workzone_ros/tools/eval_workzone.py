"""``workzone-ros evaluate workzone``: the work-zone state against a bag's ground truth.

Usage::

    workzone-ros evaluate workzone BAG [BAG ...] [--signs gt|pipeline] [--drop P]
        [--confuse P] [--spurious R] [--seed N] [--no-odom] [--no-channelizers]
        [--fusion KEY=VALUE ...] [--json OUT] [--report DIR] [--workers N] [--cache DIR]

Every camera frame of a bag, in bag order, becomes one :class:`~workzone_ros.interfaces.Signs`
payload and goes through :class:`workzone_ros.core.fusion.WorkzoneFusion` (the ``fusion``
node's core) with the metres travelled from ``/odom`` (:class:`~workzone_ros.core.odometry.
TravelledDistance`, as the node computes them; ``--no-odom``: none, the fusion works over
time) and the frame's channelizer count.  Where the signs come from:

* ``--signs gt`` (default): ``/groundtruth/signs``, tests the fusion alone.  Each *legible*
  sign (shorter box side >= ``--legible-px``, default 12 = the classifier node's
  ``min_size``, and at least half visible) is a Sign with its class, box, ``distance_m``
  (exact) and ``sign_id`` as track id; a work-zone speed limit carries its value (from the
  ``speed_limit`` event of its sign) once its box is >= 24 px (the digit reader's minimum).
  Noise, seeded per bag by ``--seed`` and the bag's name: ``--drop P`` drops an observation,
  ``--confuse P`` replaces a work-zone sign's class by another work-zone class (a
  ``background`` answer is not published by the classifier node: that is ``--drop``),
  ``--spurious R`` adds per frame with probability R a false work-zone sign (random class,
  a new track id, for 1 to ``--spurious-frames`` frames, default 2: stray classifications;
  a false sign classified alike on ``min_hits`` frames of one track is a sign to the
  fusion).  Channelizers: GT drums and cones whose box is >= 6 px.
* ``--signs pipeline``: the colour detector, the mean-shift tracker and the sign classifier
  of ``workzone_ros.core`` on the bag's images (``workzone_ros.tools.workzone_pipeline``);
  the classifier node's rules (``min_size`` 12 px, half visible, background rejected,
  distance from the apparent size and CameraInfo's focal length, the speed read on
  speed-limit signs).  ``--cache DIR`` stores each bag's pipeline signs (per bag and
  model files) so that reruns of the fusion skip the perception.

Ground truth per frame (from ``/groundtruth/workzone`` and ``/groundtruth/signs``; ``t`` is
bag time, the ego passes a sign at its event's ``t``):

* ``approaching`` from the first frame where a sign of the zone standing before the begin
  (the events up to ``zone_begin``: W20-1, lane closed, speed limit, lane shifts, the R22-1
  itself) is legible (as above), until ``begin_t``;
* ``inside`` from ``begin_t`` until the END ROAD WORK sign is first legible;
* ``leaving`` from then until ``end_t``; ``none`` before and after (the whole bag when the
  bag has no zone).

Figures per bag (every one in ``--json``; ``null`` where it does not apply):

* ``frames``, ``phase_accuracy`` (share of frames whose predicted phase is the truth's;
  ``unknown`` counts as wrong), ``active_accuracy`` (the ``active`` flag against truth
  ``inside``/``leaving``), ``unknown_frames``, ``confusion_phase`` (truth -> predicted ->
  frames);
* ``zone_begin`` / ``zone_end``: ``truth_t``, ``pred_t`` (first frame predicted active;
  first frame after it predicted not active), ``error_s`` and ``error_m`` (predicted minus
  truth, in seconds and odometry metres), ``recognised`` (a prediction within
  ``--tolerance`` s, default 3), ``images`` / ``precision`` / ``recall`` of the event's sign
  (below);
* ``changes``: one entry per driving-condition change (``speed_limit`` value,
  ``lane_shift`` direction, ``lane_closed`` side; the W20-5 + W4-2 pair of one closure is one
  change): ``recognised`` when the state shows the value at a frame between the first
  legible frame of its signs and ``--tolerance`` s after the ego passes its last sign,
  ``delay_s`` (first such frame minus the time the ego passes its first sign: negative =
  known before reaching it), ``images`` (frames where a sign of the change is legible),
  ``precision`` / ``recall`` (Table IV: per frame, raw classifier outputs; a prediction
  matches a legible GT sign at IoU >= 0.5; recall = matched frames with the right class /
  ``images``; precision = those predictions / all predictions of the change's classes that
  match no other GT sign of those classes);
* ``time_to_correct``: per truth phase onset (``approaching``, ``inside``, ``leaving``,
  ``none``), seconds from the onset to the first frame predicted in that phase (null when
  not before the next onset);
* ``phase_changes`` (predicted, after the first ``unknown``), ``truth_changes``,
  ``flicker`` = max(0, predicted - truth);
* ``likelihood_inside`` / ``likelihood_outside``: mean likelihood over truth-active and
  truth-none frames; ``sign_confusion`` (truth class -> predicted class -> frames, IoU >=
  0.5; ``missed`` and ``no sign`` for the unmatched); ``unknown_classes`` and ``resets`` of
  the fusion; ``wall_s``;
* ``stages`` (``--signs pipeline``; null with ``--signs gt``): the accuracy of each stage of
  the in-process pipeline on the frame's legible ground-truth work-zone signs
  (:mod:`workzone_ros.tools.workzone_stages`): ``detection`` (Table I form: ``precision``,
  ``recall`` at IoU >= 0.5 one to one, detections on an illegible or general sign
  ``ignored``, ``false_per_frame``: detections on no GT sign, IoU < 0.3), ``tracking``
  (``coverage`` of the legible sign frames by a track box, ``off_sign_per_frame``),
  ``classification`` (Table III form on the matched track boxes:
  ``accuracy``, ``macro_precision``, ``macro_recall``, per-class figures, ``confusion``,
  ``background_as_workzone_per_frame``), ``lidar`` (a note: not run in process) and the raw
  ``counts``.

``summary`` pools the bags: bounds and changes recognised, mean and max absolute timing
errors, total flicker, frame-weighted phase accuracy, ``stages`` (the counts of every bag
summed, the figures recomputed).  ``--report DIR`` writes ``DIR/README.md`` with the
Table IV, each bag's seed-Fig.-3 timeline PNG and the per-stage table
(``workzone_ros.tools.workzone_report``).  A missing or corrupt bag, or a bag without
ground truth, is a one-line error (exit 2).
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path
from typing import Optional

from workzone_ros.bagio import BagError
from workzone_ros.core.fusion import FusionConfig
from workzone_ros.interfaces import GtWorkzone  # noqa: F401 - re-exported
from workzone_ros.tools.eval_tracker import _xywh  # noqa: F401 - re-exported
from workzone_ros.tools.workzone_run import (  # noqa: F401 - re-exported
    CHANNELIZER_PX,
    SPEED_READ_PX,
    EvalError,
    EvalOptions,
    Frame,
    GtSignSource,
    _gt_source,
    _image,
    fusion_config,
    legible,
    run_bag,
)
from workzone_ros.tools.workzone_scoring import (
    IOU,
    PHASES_ORDER,
    pooled_stage_ms,
    score,
    sign_confusion,
    stage_summary,
    summarise,
    truth_phases,
)

__all__ = ['main', 'evaluate_bag', 'EvalOptions', 'EvalError', 'GtSignSource', 'truth_phases',
           'score', 'legible', 'PHASES_ORDER', 'SPEED_READ_PX', 'CHANNELIZER_PX', 'IOU',
           'fusion_config', 'Frame', 'run_bag', 'sign_confusion', 'stage_summary',
           'pooled_stage_ms', 'summarise']


def evaluate_bag(bag: str, opts: EvalOptions) -> dict:
    """Run and score one bag; ``{'bag', 'error'}`` instead when it cannot be evaluated."""
    started = time.monotonic()
    try:
        if not Path(bag).exists():
            raise EvalError('no such bag')
        gtw, frames, counters = run_bag(bag, opts)
    except (BagError, EvalError) as exc:
        return {'bag': bag, 'error': ' '.join(str(exc).split())}
    stages = counters.pop('_stage_ms')
    from workzone_ros.tools.workzone_stages import stage_figures
    res = {'bag': bag, **score(frames, gtw, opts.tolerance_s, opts.legible_px), **counters,
           'stages': stage_figures(frames) if opts.signs == 'pipeline' else None,
           'stage_ms': {k: stage_summary(v) for k, v in stages.items()},
           'wall_s': round(time.monotonic() - started, 2)}
    res['_stage_ms'] = stages           # raw times for the pooled figures and the histogram
    if opts.keep_frames:
        res['_frames'] = frames
    return res


# --- printing -------------------------------------------------------------------------------

def _mark(v: Optional[bool]) -> str:
    return 'N/A' if v is None else ('o' if v else 'x')


def _fmt(v) -> str:
    return '-' if v is None else (f'{v:.3f}' if isinstance(v, float) else str(v))


def table_iv_rows(r: dict) -> list[tuple[str, str]]:
    """(row label, 'o/images/precision/recall') for Table IV."""
    rows = []
    for key, label in (('zone_begin', 'Workzone begins'), ('zone_end', 'Workzone ends')):
        b = r[key]
        rows.append((label, f"{_mark(b['recognised'])}/{b['images']}/"
                            f"{_fmt(b['precision'])}/{_fmt(b['recall'])}"))
    for c in r['changes']:
        label = {'speed_limit': f"Speed limit {c['value']} mph",
                 'lane_shift': f"Lane shift {c['value']}",
                 'lane_closed': f"Lane closed {c['value']}"}[c['kind']]
        rows.append((label, f"{_mark(c['recognised'])}/{c['images']}/"
                            f"{_fmt(c['precision'])}/{_fmt(c['recall'])}"))
    return rows


def print_bag(r: dict, out=sys.stdout) -> None:
    """A readable block per bag."""
    if 'error' in r:
        print(f"\n== {r['bag']}: ERROR {r['error']}", file=out)
        return
    b, e = r['zone_begin'], r['zone_end']
    print(f"\n== {r['bag']}  ({r['scenario']}, {r['weather']}, {r['frames']} frames, "
          f"{r['wall_s']} s)", file=out)
    print(f"   phase accuracy {r['phase_accuracy']:.3f}  active accuracy "
          f"{r['active_accuracy']:.3f}  flicker {r['flicker']}  likelihood inside/outside "
          f"{_fmt(r['likelihood_inside'])}/{_fmt(r['likelihood_outside'])}", file=out)
    print(f"   begin error {_fmt(b['error_s'])} s ({_fmt(b['error_m'])} m), end error "
          f"{_fmt(e['error_s'])} s ({_fmt(e['error_m'])} m); time to correct "
          + ', '.join(f'{k} {_fmt(v)}' for k, v in r['time_to_correct'].items()), file=out)
    for label, cell in table_iv_rows(r):
        print(f'   {label:<24s} {cell}', file=out)
    if r.get('stages'):
        from workzone_ros.tools.workzone_stages import stage_lines
        for line in stage_lines(r['stages']):
            print(f'   {line}', file=out)


def print_summary(s: dict, out=sys.stdout) -> None:
    """The pooled figures."""
    print(f"\n== summary: {s['bags']} bags ({s['failed']} failed), {s['frames']} frames", file=out)
    print(f"   zone bounds recognised {s['bounds_recognised']}/{s['bounds']}, driving-condition "
          f"changes {s['changes_recognised']}/{s['changes']}, flicker {s['flicker']}, phase "
          f"accuracy {s['phase_accuracy']}", file=out)
    for key in ('zone_begin', 'zone_end'):
        print(f"   {key}: |error| mean {_fmt(s[key + '_abs_error_s_mean'])} s, max "
              f"{_fmt(s[key + '_abs_error_s_max'])} s, within 1 s: {s[key + '_within_1s']}",
              file=out)
    from workzone_ros.tools.workzone_stages import stage_lines
    for line in stage_lines(s.get('stages')):
        print(f'   {line}', file=out)
    if s.get('stage_ms'):
        print('   processing per frame (ms, in process) p50/p99: ' + ', '.join(
            f"{k} {_fmt(v['p50'])}/{_fmt(v['p99'])}" for k, v in s['stage_ms'].items()),
            file=out)


# --- CLI ------------------------------------------------------------------------------------

def _unit(text: str) -> float:
    v = float(text)
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f'must be in [0, 1], got {text}')
    return v


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='workzone-ros evaluate workzone', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bags', nargs='+', help='synthetic bags (workzone-ros synth)')
    p.add_argument('--signs', choices=('gt', 'pipeline'), default='gt',
                   help='ground-truth signs (the fusion alone) or the perception pipeline')
    p.add_argument('--drop', type=_unit, default=0.0, help='gt: drop an observation (P)')
    p.add_argument('--confuse', type=_unit, default=0.0, help='gt: wrong class (P)')
    p.add_argument('--spurious', type=_unit, default=0.0,
                   help='gt: a false work-zone sign per frame (P)')
    p.add_argument('--spurious-frames', type=int, default=2,
                   help='gt: a false sign lasts 1 to N frames (default 2)')
    p.add_argument('--seed', type=int, default=0, help='noise seed (default 0)')
    p.add_argument('--no-odom', action='store_true', help='no odometry: the fusion works '
                   'over time at its assumed speed')
    p.add_argument('--no-channelizers', action='store_true',
                   help='fusion without the channelizer evidence')
    p.add_argument('--legible-px', type=float, default=12.0,
                   help='GT signs this big (shorter side, px) are legible (default 12)')
    p.add_argument('--tolerance', type=float, default=3.0,
                   help='an event is recognised within this many seconds (default 3)')
    p.add_argument('--color-model', help='pipeline: colour model (.npz)')
    p.add_argument('--classifier-model', help='pipeline: sign classifier (.npz)')
    p.add_argument('--cache', help="pipeline: keep each bag's signs here (per bag and model "
                   'files); reruns of the fusion skip the perception')
    p.add_argument('--fusion', action='append', default=[], metavar='KEY=VALUE',
                   help='override a FusionConfig field (repeatable), e.g. sigma_m=400')
    p.add_argument('--json', help='write every figure here')
    p.add_argument('--report', help='write DIR/README.md with timelines (PNG)')
    p.add_argument('--workers', type=int, default=1, help='bags in parallel (default 1)')
    p.add_argument('--live', action='store_true', help='through the launcher, every node '
                   'and the player at --rate instead (workzone_ros.tools.live_score)')
    p.add_argument('--rate', type=float, default=1.0, help='--live: replay rate (default 1)')
    return p


def _run_all(bags: list[str], opts: EvalOptions, workers: int) -> list[dict]:
    """Bags in a process pool (results in argument order) with a progress line."""
    started = time.monotonic()
    results: list[dict] = []
    args = [(b, opts) for b in bags]
    if workers <= 1 or len(bags) == 1:
        it = (evaluate_bag(*a) for a in args)
        results = _progress(it, len(bags), started)
    else:
        with mp.get_context('spawn').Pool(min(workers, len(bags))) as pool:
            results = _progress(pool.imap(_evaluate_star, args), len(bags), started)
    return results


def _evaluate_star(args: tuple) -> dict:
    return evaluate_bag(*args)


def _progress(it, n: int, started: float) -> list[dict]:
    out = []
    for k, r in enumerate(it, 1):
        out.append(r)
        state = 'ERROR' if 'error' in r else f"{r['frames']} frames"
        print(f'[{k}/{n}] {Path(r["bag"]).name}: {state} '
              f'({time.monotonic() - started:.0f} s)', file=sys.stderr, flush=True)
    return out


def _overrides(items: list[str]) -> tuple:
    """``KEY=VALUE`` strings as typed FusionConfig overrides (ValueError, one line)."""
    import dataclasses
    kinds = {f.name: type(f.default) for f in dataclasses.fields(FusionConfig)}
    out = []
    for item in items:
        key, sep, text = item.partition('=')
        if not sep or key not in kinds:
            raise ValueError(f'--fusion {item!r}: expected KEY=VALUE with KEY one of '
                             f'{", ".join(kinds)}')
        kind = kinds[key]
        try:
            value = (text.lower() in ('1', 'true', 'yes', 'on')) if kind is bool \
                else kind(float(text)) if kind is int else kind(text)
        except ValueError:
            raise ValueError(f'--fusion {item!r}: {text!r} is not a {kind.__name__}') from None
        out.append((key, value))
    FusionConfig(**dict(out))
    return tuple(out)


def main(argv: Optional[list[str]] = None) -> int:
    """Evaluate the work-zone state on bags; prints Table IV per bag and a summary."""
    args = _parser().parse_args(argv)
    try:
        overrides = _overrides(args.fusion)
    except ValueError as exc:
        print(f'workzone-ros evaluate workzone: {exc}', file=sys.stderr)
        return 2
    opts = EvalOptions(signs=args.signs, drop=args.drop, confuse=args.confuse,
                       spurious=args.spurious, spurious_frames=max(1, args.spurious_frames),
                       seed=args.seed, odom=not args.no_odom,
                       channelizers=not args.no_channelizers, legible_px=args.legible_px,
                       tolerance_s=args.tolerance, keep_frames=bool(args.report),
                       color_model=args.color_model, classifier_model=args.classifier_model,
                       cache=args.cache, fusion=overrides)
    if opts.signs == 'pipeline':
        from workzone_ros.tools.workzone_pipeline import check_available
        problem = check_available(opts)
        if problem:
            print(f'workzone-ros evaluate workzone: {problem}', file=sys.stderr)
            return 2
    if args.live:
        from workzone_ros.tools.live_score import evaluate_live
        results = [evaluate_live(b, args.rate) for b in args.bags]
    else:
        results = _run_all(args.bags, opts, args.workers)
    for r in results if not args.live else ():      # a live run printed its own block
        print_bag(r)
    summary = summarise(results)
    print_summary(summary)
    if args.report:
        from workzone_ros.tools.workzone_report import write_report
        path = write_report(args.report, results, summary, opts, sys.argv[1:] if argv is None
                            else argv)
        print(f'report: {path}')
    for r in results:
        r.pop('_frames', None)
        r.pop('_stage_ms', None)
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({'tool': 'workzone-ros evaluate workzone',
                                   'options': opts.__dict__, 'bags': results,
                                   'summary': summary}, indent=2))
        print(f'figures written to {out}')
    errors = [r for r in results if 'error' in r]
    for r in errors:
        print(f"{r['bag']}: {r['error']}", file=sys.stderr)
    return 2 if errors else 0


if __name__ == '__main__':
    sys.exit(main())
