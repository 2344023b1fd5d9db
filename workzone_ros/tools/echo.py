"""``workzone-ros echo TOPIC``: print a topic, our JSON payloads readably.

The type comes from the ROS graph (waits until the topic has a publisher) and the QoS follows
the publishers: best effort if any publisher is best effort, transient local if every
publisher is (so a late ``echo /workzone/state`` prints the last state at once).

* ``std_msgs/String`` with a workzone_ros payload: a one-line summary (for ``WorkzoneState``
  e.g. ``ACTIVE inside likelihood=0.82 speed_limit=45 lane_shift=left closed=[right]``),
  then the payload as indented JSON.  An invalid payload prints its ``PayloadError`` line.
* Image, CompressedImage, PointCloud2, CameraInfo, Bool, Float32, Clock, DiagnosticArray: a
  short summary.  Anything else: its fields, long arrays shortened.
* ``--raw``: String data verbatim; other types as their fields.
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from typing import Any, Optional

from workzone_ros.interfaces import PayloadError, WorkzoneState, decode_any, to_dict

__all__ = ['format_message', 'format_payload', 'state_summary', 'payload_summary', 'main']

_LEVELS = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}


def _stamp(sec: int, nanosec: int) -> str:
    return f'{sec}.{nanosec:09d}'


def state_summary(state: WorkzoneState) -> str:
    """The one-line WorkzoneState summary a planner engineer wants to read first."""
    parts = ['ACTIVE' if state.active else 'INACTIVE', state.phase,
             f'likelihood={state.likelihood:.2f}']
    if state.speed_limit_mph is not None:
        parts.append(f'speed_limit={state.speed_limit_mph}')
    parts.append(f'lane_shift={state.lane_shift}')
    parts.append(f'closed=[{",".join(state.lanes_closed)}]')
    if state.unknowns:
        parts.append(f'unknown=[{",".join(state.unknowns)}]')
    if state.stale_inputs:
        parts.append(f'stale=[{",".join(state.stale_inputs)}]')
    return ' '.join(parts)


def payload_summary(payload: Any) -> str:
    """One line for any workzone_ros payload."""
    if isinstance(payload, WorkzoneState):
        return state_summary(payload)
    name = type(payload).__name__
    for field in ('detections', 'tracks', 'signs', 'rois'):
        items = getattr(payload, field, None)
        if items is not None:
            text = f'{name} n={len(items)}'
            if field == 'tracks':
                text += f' ({sum(1 for t in items if t.source == "tracking")} by tracking)'
            if field == 'signs' and items:
                text += ': ' + ', '.join(getattr(s, 'class_key', '?') for s in items[:6])
            return text
    if name == 'GtWorkzone':
        return (f'GtWorkzone {payload.scenario} seed={payload.seed} begin_t={payload.begin_t} '
                f'end_t={payload.end_t} events={len(payload.events)}')
    return name


def format_payload(text: str) -> str:
    """Summary line + indented JSON of a payload, or the ``payload error: ...`` line."""
    try:
        payload = decode_any(text)
    except PayloadError as exc:
        return f'payload error: {exc}'
    stamp = payload.header.stamp
    body = json.dumps(to_dict(payload), indent=2)
    return (f'{payload_summary(payload)}\nstamp {_stamp(stamp.sec, stamp.nanosec)} '
            f'frame {payload.header.frame_id or "-"}\n{body}')


def _fields(msg: Any, indent: int = 0, max_items: int = 16) -> list[str]:
    """Generic field dump; arrays longer than ``max_items`` are shortened."""
    pad = '  ' * indent
    out = []
    getter = getattr(msg, 'get_fields_and_field_types', None)
    if getter is None:
        return [pad + repr(msg)]
    for name in getter():
        value = getattr(msg, name)
        if hasattr(value, 'get_fields_and_field_types'):
            out.append(f'{pad}{name}:')
            out += _fields(value, indent + 1, max_items)
        elif isinstance(value, (list, tuple)) or hasattr(value, '__len__') \
                and not isinstance(value, (str, bytes)):
            seq = list(value[:max_items]) if len(value) > max_items else list(value)
            if seq and hasattr(seq[0], 'get_fields_and_field_types'):
                out.append(f'{pad}{name}: [{len(value)} items]')
                for item in seq:
                    out += _fields(item, indent + 1, max_items)
            else:
                more = f' ... ({len(value)} total)' if len(value) > max_items else ''
                out.append(f'{pad}{name}: {[x for x in seq]}{more}')
        else:
            out.append(f'{pad}{name}: {value!r}')
    return out


def _diag_level(level: Any) -> int:
    if isinstance(level, (bytes, bytearray)):
        return level[0] if level else 0
    return int(level)


def format_message(msg: Any, msgtype: str, raw: bool = False) -> str:
    """Human-readable text of one message of ``msgtype`` (``pkg/msg/Name``)."""
    if msgtype == 'std_msgs/msg/String':
        return msg.data if raw else format_payload(msg.data)
    if raw:
        return '\n'.join(_fields(msg))
    header = getattr(msg, 'header', None)
    stamp = '' if header is None else \
        f' stamp {_stamp(header.stamp.sec, header.stamp.nanosec)} frame {header.frame_id or "-"}'
    if msgtype == 'sensor_msgs/msg/Image':
        return f'Image {msg.width}x{msg.height} {msg.encoding}{stamp}'
    if msgtype == 'sensor_msgs/msg/CompressedImage':
        return f'CompressedImage {msg.format} {len(msg.data)} bytes{stamp}'
    if msgtype == 'sensor_msgs/msg/PointCloud2':
        fields = ','.join(f.name for f in msg.fields)
        return f'PointCloud2 {msg.width * msg.height} points fields {fields}{stamp}'
    if msgtype == 'sensor_msgs/msg/CameraInfo':
        k = [round(float(x), 2) for x in msg.k]
        return f'CameraInfo {msg.width}x{msg.height} K={k} {msg.distortion_model}{stamp}'
    if msgtype in ('std_msgs/msg/Bool', 'std_msgs/msg/Float32', 'std_msgs/msg/Float64',
                   'std_msgs/msg/Int32', 'std_msgs/msg/Int64'):
        return f'{msgtype.rsplit("/", 1)[1]} {msg.data}'
    if msgtype == 'rosgraph_msgs/msg/Clock':
        return f'Clock {_stamp(msg.clock.sec, msg.clock.nanosec)}'
    if msgtype == 'diagnostic_msgs/msg/DiagnosticArray':
        lines = [f'DiagnosticArray {len(msg.status)} status{stamp}']
        for st in msg.status:
            level = _LEVELS.get(_diag_level(st.level), str(_diag_level(st.level)))
            lines.append(f'  [{level}] {st.name}: {st.message}')
            for kv in st.values:
                if kv.value != '':
                    lines.append(f'      {kv.key} = {kv.value}')
        return '\n'.join(lines)
    return '\n'.join(_fields(msg))


def _publisher_qos(node, topic: str):
    """A subscription QoS compatible with every current publisher of ``topic``."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    infos = node.get_publishers_info_by_topic(topic)
    best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
    transient = bool(infos) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(depth=10,
                      reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                      else ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient
                      else DurabilityPolicy.VOLATILE)


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros echo`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros echo', description=__doc__.split('\n')[0])
    p.add_argument('topic')
    p.add_argument('--once', action='store_true', help='print one message and exit')
    p.add_argument('--count', type=int, metavar='N', help='print N messages and exit')
    p.add_argument('--raw', action='store_true', help='no parsing: String data verbatim')
    p.add_argument('--type', dest='msgtype', metavar='pkg/msg/Name',
                   help='do not wait for a publisher to learn the type')
    p.add_argument('--timeout', type=float, metavar='S',
                   help='give up after S seconds without the wanted messages (exit 1)')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros echo``; returns 0, 1 on timeout, 2 on a usage error."""
    args = build_parser().parse_args(argv)
    wanted = 1 if args.once else args.count
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from workzone_ros.tools.player import message_class

    stop = threading.Event()

    def _on_signal(signum, frame):  # noqa: ARG001
        stop.set()

    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    ctx = Context()
    rclpy.init(context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('workzone_echo', context=ctx, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    topic = args.topic if args.topic.startswith('/') else '/' + args.topic
    printed = 0
    code = 0
    try:
        msgtype = args.msgtype
        said_waiting = False
        t0 = time.monotonic()
        while msgtype is None:
            types = dict(node.get_topic_names_and_types()).get(topic)
            if types and node.get_publishers_info_by_topic(topic):
                msgtype = types[0]
                break
            if stop.is_set():
                return 0
            if deadline is not None and time.monotonic() > deadline:
                print(f'workzone-ros echo: no publisher on {topic}', file=sys.stderr)
                return 1
            if not said_waiting and time.monotonic() - t0 > 1.0:
                print(f'waiting for a publisher on {topic} ...', file=sys.stderr, flush=True)
                said_waiting = True
            executor.spin_once(timeout_sec=0.05)
        if msgtype.count('/') == 1:
            msgtype = msgtype.replace('/', '/msg/', 1)
        try:
            cls = message_class(msgtype)
        except ImportError as exc:
            print(f'workzone-ros echo: cannot print {msgtype}: {exc}', file=sys.stderr)
            return 2
        qos = _publisher_qos(node, topic)

        def on_message(msg) -> None:
            nonlocal printed
            if wanted is not None and printed >= wanted:
                return
            printed += 1
            text = format_message(msg, msgtype, raw=args.raw)
            print(f'--- {topic} [{msgtype}] #{printed} received {time.time():.3f}\n{text}',
                  flush=True)

        node.create_subscription(cls, topic, on_message, qos)
        while not stop.is_set() and (wanted is None or printed < wanted):
            if deadline is not None and time.monotonic() > deadline:
                print(f'workzone-ros echo: timeout after {printed} message(s) on {topic}',
                      file=sys.stderr)
                code = 1
                break
            executor.spin_once(timeout_sec=0.1)
    except BrokenPipeError:
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return code


if __name__ == '__main__':
    sys.exit(main())
