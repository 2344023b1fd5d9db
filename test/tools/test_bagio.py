"""bagio: round trips through MCAP / sqlite3 / ROS 1, QoS metadata, conversion, errors."""
import os

import pytest
from wz_tools_helpers import N_CHATTER, PERIOD_NS, T0, write_ros1_bag, write_ros2_bag

from workzone_ros import bagio


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_rosbag2_round_trip(tmp_path, storage):
    path = write_ros2_bag(tmp_path / 'bag', storage)
    with bagio.open_reader(path) as reader:
        assert reader.format == 'rosbag2'
        assert reader.message_count == N_CHATTER + 1 + 5
        assert reader.start_time == T0
        assert reader.duration == (N_CHATTER - 1) * PERIOD_NS
        assert set(reader.topics) == {'/chatter', '/camera/image_raw', '/workzone/state'}
        chatter = reader.topics['/chatter']
        assert (chatter.msgtype, chatter.message_count) == ('std_msgs/msg/String', N_CHATTER)
        assert all(info.is_jazzy_native for info in reader.topics.values())
        assert reader.topics['/workzone/state'].transient_local
        assert not chatter.transient_local
        msgs = list(reader.messages(['/chatter']))
        assert [m.timestamp_ns for m in msgs] == sorted(m.timestamp_ns for m in msgs)
        # native: the stored bytes are what gets published
        assert reader.to_cdr(msgs[3]) is msgs[3].rawdata
        assert reader.deserialize(msgs[3]).data == '3'
    # bare storage file, as rosbags supports it
    bare = next(p for p in path.iterdir() if p.suffix in ('.mcap', '.db3'))
    with bagio.open_reader(bare) as reader:
        assert reader.message_count == N_CHATTER + 6
        assert reader.topics['/workzone/state'].transient_local


def test_read_messages_deserializes(tmp_path):
    path = write_ros2_bag(tmp_path / 'bag')
    out = list(bagio.read_messages(path, ['/chatter', '/camera/image_raw']))
    assert [m.data for t, _, m in out if t == '/chatter'] == [str(i) for i in range(N_CHATTER)]
    img = next(m for t, _, m in out if t == '/camera/image_raw')
    assert (img.width, img.height, img.encoding) == (3, 2, 'bgr8')


def test_ros1_bag_converts_to_jazzy_cdr(tmp_path):
    path = write_ros1_bag(tmp_path / 'old.bag')
    store = bagio.typestore()
    with bagio.open_reader(path) as reader:
        assert reader.format == 'ros1' and reader.is_ros1
        assert reader.duration == (N_CHATTER - 1) * PERIOD_NS
        assert not reader.topics['/chatter'].is_jazzy_native
        assert reader.topics['/workzone/state'].transient_local     # latched
        img_msg = next(iter(reader.messages(['/camera/image_raw'])))
        img = store.deserialize_cdr(reader.to_cdr(img_msg), 'sensor_msgs/msg/Image')
        assert img.header.frame_id == 'camera' and img.header.stamp.sec == T0 // 10**9
        assert list(img.data) == list(range(18))
        first = next(iter(reader.messages(['/chatter'])))
        assert store.deserialize_cdr(reader.to_cdr(first), 'std_msgs/msg/String').data == '0'


def test_writer_rejects_existing_and_unknown(tmp_path):
    path = write_ros2_bag(tmp_path / 'bag')
    with pytest.raises(bagio.BagError, match='exists'):
        bagio.BagWriter(path)
    other = tmp_path / 'not_a_bag'
    other.mkdir()
    (other / 'keep.txt').write_text('precious')
    with pytest.raises(bagio.BagError, match='not deleting'):
        bagio.BagWriter(other, overwrite=True)
    assert (other / 'keep.txt').exists()
    with bagio.BagWriter(path, overwrite=True, storage='sqlite3') as bag:
        with pytest.raises(bagio.BagError, match='unknown message type'):
            bag.add_topic('/x', 'nope_msgs/msg/Nope')
        with pytest.raises(bagio.BagError, match='QoS'):
            bag.add_topic('/x', 'std_msgs/msg/String', qos='fast')
        with pytest.raises(bagio.BagError, match='not added'):
            bag.write('/y', 1, b'')
        bag.add_topic('/x', 'std_msgs/String')
        bag.write('/x', 5, bagio.typestore().types['std_msgs/msg/String'](data='hi'))
    assert [m.data for _, _, m in bagio.read_messages(path)] == ['hi']


def _bad_inputs(tmp_path):
    (tmp_path / 'notes.txt').write_text('hello')
    (tmp_path / 'noise.mcap').write_bytes(os.urandom(2000))
    (tmp_path / 'noise.db3').write_bytes(os.urandom(2000))
    (tmp_path / 'noise.bag').write_bytes(os.urandom(2000))
    (tmp_path / 'empty_dir').mkdir()
    truncated = write_ros2_bag(tmp_path / 'truncated')
    data = next(p for p in truncated.iterdir() if p.suffix == '.mcap')
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])
    with bagio.BagWriter(tmp_path / 'empty') as bag:
        bag.add_topic('/chatter', 'std_msgs/msg/String')
    return {
        'missing': (tmp_path / 'missing', 'not found'),
        'text file': (tmp_path / 'notes.txt', 'unknown bag format'),
        'noise mcap': (tmp_path / 'noise.mcap', 'cannot read'),
        'noise db3': (tmp_path / 'noise.db3', 'cannot read'),
        'noise bag': (tmp_path / 'noise.bag', 'cannot read'),
        'empty dir': (tmp_path / 'empty_dir', 'unknown bag format'),
        'truncated': (truncated, 'cannot read'),
        'empty bag': (tmp_path / 'empty', 'empty'),
    }


def test_errors_are_one_line_bag_errors(tmp_path):
    for name, (path, text) in _bad_inputs(tmp_path).items():
        with pytest.raises(bagio.BagError) as info:
            with bagio.open_reader(path) as reader:
                for _ in reader:
                    pass
        message = str(info.value)
        assert text in message, (name, message)
        assert '\n' not in message, name
