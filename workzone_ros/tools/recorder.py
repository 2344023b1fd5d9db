"""``workzone-ros record -o OUT TOPIC...``: record topics to an MCAP bag, bytes as received.

Types are discovered from the graph (``get_topic_names_and_types``); topics that are not up
yet are picked up as soon as they appear.  Subscriptions are raw (``raw=True``): the CDR bytes
go to the bag untouched.  The QoS follows the publishers (best effort if any publisher is,
transient local if all are, so latched state is captured) and is written to the bag's
``offered_qos_profiles`` so the player replays it the same way.  Stops on Ctrl-C / SIGTERM
or after ``--duration`` and always closes the bag cleanly.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import Optional

from workzone_ros.bagio import BagError, BagWriter

__all__ = ['Recorder', 'main']

_SCAN_S = 0.5


class Recorder:
    """Subscribes to topics as they appear and writes what arrives to a :class:`BagWriter`."""

    def __init__(self, node, writer: BagWriter, topics: list[str], all_workzone: bool = False,
                 log=print) -> None:
        """Args: an rclpy node, an open writer, exact topic names, whether to add /workzone/*."""
        self.node = node
        self.writer = writer
        self.wanted = list(topics)
        self.all_workzone = all_workzone
        self.log = log
        self.subscribed: dict[str, str] = {}
        self.counts: dict[str, int] = {}
        self._lock = threading.Lock()

    def scan(self) -> None:
        """Subscribe to wanted topics that now have a publisher."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from workzone_ros.tools.player import message_class
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.subscribed or not types:
                continue
            if topic not in self.wanted and not (self.all_workzone
                                                 and topic.startswith('/workzone/')):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            msgtype = types[0]
            try:
                cls = message_class(msgtype)
                best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                                  for i in infos)
                latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                              for i in infos)
                kind = 'sensor' if best_effort else 'transient_local' if latched else 'reliable'
                self.writer.add_topic(topic, msgtype, qos=kind)
            except (ImportError, BagError) as exc:
                self.subscribed[topic] = msgtype
                self.log(f'[record] cannot record {topic} ({msgtype}): {exc}')
                continue
            qos = QoSProfile(depth=100,
                             reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                             else ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                             else DurabilityPolicy.VOLATILE)
            self.node.create_subscription(cls, topic, lambda data, t=topic: self._on(t, data),
                                          qos, raw=True)
            self.subscribed[topic] = msgtype
            self.counts[topic] = 0
            self.log(f'[record] recording {topic} ({msgtype}, {kind})')

    def _on(self, topic: str, data: bytes) -> None:
        with self._lock:
            self.writer.write(topic, time.time_ns(), data)
            self.counts[topic] += 1


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros record`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros record', description=__doc__.split('\n')[0])
    p.add_argument('-o', '--output', required=True, metavar='OUT', help='bag directory to create')
    p.add_argument('topics', nargs='*', metavar='TOPIC')
    p.add_argument('--all-workzone', action='store_true', help='also every /workzone/* topic')
    p.add_argument('--duration', type=float, metavar='S', help='stop after S seconds')
    p.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap')
    p.add_argument('--overwrite', action='store_true', help='replace an existing bag at OUT')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros record``; returns 0, or 2 on a usage / bag error."""
    args = build_parser().parse_args(argv)
    if not args.topics and not args.all_workzone:
        print('workzone-ros record: error: give topics or --all-workzone', file=sys.stderr)
        return 2
    try:
        writer = BagWriter(args.output, storage=args.storage, overwrite=args.overwrite)
    except BagError as exc:
        print(f'workzone-ros record: error: {exc}', file=sys.stderr)
        return 2
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    ctx = Context()
    rclpy.init(context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('workzone_recorder', context=ctx, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    topics = [t if t.startswith('/') else '/' + t for t in args.topics]
    recorder = Recorder(node, writer, topics, args.all_workzone,
                        log=lambda text: print(text, file=sys.stderr, flush=True))
    t_end = None if args.duration is None else time.monotonic() + args.duration
    next_scan = 0.0
    try:
        while not stop.is_set() and (t_end is None or time.monotonic() < t_end):
            if time.monotonic() >= next_scan:
                recorder.scan()
                next_scan = time.monotonic() + _SCAN_S
            executor.spin_once(timeout_sec=0.1)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        writer.close()
    missing = [t for t in topics if t not in recorder.subscribed]
    total = sum(recorder.counts.values())
    print(f'[record] wrote {total} messages on {len(recorder.counts)} topics to {args.output}'
          + (f'; never appeared: {", ".join(missing)}' if missing else ''), file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
