"""Bag reading and writing on top of rosbags, with no rclpy import.

Shared by the player, the recorder, the simulator's bag writer and the evaluation tools:

* :func:`open_reader` opens a rosbag2 directory (MCAP or sqlite3), a bare ``.mcap`` / ``.db3``
  file or a ROS 1 ``.bag`` and returns a :class:`BagReader` that iterates
  :class:`BagMessage` ``(topic, msgtype, timestamp_ns, rawdata)`` tuples in time order, with
  ``duration``, ``message_count`` and a ``topics`` dict of :class:`TopicInfo`.
* :meth:`BagReader.to_cdr` returns the ROS 2 Jazzy CDR bytes of a message: the stored bytes
  when the bag's type is wire-identical to the Jazzy type (``TopicInfo.is_jazzy_native``),
  otherwise a ROS 1 -> CDR conversion or a field-by-field migration (rosbags' converter).
* :func:`read_messages` yields deserialized rosbags messages for evaluation tools.
* :class:`BagWriter` writes MCAP (default) or sqlite3 rosbag2 bags with per-topic offered QoS
  (``reliable``, ``sensor``, ``transient_local``).

Every problem with a bag is one :class:`BagError` whose message fits on one line.
"""
from __future__ import annotations

import functools
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, NamedTuple, Optional, Union

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag1,
    ConnectionExtRosbag2,
    Nodetype,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import TypesysError

__all__ = [
    'BagError', 'BagMessage', 'TopicInfo', 'BagReader', 'BagWriter', 'open_reader',
    'read_messages', 'typestore', 'qos_profile', 'QOS_KINDS',
]

#: Offered-QoS kinds accepted by :meth:`BagWriter.add_topic`.
QOS_KINDS = ('reliable', 'sensor', 'transient_local')

_READ_ERRORS = (AnyReaderError, Reader1Error, Reader2Error, SerdeError, TypesysError)


class BagError(Exception):
    """A bag that is missing, empty, corrupt, of unknown format, or cannot be written."""


@functools.lru_cache(maxsize=1)
def typestore():
    """The rosbags typestore of ROS 2 Jazzy (the newest ROS 2 store if Jazzy is absent).

    Returns:
        A shared :class:`rosbags.typesys.store.Typestore`; do not register types into it.
    """
    store = getattr(Stores, 'ROS2_JAZZY', None) or Stores.LATEST
    return get_typestore(store)


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 300 else text[:297] + '...'


_INFINITE = QosTime(0, 0)  # rmw: 0/0 means "default" (infinite) for deadline/lifespan/lease


def qos_profile(kind: str, depth: Optional[int] = None) -> Qos:
    """A rosbags :class:`~rosbags.interfaces.Qos` for ``offered_qos_profiles`` metadata.

    Args:
        kind: ``'reliable'`` (depth 10), ``'sensor'`` (best effort, depth 5) or
            ``'transient_local'`` (reliable, transient local, depth 1).
        depth: override the history depth.

    Raises:
        BagError: unknown kind.
    """
    table = {
        'reliable': (QosReliability.RELIABLE, QosDurability.VOLATILE, 10),
        'sensor': (QosReliability.BEST_EFFORT, QosDurability.VOLATILE, 5),
        'transient_local': (QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, 1),
    }
    if kind not in table:
        raise BagError(f'unknown QoS kind {kind!r}; expected one of {", ".join(QOS_KINDS)}')
    reliability, durability, default_depth = table[kind]
    return Qos(QosHistory.KEEP_LAST, default_depth if depth is None else int(depth),
               reliability, durability, _INFINITE, _INFINITE, QosLiveliness.AUTOMATIC,
               _INFINITE, False)


# --- reading -------------------------------------------------------------------------------

class BagMessage(NamedTuple):
    """One stored message: raw bytes as stored (CDR for rosbag2, ROS 1 serialization for .bag)."""

    topic: str
    msgtype: str
    timestamp_ns: int
    rawdata: bytes


@dataclass
class TopicInfo:
    """What a bag holds on one topic.

    Attributes:
        topic: topic name.
        msgtype: ROS 2 style type name, e.g. ``sensor_msgs/msg/Image``.
        message_count: messages on this topic.
        is_jazzy_native: the stored bytes are Jazzy CDR of a wire-identical type and can be
            published as they are (``Publisher.publish(bytes)``).
        transient_local: the recorded publisher was transient local (ROS 1: latched).
        qos: the offered QoS profiles recorded with the topic (rosbag2 only).
    """

    topic: str
    msgtype: str
    message_count: int
    is_jazzy_native: bool
    transient_local: bool = False
    qos: list = field(default_factory=list)


def _same_wireformat(src, dst, src_type: str, dst_type: str, ros1_header_ok: bool) -> bool:
    """True when ``src_type`` in ``src`` serializes exactly like ``dst_type`` in ``dst``."""
    try:
        from rosbags.convert.converter import is_same_wireformat
    except ImportError:  # pragma: no cover - older rosbags: compare the field tables
        def is_same_wireformat(a, b, x, y):  # type: ignore[no-redef]
            return a.fielddefs[x] == b.fielddefs[y]
    if not ros1_header_ok:
        # is_same_wireformat treats every std_msgs/Header as equal (ROS 1 <-> 2 conversion
        # handles the seq field); for CDR -> CDR the header must be compared for real.
        try:
            if src.fielddefs.get('std_msgs/msg/Header') != dst.fielddefs.get(
                    'std_msgs/msg/Header') and _uses(src, src_type, 'std_msgs/msg/Header'):
                return False
        except (KeyError, TypeError):
            return False
    try:
        return bool(is_same_wireformat(src, dst, src_type, dst_type))
    except (KeyError, TypeError, ValueError, AssertionError):
        return False


def _uses(store, msgtype: str, needle: str, _seen: Optional[set] = None) -> bool:
    """Whether ``msgtype`` contains ``needle`` anywhere in its field tree."""
    seen = _seen if _seen is not None else set()
    if msgtype == needle:
        return True
    if msgtype in seen or msgtype not in store.fielddefs:
        return False
    seen.add(msgtype)
    for _, desc in store.fielddefs[msgtype][1]:
        sub = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
        if sub[0] == Nodetype.NAME and isinstance(sub[1], str) \
                and _uses(store, sub[1], needle, seen):
            return True
    return False


def _resolve_path(path: Path) -> Path:
    """Map a user path to what rosbags opens; raise BagError for missing / unknown inputs."""
    if not path.exists():
        raise BagError(f'bag not found: {path}')
    if path.is_dir():
        if (path / 'metadata.yaml').is_file():
            return path
        files = sorted([*path.glob('*.mcap'), *path.glob('*.db3')])
        if len(files) == 1:  # a rosbag2 directory whose recorder died before metadata.yaml
            return files[0]
        if not files:
            raise BagError(f'unknown bag format: {path} is a directory without metadata.yaml '
                           'or a .mcap/.db3 file')
        raise BagError(f'cannot read bag {path}: no metadata.yaml and {len(files)} storage '
                       'files')
    if path.suffix in ('.mcap', '.db3', '.bag'):
        return path
    raise BagError(f'unknown bag format: {path} (expected a rosbag2 directory, .mcap, .db3 '
                   'or ROS 1 .bag)')


class BagReader:
    """An open bag.  Iterating yields :class:`BagMessage` in timestamp order.

    Use :func:`open_reader` to create one; close it (or use ``with``) when done.

    Attributes:
        path: the path given by the user.
        format: ``'rosbag2'`` (directory), ``'mcap'`` / ``'db3'`` (bare file) or ``'ros1'``.
        is_ros1: the stored bytes are ROS 1 serialized.
        topics: topic name -> :class:`TopicInfo`.
    """

    def __init__(self, path: Union[str, Path]) -> None:
        """Open ``path`` (prefer :func:`open_reader`).

        Raises:
            BagError: missing path, unknown format, corrupt or unreadable bag.
        """
        self.path = Path(path)
        real = _resolve_path(self.path)
        self.format = ('ros1' if real.suffix == '.bag' else
                       'rosbag2' if real.is_dir() else real.suffix[1:])
        self.is_ros1 = self.format == 'ros1'
        try:
            self._reader = AnyReader([real], default_typestore=typestore())
            self._reader.open()
        except FileNotFoundError as exc:
            raise BagError(f'bag not found: {self.path} ({_one_line(exc)})') from None
        except _READ_ERRORS as exc:
            raise BagError(f'cannot read bag {self.path}: {_one_line(exc)}') from None
        except Exception as exc:  # noqa: BLE001 - corrupt files raise anything (struct, OS)
            raise BagError(f'cannot read bag {self.path}: corrupt or unsupported '
                           f'({type(exc).__name__}: {_one_line(exc)})') from None
        self._closed = False
        self._converters: dict[str, Callable[[bytes], bytes]] = {}
        self.topics: dict[str, TopicInfo] = {}
        jazzy = typestore()
        for conn in self._reader.connections:
            info = self.topics.get(conn.topic)
            if info is None:
                native = (not self.is_ros1 and conn.msgtype in jazzy.fielddefs
                          and conn.msgtype in self._reader.typestore.fielddefs
                          and _same_wireformat(self._reader.typestore, jazzy, conn.msgtype,
                                               conn.msgtype, ros1_header_ok=False))
                info = TopicInfo(conn.topic, conn.msgtype, 0, native)
                self.topics[conn.topic] = info
            info.message_count += int(conn.msgcount)
            ext = conn.ext
            if isinstance(ext, ConnectionExtRosbag2):
                info.qos.extend(ext.offered_qos_profiles)
                if any(q.durability == QosDurability.TRANSIENT_LOCAL
                       for q in ext.offered_qos_profiles):
                    info.transient_local = True
            elif isinstance(ext, ConnectionExtRosbag1) and ext.latching:
                info.transient_local = True

    # -- metadata --------------------------------------------------------------------------

    @property
    def message_count(self) -> int:
        """Total number of messages."""
        return int(self._reader.message_count)

    @property
    def start_time(self) -> int:
        """Timestamp (ns) of the first message (0 for an empty bag)."""
        return int(self._reader.start_time) if self.message_count else 0

    @property
    def end_time(self) -> int:
        """Timestamp (ns) of the last message (0 for an empty bag)."""
        if not self.message_count:
            return 0
        # rosbags reports end_time one nanosecond past the last message
        return max(self.start_time, int(self._reader.end_time) - 1)

    @property
    def duration(self) -> int:
        """Nanoseconds between the first and the last message."""
        return max(0, self.end_time - self.start_time)

    @property
    def rosbags_typestore(self):
        """The typestore built from the bag's own definitions (deserializes its raw bytes)."""
        return self._reader.typestore

    def summary(self) -> str:
        """A one-line description: format, duration, message and topic counts."""
        return (f'{self.path} ({self.format}): {self.duration / 1e9:.2f} s, '
                f'{self.message_count} messages on {len(self.topics)} topics')

    # -- messages --------------------------------------------------------------------------

    def messages(self, topics: Optional[Iterable[str]] = None,
                 start_ns: Optional[int] = None,
                 stop_ns: Optional[int] = None) -> Iterator[BagMessage]:
        """Yield messages in timestamp order.

        Args:
            topics: only these topics (all when None). Unknown names are ignored.
            start_ns: only messages at or after this absolute timestamp.
            stop_ns: only messages before this absolute timestamp.

        Raises:
            BagError: the storage turns out to be corrupt while reading.
        """
        wanted = None if topics is None else set(topics)
        conns: list[Connection] = [c for c in self._reader.connections
                                   if wanted is None or c.topic in wanted]
        if wanted is not None and not conns:
            return
        try:
            for conn, t_ns, raw in self._reader.messages(connections=conns, start=start_ns,
                                                         stop=stop_ns):
                yield BagMessage(conn.topic, conn.msgtype, int(t_ns),
                                 raw if isinstance(raw, bytes) else bytes(raw))
        except _READ_ERRORS as exc:
            raise BagError(f'cannot read bag {self.path}: {_one_line(exc)}') from None
        except (GeneratorExit, KeyboardInterrupt):
            raise
        except Exception as exc:  # noqa: BLE001 - truncated/corrupt chunks raise anything
            raise BagError(f'cannot read bag {self.path}: corrupt data '
                           f'({type(exc).__name__}: {_one_line(exc)})') from None

    def __iter__(self) -> Iterator[BagMessage]:
        """All messages in timestamp order."""
        return self.messages()

    def deserialize(self, message: BagMessage) -> Any:
        """Deserialize one message with the bag's own type definitions.

        Raises:
            BagError: the bytes do not match the type.
        """
        try:
            return self._reader.deserialize(message.rawdata, message.msgtype)
        except (AnyReaderError, SerdeError, Exception) as exc:  # noqa: BLE001
            raise BagError(f'cannot deserialize {message.msgtype} on {message.topic} at '
                           f'{message.timestamp_ns}: {_one_line(exc)}') from None

    def to_cdr(self, message: BagMessage) -> bytes:
        """The message as ROS 2 Jazzy CDR bytes, ready for ``Publisher.publish(bytes)``.

        Native topics return the stored bytes untouched (no deserialization).

        Raises:
            BagError: the type cannot be expressed as its Jazzy counterpart.
        """
        info = self.topics.get(message.topic)
        if info is not None and info.is_jazzy_native:
            return message.rawdata
        conv = self._converters.get(message.msgtype)
        if conv is None:
            conv = self._converters[message.msgtype] = self._make_converter(message.msgtype)
        try:
            return conv(message.rawdata)
        except BagError:
            raise
        except Exception as exc:  # noqa: BLE001 - serde raises many kinds
            raise BagError(f'cannot convert {message.msgtype} on {message.topic}: '
                           f'{_one_line(exc)}') from None

    def _make_converter(self, msgtype: str) -> Callable[[bytes], bytes]:
        jazzy = typestore()
        src = self._reader.typestore
        if msgtype not in jazzy.fielddefs:
            raise BagError(f'message type {msgtype} is not a ROS 2 Jazzy type')
        if self.is_ros1 and _same_wireformat(src, jazzy, msgtype, msgtype, ros1_header_ok=True):
            return lambda raw: bytes(jazzy.ros1_to_cdr(raw, msgtype))
        try:
            from rosbags.convert.converter import migrate_message
        except ImportError as exc:  # pragma: no cover
            raise BagError(f'message type {msgtype} differs from Jazzy and this rosbags '
                           'cannot migrate it') from exc
        cache: dict = {}
        deser = src.deserialize_ros1 if self.is_ros1 else src.deserialize_cdr

        def migrate(raw: bytes) -> bytes:
            msg = migrate_message(src, jazzy, msgtype, msgtype, cache, deser(raw, msgtype))
            return bytes(jazzy.serialize_cdr(msg, msgtype))

        return migrate

    def close(self) -> None:
        """Close the underlying storage (idempotent)."""
        if not self._closed:
            self._closed = True
            try:
                self._reader.close()
            except Exception:  # noqa: BLE001 - closing a half-broken storage
                pass

    def __enter__(self) -> 'BagReader':
        """Context manager entry."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Close on exit."""
        self.close()


def open_reader(path: Union[str, Path], allow_empty: bool = False) -> BagReader:
    """Open a bag of any supported format.

    Args:
        path: rosbag2 directory (MCAP or sqlite3), bare ``.mcap`` / ``.db3`` file, or ROS 1
            ``.bag``.
        allow_empty: accept a bag without messages (default: that is an error).

    Returns:
        An open :class:`BagReader`.

    Raises:
        BagError: missing path, unknown format, corrupt file, or empty bag.
    """
    reader = BagReader(path)
    if not allow_empty and reader.message_count == 0:
        reader.close()
        raise BagError(f'bag is empty: {path} has no messages')
    return reader


def read_messages(path: Union[str, Path], topics: Optional[Iterable[str]] = None
                  ) -> Iterator[tuple[str, int, Any]]:
    """Yield ``(topic, timestamp_ns, message)`` with messages deserialized by rosbags.

    Messages are rosbags dataclasses (``msg.header.stamp.sec``, ``msg.data`` ...), typed with
    the bag's own definitions.  Intended for evaluation tools, not for replay.

    Raises:
        BagError: as :func:`open_reader`, or undecodable data.
    """
    with open_reader(path, allow_empty=True) as reader:
        for message in reader.messages(topics):
            yield message.topic, message.timestamp_ns, reader.deserialize(message)


# --- writing -------------------------------------------------------------------------------

class BagWriter:
    """Write a rosbag2 bag (MCAP by default) from rosbags messages or CDR bytes.

    Example::

        with BagWriter('bags/out') as bag:
            bag.add_topic('/workzone/state', 'std_msgs/msg/String', qos='transient_local')
            bag.write('/workzone/state', t_ns, msg)            # rosbags message
            bag.write('/camera/image_raw', t_ns, cdr_bytes)     # already serialized
    """

    def __init__(self, path: Union[str, Path], storage: str = 'mcap', overwrite: bool = False,
                 store=None) -> None:
        """Create the bag directory.

        Args:
            path: bag directory to create.
            storage: ``'mcap'`` or ``'sqlite3'``.
            overwrite: replace an existing bag directory (one holding ``metadata.yaml`` or
                nothing); anything else at ``path`` is never deleted.
            store: typestore for type definitions (default: :func:`typestore`).

        Raises:
            BagError: bad storage name, path exists, or cannot be created.
        """
        self.path = Path(path)
        plugins = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
        if storage not in plugins:
            raise BagError(f'unknown storage {storage!r}; expected mcap or sqlite3')
        if self.path.exists():
            if not overwrite:
                raise BagError(f'{self.path} exists already (use overwrite)')
            if self.path.is_dir() and ((self.path / 'metadata.yaml').exists()
                                       or not any(self.path.iterdir())):
                shutil.rmtree(self.path)
            else:
                raise BagError(f'{self.path} exists and is not a bag directory; not deleting')
        self.store = store if store is not None else typestore()
        try:
            self._writer = Writer(self.path, version=Writer.VERSION_LATEST,
                                  storage_plugin=plugins[storage])
            self._writer.open()
        except (WriterError, OSError) as exc:
            raise BagError(f'cannot create bag {self.path}: {_one_line(exc)}') from None
        self._conns: dict[str, Connection] = {}
        self._types: dict[str, str] = {}
        self._closed = False
        self.counts: dict[str, int] = {}

    @property
    def topics(self) -> dict[str, str]:
        """Topic -> msgtype of the topics added so far."""
        return dict(self._types)

    def add_topic(self, topic: str, msgtype: str, qos: str = 'reliable',
                  depth: Optional[int] = None) -> None:
        """Register a topic before writing to it (adding the same topic+type again is a no-op).

        Args:
            topic: topic name.
            msgtype: ROS 2 type name, e.g. ``sensor_msgs/msg/Image`` (``sensor_msgs/Image`` is
                accepted).
            qos: offered QoS recorded in the metadata: ``'reliable'``, ``'sensor'`` or
                ``'transient_local'``.
            depth: history depth override.

        Raises:
            BagError: unknown type, QoS kind, or the topic exists with another type.
        """
        msgtype = _normalize_type(msgtype)
        if topic in self._types:
            if self._types[topic] != msgtype:
                raise BagError(f'topic {topic} already added as {self._types[topic]}')
            return
        if msgtype not in self.store.fielddefs:
            raise BagError(f'unknown message type {msgtype}')
        profile = qos_profile(qos, depth)
        try:
            self._conns[topic] = self._writer.add_connection(
                topic, msgtype, typestore=self.store, offered_qos_profiles=[profile])
        except WriterError as exc:
            raise BagError(f'cannot add {topic}: {_one_line(exc)}') from None
        self._types[topic] = msgtype
        self.counts[topic] = 0

    def write(self, topic: str, t_ns: int, msg_or_cdr: Union[bytes, bytearray, memoryview, Any]
              ) -> None:
        """Append one message.

        Args:
            topic: a topic registered with :meth:`add_topic`.
            t_ns: receive timestamp (ns) that orders and times the replay.
            msg_or_cdr: CDR bytes, or a rosbags message of the topic's type.

        Raises:
            BagError: unknown topic, closed bag, or a message that cannot be serialized.
        """
        conn = self._conns.get(topic)
        if conn is None:
            raise BagError(f'topic {topic} was not added to {self.path}')
        if isinstance(msg_or_cdr, (bytes, bytearray, memoryview)):
            data = msg_or_cdr
        else:
            try:
                data = self.store.serialize_cdr(msg_or_cdr, self._types[topic])
            except Exception as exc:  # noqa: BLE001 - serde raises many kinds
                raise BagError(f'cannot serialize message for {topic}: {_one_line(exc)}') \
                    from None
        try:
            self._writer.write(conn, int(t_ns), data)
        except WriterError as exc:
            raise BagError(f'cannot write {topic}: {_one_line(exc)}') from None
        self.counts[topic] += 1

    def close(self) -> None:
        """Finish the bag (writes metadata.yaml); idempotent."""
        if not self._closed:
            self._closed = True
            self._writer.close()

    def abort(self) -> None:
        """Close without finishing (the directory is left for inspection)."""
        if not self._closed:
            self._closed = True
            try:
                self._writer.close()
            except Exception:  # noqa: BLE001 - already failing
                pass

    def __enter__(self) -> 'BagWriter':
        """Context manager entry."""
        return self

    def __exit__(self, exc_type, *exc: object) -> None:
        """Close (finish) the bag, also when the body raised."""
        self.close()


def _normalize_type(msgtype: str) -> str:
    parts = msgtype.split('/')
    if len(parts) == 2:
        return f'{parts[0]}/msg/{parts[1]}'
    return msgtype

