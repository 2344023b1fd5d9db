"""``workzone-ros launch``: run the node graph, optionally replaying a bag, with a report.

What ``ros2 launch`` would do for this package, without the ROS CLI:

* every node in its own process (``python -m workzone_ros.nodes.<name> --ros-args
  --params-file FILE -r __node:=<name> [-p use_sim_time:=true]``), in its own process group,
  its output prefixed ``[name] ``;
* a node that dies is restarted with exponential backoff (0.5, 1, 2, 4 ... s, capped); one
  that dies more than ``--max-restarts`` times within ``--restart-window`` seconds stops
  everything (exit code 3, naming the node).  A node exiting with code 2 (configuration
  error, see ``nodes.base.run_node``) is not restarted: exit code 3 at once;
* ``--bag``: the bag is checked before any node starts (exit 2 with one line if unusable),
  replayed in-process once the nodes are up (``/clock``, ``use_sim_time``), and the launcher
  exits 0 after the bag and a short drain;
* SIGINT / SIGTERM: SIGINT to every child group, SIGKILL after a deadline, all gone within
  5 s; children also get SIGKILL from the kernel if the launcher itself is killed;
* ``--loop`` replays the bag over and over (time jumps back at each pass; ``--duration``
  ends the run), ``--cut TOPIC:START:DURATION`` withholds a topic for a window of bag time
  (a lost sensor; see ``workzone-ros play``), ``--duration S`` stops after S s of playing;
* ``--single-process``: every node class (``NODE_CLASS``) in one executor in this process;
* ``--report``: counts and rates of the ``/workzone/*`` outputs, drops from ``/diagnostics``
  and, with ``/groundtruth/signs`` in the bag, frames with ground-truth signs vs frames with
  detections / tracks / signs (a coarse recall).

Node names: ``lidar_cluster`` (module ``workzone_ros.nodes.lidar_cluster``), a dotted module
path (``pkg.my_node``, node name ``my_node``), or ``alias=module`` for a second instance.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Optional

from workzone_ros.tools.launch_dds import apply_dds_profile, fastdds_shm_profile
from workzone_ros.tools.launch_nodes import (
    PACKAGE,
    PLANNED_NODES,
    LaunchError,
    NodeSpec,
    default_params_file,
    resolve_nodes,
)
from workzone_ros.tools.launch_report import ReportCollector
from workzone_ros.tools.launch_supervisor import EXIT_BAG, EXIT_CRASH_LOOP, Launcher

__all__ = ['PLANNED_NODES', 'NodeSpec', 'Launcher', 'ReportCollector', 'default_params_file',
           'resolve_nodes', 'fastdds_shm_profile', 'apply_dds_profile', 'main', 'LaunchError',
           'PACKAGE', 'EXIT_BAG', 'EXIT_CRASH_LOOP']


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros launch`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros launch', description=__doc__.split('\n')[0])
    p.add_argument('--params', metavar='FILE', help='ROS params YAML (default: '
                   'config/workzone.yaml of the package)')
    p.add_argument('--bag', metavar='PATH', help='replay this bag with /clock and use_sim_time')
    p.add_argument('--rate', type=float, default=1.0, help='bag replay rate (0 = max)')
    p.add_argument('--nodes', metavar='A,B', help='comma-separated node names or modules '
                   f'(default: those of {", ".join(PLANNED_NODES)} that exist)')
    p.add_argument('--single-process', action='store_true',
                   help='all nodes in one executor in this process')
    p.add_argument('--report', action='store_true', help='print an output report at the end')
    p.add_argument('--log-level', metavar='L',
                   choices=['debug', 'info', 'warn', 'error', 'fatal'], help='node log level')
    p.add_argument('--max-restarts', type=int, default=5, metavar='N',
                   help='give up on a node that dies more than N times in the window (5)')
    p.add_argument('--restart-window', type=float, default=60.0, metavar='S',
                   help='crash-counting window in seconds (60)')
    p.add_argument('--backoff-cap', type=float, default=8.0, metavar='S',
                   help='longest restart delay (8 s)')
    p.add_argument('--drain', type=float, default=2.0, metavar='S',
                   help='seconds to keep running after the bag ends (2)')
    p.add_argument('--ready-timeout', type=float, default=30.0, metavar='S',
                   help='longest wait for the nodes before playing the bag (30)')
    p.add_argument('--loop', action='store_true', help='replay the bag over and over (the '
                   'time jumps back at each pass; --duration ends the run)')
    p.add_argument('--cut', action='append', default=[], metavar='TOPIC:START:DURATION',
                   help='withhold TOPIC (and the topics under it) from the nodes for DURATION '
                   's from START s of bag time, on every pass (repeatable): a lost sensor')
    p.add_argument('--duration', type=float, metavar='S', help='stop (exit 0) after S s of '
                   'playing the bag (or of running, without a bag)')
    p.add_argument('--quiet-play', action='store_true', help='no bag progress lines')
    p.add_argument('--state', action='store_true', help='print /workzone/state changes as a '
                   'planner sees them (phase, speed limit, lanes, evidence)')
    p.add_argument('--score', metavar='DIR', help='with a synthetic bag: score the '
                   "published states against the bag's ground truth at the end (Table IV) "
                   'and write DIR/README.md with the timeline')
    p.add_argument('--verbose', action='store_true', help="show every node's start-up "
                   'configuration on the console (always in the log file)')
    p.add_argument('--log-file', metavar='FILE', help='where every line goes (default: '
                   "~/.ros/log/workzone_launch_<time>.log; '' = none)")
    p.add_argument('--dds-profile', default='shm', metavar='shm|none|FILE',
                   help='Fast DDS profile for every process: shm = shared memory with 32 MB '
                   'segments so large images/clouds are not fragmented over UDP (default; '
                   'an already set FASTRTPS_DEFAULT_PROFILES_FILE wins), none, or an XML file')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros launch``; returns the exit code."""
    args = build_parser().parse_args(argv)
    if args.rate < 0:
        print('workzone-ros launch: error: --rate must be >= 0', file=sys.stderr)
        return EXIT_BAG
    from workzone_ros.tools.player import parse_cut
    try:
        args.cuts = [parse_cut(c) for c in args.cut]
    except ValueError as exc:
        print(f'workzone-ros launch: error: {exc}', file=sys.stderr)
        return EXIT_BAG
    if args.duration is not None and not args.duration > 0:
        print('workzone-ros launch: error: --duration must be > 0', file=sys.stderr)
        return EXIT_BAG
    params = Path(args.params) if args.params else default_params_file()
    if params is None or not params.is_file():
        print(f'workzone-ros launch: error: params file not found: '
              f'{params or "config/workzone.yaml"}', file=sys.stderr)
        return EXIT_BAG
    try:
        specs = resolve_nodes(args.nodes)
        args.dds_profile_file = apply_dds_profile(args.dds_profile)
    except LaunchError as exc:
        print(f'workzone-ros launch: error: {exc}', file=sys.stderr)
        return EXIT_BAG
    if not args.bag and not specs:
        print('workzone-ros launch: error: no nodes to launch', file=sys.stderr)
        return EXIT_BAG
    return Launcher(args, specs, params.resolve()).run()


if __name__ == '__main__':
    sys.exit(main())
