"""``workzone-ros evaluate faults``: fuzz every subscription of every node with malformed messages.

Each node runs with its real subscriptions on real topics, in a private rclpy context (a
unique ROS_DOMAIN_ID and localhost discovery), next to a peer node that feeds it.  After a
warm-up on good input (the reference output), for every subscription, malformed messages
drawn by hypothesis (:mod:`workzone_ros.tools.fault_messages`) are published one at a time,
each followed by good frames (every input of the node, freshly stamped) until the node's
output is right again.  Per message it records:

* crash: an exception that escaped to the executor (it would end the node's process), a
  callback stuck for longer than ``--hang-s``, or, with the default process isolation, the
  node's process dying (a segfault, out of memory);
* dropped, with the reason the node gave (``internal error: ...`` reasons are bugs: the node
  survived, but did not say what was wrong with the input), or accepted as usable input;
* recovered: the output for a good frame after it matched the reference, and how many good
  frames that took (target: the first).

And per subscription, that ``/diagnostics`` reports the node's drop counter and last reason.
Duplicate and out-of-order stamps are tried too: each is counted in
``/diagnostics``, and the next good frame is processed normally.

Usage::

    workzone-ros evaluate faults [--examples 40] [--nodes lidar_cluster,fusion,...]
        [--json faults.json] [--in-process] [--hang-s 10]
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from typing import Callable, Optional

from workzone_ros.tools.fault_harness import (
    GOOD_EVERY_S,
    T_FAULT_S,
    T_RECOVER_S,
    Harness,
    Outcome,
    PrivateRos,
)
from workzone_ros.tools.fault_targets import Input, Target, targets

__all__ = ['targets', 'Harness', 'Outcome', 'fuzz_topic', 'stamp_faults', 'summarise',
           'main', 'Input', 'Target', 'PrivateRos', 'T_FAULT_S', 'T_RECOVER_S',
           'GOOD_EVERY_S']


# --- stamps: repeated and out of order -----------------------------------------------------------

def stamp_faults(h: Harness, topic: str) -> list[Outcome]:
    """A good message with the stamp of the last one, then one 0.5 s older: each must be
    counted (``<topic> stamps repeated`` / ``stamps out of order``), never fatal."""
    from builtin_interfaces.msg import Time

    from workzone_ros.tools.fault_messages import Fault
    inp = h.topics[topic]
    outcomes = []
    for kind, back_ns in (('duplicate stamp', 0), ('out-of-order stamp', 500_000_000)):
        ns = h.last_good_ns - back_ns          # the last good frame's stamp, or before it
        stamp = Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)
        outcomes.append(h.try_fault(topic, Fault(kind, (), lambda _s, t=stamp: inp.good(t))))
    return outcomes


# --- hypothesis ---------------------------------------------------------------------------

def fuzz_topic(h: Harness, topic: str, examples: int, seed: Optional[int] = None,
               progress: Optional[Callable[[Outcome], None]] = None) -> list[Outcome]:
    """``examples`` malformed messages drawn by hypothesis, each tried on ``topic``."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    from workzone_ros.tools.fault_messages import faults_for
    inp = h.topics[topic]
    outcomes: list[Outcome] = []

    @settings(max_examples=examples, derandomize=seed is None, database=None, deadline=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(faults_for(inp.msg_type, inp.good))
    def run(fault):
        o = h.try_fault(topic, fault)
        outcomes.append(o)
        if progress is not None:
            progress(o)
    if seed is not None:
        run = hseed(seed)(run)
    run()
    return outcomes


def run_target(name: str, examples: int, seed: Optional[int] = None, hang_s: float = 10.0,
               progress: Optional[Callable[[dict], None]] = None) -> dict:
    """The campaign on one target: per topic, its outcomes and the diagnostics check."""
    h = Harness(targets()[name], hang_s=hang_s)
    result = {'target': name, 'node': h.target.node, 'topics': {}}
    try:
        h.start()
        for topic in h.fuzzed:
            if progress:
                progress({'topic': topic, 'start': True})
            outcomes = fuzz_topic(h, topic, examples, seed,
                                  lambda o: progress and progress(dataclasses.asdict(o)))
            stamps = stamp_faults(h, topic)
            for o in stamps:
                if progress:
                    progress(dataclasses.asdict(o))
            result['topics'][topic] = {
                'outcomes': [dataclasses.asdict(o) for o in outcomes],
                'stamps': [dataclasses.asdict(o) for o in stamps],
                'diagnostics_agree': h.diagnostics_agree(topic)}
    finally:
        h.close()
    return result


# --- report -------------------------------------------------------------------------------

def summarise(result: dict) -> list[dict]:
    """One row per (target, topic): tried, dropped, crashes, recovery, stamps."""
    rows = []
    for topic, r in result['topics'].items():
        outs = r['outcomes']
        n = len(outs)
        rows.append({
            'node': result['target'], 'topic': topic, 'tried': n,
            'delivered': sum(o['delivered'] for o in outs),
            'dropped': sum(bool(o['dropped']) for o in outs),
            'dropped_elsewhere_only': sum(bool(o['dropped_elsewhere'] and not o['dropped'])
                                          for o in outs),
            'internal_errors': sum(bool(o['internal_error']) for o in outs),
            'crashes': sum(bool(o['crash']) for o in outs) + r.get('process_crashes', 0),
            'recovered_pct': 100.0 * sum(o['recovered'] for o in outs) / n if n else 0.0,
            'max_good_frames': max((o['good_frames'] for o in outs), default=0),
            'stamps_ok': all(o['recovered'] and not o['crash'] and not o['resets']
                             for o in r.get('stamps', ())),
            'stamps_counted': sum(bool(o['stamps_counted'] or o['dropped'])
                                  for o in r.get('stamps', ())),
            'diagnostics_agree': r.get('diagnostics_agree', False),
            'kinds': dict(collections.Counter(o['kind'] for o in outs)),
            'failures': [o for o in outs if not (o['recovered'] and not o['crash']
                                                 and not o['internal_error'])][:5],
        })
    return rows


def _table(rows: list[dict]) -> str:
    head = ('| node | topic | tried | dropped | internal errors | crashes | recovered | '
            'good frames (max) | stamps | diagnostics |')
    lines = [head, '|' + '---|' * 10]
    for r in rows:
        lines.append(f"| {r['node']} | `{r['topic'].split('/', 3)[-1]}` | {r['tried']} | "
                     f"{r['dropped']} | {r['internal_errors']} | {r['crashes']} | "
                     f"{r['recovered_pct']:.0f} % | {r['max_good_frames']} | "
                     f"{'ok' if r['stamps_ok'] else 'FAIL'}, {r['stamps_counted']}/2 counted | "
                     f"{'ok' if r['diagnostics_agree'] else 'FAIL'} |")
    return '\n'.join(lines)


def _child(name: str, args: argparse.Namespace) -> dict:
    """Run one target in its own process: a node that dies takes only this run with it."""
    with tempfile.TemporaryDirectory() as tmp:
        progress, out = os.path.join(tmp, 'progress.jsonl'), os.path.join(tmp, 'result.json')
        cmd = [sys.executable, '-m', 'workzone_ros.tools.eval_faults', '--target', name,
               '--examples', str(args.examples), '--hang-s', str(args.hang_s),
               '--result', out, '--progress', progress]
        if args.seed is not None:
            cmd += ['--seed', str(args.seed)]
        t0 = time.monotonic()
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True, timeout=args.timeout)
        if proc.returncode == 0 and os.path.exists(out):
            with open(out) as f:
                result = json.load(f)
            result['seconds'] = time.monotonic() - t0
            return result
        # the process died: what it had done, and the message it died on
        result = {'target': name, 'node': targets()[name].node, 'topics': {},
                  'died': f'exit {proc.returncode}: {proc.stderr.strip()[-300:]}'}
        topic = None
        if os.path.exists(progress):
            with open(progress) as f:
                for line in f:
                    item = json.loads(line)
                    if item.get('start'):
                        topic = item['topic']
                        result['topics'][topic] = {'outcomes': [], 'stamps': []}
                    elif topic:
                        result['topics'][topic]['outcomes'].append(item)
        if topic:
            result['topics'][topic]['process_crashes'] = 1
        return result


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros evaluate faults``."""
    ap = argparse.ArgumentParser(prog='workzone-ros evaluate faults', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--examples', type=int, default=40, help='malformed messages per topic')
    ap.add_argument('--nodes', default='', help='comma-separated targets (default: all): '
                    + ', '.join(_TARGET_NAMES))
    ap.add_argument('--seed', type=int, default=None,
                    help='hypothesis seed (default: derandomized, the same messages each run)')
    ap.add_argument('--json', default='', help='write the results here')
    ap.add_argument('--in-process', action='store_true',
                    help='run every target in this process (a segfault ends the run)')
    ap.add_argument('--hang-s', type=float, default=10.0,
                    help='a callback running longer counts as a crash')
    ap.add_argument('--timeout', type=float, default=3600.0, help='per target, s')
    ap.add_argument('--target', help=argparse.SUPPRESS)
    ap.add_argument('--result', help=argparse.SUPPRESS)
    ap.add_argument('--progress', help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    try:
        import hypothesis  # noqa: F401
    except ImportError:
        print("evaluate faults needs hypothesis: pip install -e '.[test]'", file=sys.stderr)
        return 2
    _isolate()
    if args.target:                               # the child of _child()
        with open(args.progress, 'a') as prog:
            def progress(item: dict) -> None:
                prog.write(json.dumps(item) + '\n')
                prog.flush()
            result = run_target(args.target, args.examples, args.seed, args.hang_s, progress)
        with open(args.result, 'w') as f:
            json.dump(result, f)
        return 0
    names = [n.strip() for n in args.nodes.split(',') if n.strip()] or list(_TARGET_NAMES)
    unknown = [n for n in names if n not in _TARGET_NAMES]
    if unknown:
        print(f'unknown target(s) {", ".join(unknown)}; known: {", ".join(_TARGET_NAMES)}',
              file=sys.stderr)
        return 2
    results, t0 = [], time.monotonic()
    for name in names:
        print(f'[faults] {name} ...', flush=True)
        results.append(run_target(name, args.examples, args.seed, args.hang_s)
                       if args.in_process else _child(name, args))
    rows = [row for r in results for row in summarise(r)]
    print(_table(rows))
    for r in results:
        if r.get('died'):
            print(f"[faults] {r['target']}: the node's process died ({r['died']})")
    for row in rows:
        for o in row['failures']:
            print(f"[faults] {row['node']} {row['topic']}: {o['fault']} -> crash "
                  f"{o['crash'] or '-'}; internal {o['internal_error'] or '-'}; recovered "
                  f"{o['recovered']}; dropped {o['dropped'][:1]}")
    total = sum(r['tried'] for r in rows)
    crashes = sum(r['crashes'] for r in rows)
    print(f'[faults] {total} malformed messages on {len(rows)} subscriptions, {crashes} '
          f'crash(es), {time.monotonic() - t0:.0f} s')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({'examples': args.examples, 'seed': args.seed, 'rows': rows,
                       'results': results}, f, indent=1)
    bad = crashes or any(r['recovered_pct'] < 100 or r['internal_errors'] for r in rows)
    return 1 if bad else 0


_TARGET_NAMES = ('lidar_cluster', 'projector', 'projector/compressed', 'color_detector',
                 'color_detector/compressed', 'tracker', 'tracker/compressed', 'classifier',
                 'classifier/compressed', 'fusion')


def _isolate() -> None:
    """A DDS domain of our own, localhost only (as the test session does)."""
    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)
    os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')


if __name__ == '__main__':
    raise SystemExit(main())
