"""``workzone-ros play BAG``: replay a rosbag2 (MCAP / sqlite3) or ROS 1 bag with ``/clock``.

The stored CDR bytes are published as they are (``Publisher.publish(bytes)``, rclpy >= 7):
no per-message Python deserialization for bags whose types are the Jazzy types.  ROS 1
bags and bags with other type versions are converted to Jazzy CDR by :mod:`workzone_ros.bagio`.

Timing follows the recorded receive timestamps scaled by ``--rate`` (``--rate 0`` or
``--max``: as fast as possible).  ``/clock`` (rosgraph_msgs/Clock) is published at
``--clock-hz`` while waiting and at every message, and never goes backwards within a pass.

QoS per topic: camera and LiDAR topics reliable depth 10 (sensor-data subscribers connect to
reliable publishers), ``/workzone/state``, ``/workzone/active``, ``/groundtruth/workzone``
and anything recorded as transient local / latched: reliable + transient local depth 1;
everything else reliable depth 100.

``--cut TOPIC:START:DURATION`` (repeatable) withholds a topic for a window of bag time, on
every pass of a loop: a sensor that goes quiet on a running graph (``TOPIC`` also names
every topic under it: ``/camera`` cuts ``/camera/image_raw/compressed`` and
``/camera/camera_info``).  ``/clock`` keeps running.

A missing, empty or corrupt bag is one line on stderr and exit code 2.  :class:`BagPlayer`
is the same player for in-process use (tests, the launcher).
"""
from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Optional, Sequence, TextIO, Union

from workzone_ros.bagio import BagError, BagReader, open_reader

__all__ = ['BagPlayer', 'Cut', 'PlayStats', 'SENSOR_TYPES', 'TRANSIENT_TOPICS', 'main',
           'parse_cut', 'parse_remaps', 'message_class']

#: Types replayed with the sensor profile (reliable, depth 10).
SENSOR_TYPES = frozenset({'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage',
                          'sensor_msgs/msg/PointCloud2'})
#: Topics replayed as reliable + transient local, depth 1.
TRANSIENT_TOPICS = frozenset({'/workzone/state', '/workzone/active', '/groundtruth/workzone'})

_PROGRESS_TTY_S = 0.2
_PROGRESS_LOG_S = 5.0


@dataclass
class PlayStats:
    """What one :meth:`BagPlayer.run` did."""

    published: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    skipped_topics: dict[str, str] = field(default_factory=dict)
    bag_s: float = 0.0          # bag time covered in the last pass
    wall_s: float = 0.0         # wall time from the first to the last message
    cpu_s: float = 0.0          # process CPU time spent inside run() (all threads)
    clock_published: int = 0
    loops: int = 0
    interrupted: bool = False
    withheld: dict[str, int] = field(default_factory=dict)   # messages held back by cuts
    late: int = 0               # messages published more than LATE_S after their time
    late_max_s: float = 0.0     # the latest of them (s)


#: a message published this long after its time at the rate (s) counts as late: the player
#: was kept from running and then sent what it owed back to back, a burst no camera sends
#: (the subscribers' queues may overflow)
LATE_S = 0.1


@dataclass(frozen=True)
class Cut:
    """A topic withheld from ``start_s`` to ``start_s + duration_s`` of bag time (from the
    start of the bag, on every pass); ``topic`` also covers the topics under it."""

    topic: str
    start_s: float
    duration_s: float

    def covers(self, topic: str, bag_s: float) -> bool:
        """Whether a message on ``topic`` at ``bag_s`` is withheld."""
        under = topic == self.topic or topic.startswith(self.topic.rstrip('/') + '/')
        return under and self.start_s <= bag_s < self.start_s + self.duration_s


def parse_cut(text: str) -> Cut:
    """``'/camera:10:5'`` -> ``Cut('/camera', 10.0, 5.0)``.

    Raises:
        ValueError: not ``TOPIC:START:DURATION`` with a topic starting with ``/`` and
            non-negative numbers.
    """
    topic, _, rest = text.partition(':')
    start, _, duration = rest.partition(':')
    try:
        cut = Cut(topic, float(start), float(duration))
    except ValueError:
        raise ValueError(f'bad cut {text!r}; expected TOPIC:START:DURATION '
                         '(seconds of bag time)') from None
    if not topic.startswith('/') or not cut.start_s >= 0 or not cut.duration_s > 0:
        raise ValueError(f'bad cut {text!r}; the topic starts with /, START >= 0, '
                         'DURATION > 0')
    return cut


def parse_remaps(items: Optional[Iterable[str]]) -> dict[str, str]:
    """``['a:=b', ...]`` -> ``{'a': 'b'}``.

    Raises:
        ValueError: an item without ``:=``.
    """
    out = {}
    for item in items or ():
        src, sep, dst = item.partition(':=')
        if not sep or not src or not dst:
            raise ValueError(f'bad remap {item!r}; expected OLD:=NEW')
        out[src] = dst
    return out


def message_class(msgtype: str):
    """The rclpy message class for ``pkg/msg/Name`` (``pkg/Name`` accepted).

    Raises:
        ImportError: the package or type is not installed.
    """
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3:
        raise ImportError(f'bad message type name {msgtype!r}')
    module = importlib.import_module(f'{parts[0]}.{parts[1]}')
    try:
        return getattr(module, parts[2])
    except AttributeError:
        raise ImportError(f'{msgtype} not found in {parts[0]}.{parts[1]}') from None


def _fmt_t(seconds: float) -> str:
    return f'{seconds:7.1f}'


class BagPlayer:
    """Replays a bag on real topics; usable in-process or through :func:`main`.

    Example::

        player = BagPlayer('bags/demo', rate=2.0, context=ctx, wait_for=['/camera/image_raw'])
        stats = player.run()        # blocks; player.stop() from another thread ends it early
    """

    def __init__(self, bag: Union[str, Path, BagReader], *, rate: float = 1.0,
                 start: float = 0.0, loop: bool = False,
                 topics: Optional[Sequence[str]] = None,
                 remap: Optional[dict[str, str]] = None, clock_hz: float = 100.0,
                 quiet: bool = True, delay: float = 0.0,
                 wait_for: Union[Sequence[str], dict[str, int]] = (),
                 wait_timeout: float = 10.0, context: Any = None,
                 node_name: str = 'workzone_player',
                 progress_stream: Optional[TextIO] = None,
                 log: Optional[Callable[[str], None]] = None,
                 cuts: Sequence[Cut] = ()) -> None:
        """Open the bag (rclpy is not touched until :meth:`run`).

        Args:
            bag: bag path or an open :class:`~workzone_ros.bagio.BagReader` (then owned here).
            rate: time scale; 0 plays as fast as possible.
            start: seconds to skip from the beginning of the bag.
            loop: start over at the end until stopped.
            topics: only these bag topics (all when None).
            remap: bag topic -> published topic.
            clock_hz: steady ``/clock`` rate while waiting (0: /clock only at messages;
                negative: no /clock at all).
            quiet: no progress output.
            delay: seconds to wait after creating the publishers, before the first message.
            wait_for: topics (published names, or ``'*'`` for all) that must have a matched
                subscriber before playback starts, or a dict of topic -> the subscribers
                to match (all of the graph's: a node whose subscription is matched later
                would miss the first messages); waits up to ``wait_timeout``.
            wait_timeout: the longest wait for ``wait_for`` (then plays anyway, with a note).
            context: an initialised rclpy Context to use; by default a private one is created
                and shut down by :meth:`run`.
            node_name: the player node's name.
            progress_stream: where progress goes (default stderr).
            log: callable for one-line notes (default: print to ``progress_stream``).
            cuts: topics withheld for a window of bag time (:class:`Cut`).

        Raises:
            BagError: missing, empty, corrupt bag, or nothing to play on ``topics``.
            ValueError: negative rate or start.
        """
        if rate < 0 or start < 0:
            raise ValueError('rate and start must be >= 0')
        self.reader = bag if isinstance(bag, BagReader) else open_reader(bag)
        self.rate = float(rate)
        self.loop = loop
        self.remap = dict(remap or {})
        self.clock_hz = float(clock_hz)
        self.quiet = quiet
        self.delay = float(delay)
        self.wait_for = dict(wait_for) if isinstance(wait_for, dict) else {
            t: 1 for t in wait_for}
        self.wait_timeout = float(wait_timeout)
        self.node_name = node_name
        self._context = context
        self._stream = progress_stream or sys.stderr
        self._log = log or (lambda text: print(text, file=self._stream, flush=True))
        self._stop = threading.Event()
        self.stats = PlayStats()
        self.cuts = list(cuts)
        self._cutting: set[Cut] = set()
        known = self.reader.topics
        if topics is None:
            self.topics = sorted(known)
        else:
            missing = [t for t in topics if t not in known]
            if missing:
                self._log(f'[play] not in the bag, ignored: {", ".join(missing)}')
            self.topics = [t for t in topics if t in known]
        if not self.topics or not sum(known[t].message_count for t in self.topics):
            self.reader.close()
            raise BagError(f'nothing to play: {self.reader.path} has no messages on the '
                           'selected topics')
        self.start_ns = self.reader.start_time + int(round(start * 1e9))
        if self.start_ns > self.reader.end_time:
            self.reader.close()
            raise BagError(f'--start {start} s is past the end of the bag '
                           f'({self.reader.duration / 1e9:.2f} s)')
        self.message_count = sum(known[t].message_count for t in self.topics)

    @property
    def duration_s(self) -> float:
        """Bag time that one pass covers, seconds."""
        return max(0.0, (self.reader.end_time - self.start_ns) / 1e9)

    def stop(self) -> None:
        """Ask :meth:`run` to finish after the current message (thread- and signal-safe)."""
        self._stop.set()

    @property
    def stopped(self) -> bool:
        """Whether :meth:`stop` was called."""
        return self._stop.is_set()

    # -- rclpy side -------------------------------------------------------------------------

    def _qos(self, topic: str, out_topic: str, msgtype: str):
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        info = self.reader.topics[topic]
        if topic in TRANSIENT_TOPICS or out_topic in TRANSIENT_TOPICS or info.transient_local:
            return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                              reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.TRANSIENT_LOCAL)
        depth = 10 if msgtype in SENSOR_TYPES else 100
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)

    def _make_publishers(self, node) -> dict[str, tuple[Any, str]]:
        pubs: dict[str, tuple[Any, str]] = {}
        for topic in self.topics:
            info = self.reader.topics[topic]
            out = self.remap.get(topic, topic)
            try:
                cls = message_class(info.msgtype)
            except ImportError as exc:
                self.stats.skipped_topics[topic] = f'no rclpy type: {exc}'
                self._log(f'[play] skipping {topic}: type {info.msgtype} is not installed')
                continue
            pubs[topic] = (node.create_publisher(cls, out, self._qos(topic, out, info.msgtype)),
                           out)
        return pubs

    def _wait_for_subscribers(self, pubs, clock) -> None:
        wanted = set(self.wait_for)
        if not wanted:
            return
        if '*' in wanted:
            targets = [(p, 1) for p, _ in pubs.values()]
        else:
            targets = [(p, self.wait_for[out]) for p, out in pubs.values() if out in wanted]
            if clock is not None and '/clock' in wanted:
                targets.append((clock, self.wait_for['/clock']))
        deadline = time.monotonic() + self.wait_timeout
        while not self._stop.is_set():
            waiting = [p for p, n in targets if p.get_subscription_count() < n]
            if not waiting:
                return
            if time.monotonic() > deadline:
                self._log('[play] no subscriber yet on ' + ', '.join(p.topic_name
                                                                     for p in waiting)
                          + f' after {self.wait_timeout:.0f} s; playing anyway')
                return
            self._publish_clock(clock, self.start_ns)
            self._stop.wait(0.02)

    def _publish_clock(self, clock, t_ns: int) -> None:
        if clock is None:
            return
        t_ns = max(t_ns, self._last_clock)
        self._last_clock = t_ns
        self._clock_msg.clock.sec = t_ns // 1_000_000_000
        self._clock_msg.clock.nanosec = t_ns % 1_000_000_000
        clock.publish(self._clock_msg)
        self.stats.clock_published += 1

    def run(self) -> PlayStats:
        """Play (blocking) until the end of the bag, or until :meth:`stop`.

        Returns:
            The :class:`PlayStats` of this run (also in ``self.stats``).

        Raises:
            BagError: the bag turns out to be corrupt in the middle.
        """
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock

        own = self._context is None
        context = Context() if own else self._context
        if own:
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        cpu0 = time.process_time()
        node = None
        try:
            node = rclpy.create_node(self.node_name, context=context,
                                     start_parameter_services=False)
            pubs = self._make_publishers(node)
            clock = None
            if self.clock_hz >= 0:
                clock = node.create_publisher(Clock, '/clock', 10)
            self._clock_msg = Clock()
            self._last_clock = 0
            if self.delay > 0:
                end = time.monotonic() + self.delay
                while not self._stop.is_set() and time.monotonic() < end:
                    self._publish_clock(clock, self.start_ns)
                    self._stop.wait(min(0.05, max(0.0, end - time.monotonic())))
            self._wait_for_subscribers(pubs, clock)
            while not self._stop.is_set():
                self._play_once(pubs, clock)
                if not self.loop or self._stop.is_set():
                    break
                self.stats.loops += 1
                self._last_clock = 0
            self._drain([p for p, _ in pubs.values()] + ([clock] if clock else []))
        finally:
            self.stats.cpu_s = time.process_time() - cpu0
            self.stats.interrupted = self._stop.is_set()
            if node is not None:
                node.destroy_node()
            if own:
                rclpy.try_shutdown(context=context)
            self.reader.close()
        return self.stats

    def _drain(self, publishers, timeout: float = 1.0) -> None:
        """Give reliable subscribers a moment to acknowledge the last messages (bounded).

        ``wait_for_all_acked`` holds the GIL while it blocks, and acknowledgements often wait
        for the writer's next heartbeat; so it is polled with a zero timeout, sleeping in
        between, to keep the other threads of the process (executors) running.
        """
        from rclpy.duration import Duration
        zero = Duration(nanoseconds=0)
        pending = list(publishers)
        deadline = time.monotonic() + timeout
        while pending and time.monotonic() < deadline and not self._stop.is_set():
            try:
                pending = [p for p in pending if not p.wait_for_all_acked(zero)]
            except Exception:  # noqa: BLE001 - best effort: some RMWs do not support it
                return
            if pending:
                self._stop.wait(0.02)

    def _lateness(self, late_s: float) -> None:
        """Count a message sent ``late_s`` after its time (:data:`LATE_S`)."""
        if late_s > LATE_S:
            self.stats.late += 1
            self.stats.late_max_s = max(self.stats.late_max_s, late_s)

    def _play_once(self, pubs, clock) -> None:
        stats = self.stats
        period = 1.0 / self.clock_hz if self.clock_hz > 0 else 0.05
        tty = self._stream.isatty() if hasattr(self._stream, 'isatty') else False
        next_progress = time.monotonic()
        first_t = None
        wall0 = time.monotonic()
        last_wall = wall0
        t_ns = self.start_ns
        for msg in self.reader.messages(list(pubs), start_ns=self.start_ns):
            if self._stop.is_set():
                break
            t_ns = msg.timestamp_ns
            if first_t is None:
                first_t, wall0 = t_ns, time.monotonic()
            if self.rate > 0:
                target = wall0 + (t_ns - first_t) / 1e9 / self.rate
                while True:
                    now = time.monotonic()
                    if now >= target or self._stop.is_set():
                        break
                    self._publish_clock(clock, first_t + int((now - wall0) * self.rate * 1e9))
                    if not self.quiet and now >= next_progress:
                        next_progress = self._progress(tty, t_ns - first_t, now - wall0)
                    self._stop.wait(min(period, target - now))
                if self._stop.is_set():
                    break
                self._lateness(time.monotonic() - target)
            entry = pubs.get(msg.topic)
            if entry is None:  # skipped after a conversion error
                continue
            self._publish_clock(clock, t_ns)
            if self.cuts and self._withheld(msg.topic, (t_ns - self.reader.start_time) / 1e9):
                continue
            pub = entry[0]
            try:
                data = self.reader.to_cdr(msg)
            except BagError as exc:
                self._log(f'[play] skipping {msg.topic}: {exc}')
                stats.skipped_topics[msg.topic] = str(exc)
                del pubs[msg.topic]
                continue
            pub.publish(data)
            stats.published += 1
            stats.per_topic[msg.topic] = stats.per_topic.get(msg.topic, 0) + 1
            last_wall = time.monotonic()
            if not self.quiet and last_wall >= next_progress:
                next_progress = self._progress(tty, t_ns - first_t, last_wall - wall0)
        if first_t is not None:
            stats.bag_s = (t_ns - first_t) / 1e9
            stats.wall_s = last_wall - wall0
        if not self.quiet:
            if tty:
                self._stream.write('\n')
            self._log(f'[play] {"stopped" if self._stop.is_set() else "done"}: '
                      f'{stats.published} messages, bag {stats.bag_s:.1f} s in wall '
                      f'{stats.wall_s:.1f} s')

    def _withheld(self, topic: str, bag_s: float) -> bool:
        """Whether a cut withholds this message; logs each cut as it starts and ends."""
        hit = False
        for cut in self.cuts:
            inside = cut.start_s <= bag_s < cut.start_s + cut.duration_s
            if inside and cut not in self._cutting:
                self._cutting.add(cut)
                self._log(f'[play] cut {cut.topic} at {bag_s:.2f} s for {cut.duration_s:g} s')
            elif not inside and cut in self._cutting:
                self._cutting.discard(cut)
                self._log(f'[play] cut {cut.topic} over at {bag_s:.2f} s')
            hit = hit or cut.covers(topic, bag_s)
        if hit:
            self.stats.withheld[topic] = self.stats.withheld.get(topic, 0) + 1
        return hit

    def _progress(self, tty: bool, bag_ns: int, wall_s: float) -> float:
        total = self.duration_s
        text = (f'[play] {_fmt_t(bag_ns / 1e9)} / {total:.1f} s  {self.stats.published:6d} msgs'
                f'  x{(bag_ns / 1e9) / wall_s if wall_s > 0 else 0.0:.2f}')
        if tty:
            self._stream.write('\r' + text + '\x1b[K')
            self._stream.flush()
            return time.monotonic() + _PROGRESS_TTY_S
        self._log(text)
        return time.monotonic() + _PROGRESS_LOG_S


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros play`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros play', description=__doc__.split('\n')[0])
    p.add_argument('bag', help='rosbag2 directory, .mcap, .db3 or ROS 1 .bag')
    p.add_argument('--rate', type=float, default=1.0, help='time scale (0 = as fast as possible)')
    p.add_argument('--max', action='store_true', help='as fast as possible (same as --rate 0)')
    p.add_argument('--start', type=float, default=0.0, metavar='S',
                   help='skip the first S seconds of the bag')
    p.add_argument('--loop', action='store_true', help='start over at the end')
    p.add_argument('--topics', nargs='+', metavar='T', help='only these topics')
    p.add_argument('--remap', nargs='+', default=[], metavar='OLD:=NEW', help='rename topics')
    p.add_argument('--clock-hz', type=float, default=100.0, metavar='HZ',
                   help='steady /clock rate (0: only at messages, <0: no /clock)')
    p.add_argument('--delay', type=float, default=0.0, metavar='S',
                   help='wait S seconds after creating publishers')
    p.add_argument('--wait-for', nargs='+', default=[], metavar='T',
                   help="wait (up to 10 s) until these topics have a subscriber ('*' = all)")
    p.add_argument('--cut', action='append', default=[], metavar='TOPIC:START:DURATION',
                   help='withhold TOPIC (and the topics under it) for DURATION s from START s '
                   'of bag time, on every pass (repeatable): a sensor lost on a running graph')
    p.add_argument('--quiet', action='store_true', help='no progress output')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros play``; returns the exit code (2: unusable bag)."""
    args = build_parser().parse_args(argv)
    try:
        remap = parse_remaps(args.remap)
        cuts = [parse_cut(c) for c in args.cut]
    except ValueError as exc:
        print(f'workzone-ros play: error: {exc}', file=sys.stderr)
        return 2
    try:
        player = BagPlayer(args.bag, rate=0.0 if args.max else args.rate, start=args.start,
                           loop=args.loop, topics=args.topics, remap=remap,
                           clock_hz=args.clock_hz, quiet=args.quiet, delay=args.delay,
                           wait_for=args.wait_for, cuts=cuts)
    except (BagError, ValueError) as exc:
        print(f'workzone-ros play: error: {exc}', file=sys.stderr)
        return 2
    if not args.quiet:
        print(f'[play] {player.reader.summary()}', file=sys.stderr, flush=True)

    def _on_signal(signum, frame):  # noqa: ARG001
        player.stop()

    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    try:
        stats = player.run()
    except BagError as exc:
        print(f'workzone-ros play: error: {exc}', file=sys.stderr)
        return 2
    return 130 if stats.interrupted else 0


if __name__ == '__main__':
    sys.exit(main())
