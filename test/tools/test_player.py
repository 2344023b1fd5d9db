"""player: real DDS replay of MCAP / sqlite3 / ROS 1 bags; timing, order, /clock, errors."""
import threading
import time

import pytest
from wz_tools_helpers import (
    N_CHATTER,
    PERIOD_NS,
    T0,
    run_cli,
    spin_until,
    write_ros1_bag,
    write_ros2_bag,
)

from workzone_ros.tools.player import BagPlayer, parse_remaps


def _play_and_receive(ros_context, bag, rate, remap=None):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String
    topic = (remap or {}).get('/chatter', '/chatter')
    node = rclpy.create_node('player_test_sub', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got, clocks = [], []
    node.create_subscription(String, topic, lambda m: got.append((time.monotonic(), m.data)),
                             QoSProfile(depth=100))
    node.create_subscription(Clock, '/clock', lambda m: clocks.append(
        m.clock.sec * 10**9 + m.clock.nanosec), QoSProfile(depth=1000))
    # the player has its own context (its own DDS participant), like a separate process
    player = BagPlayer(bag, rate=rate, remap=remap, wait_for=[topic, '/clock'],
                       wait_timeout=15.0)
    thread = threading.Thread(target=player.run, daemon=True)
    thread.start()
    try:
        assert spin_until(executor, lambda: len(got) >= N_CHATTER and not thread.is_alive(),
                          timeout=30.0), f'received {len(got)} of {N_CHATTER}'
        spin_until(executor, lambda: False, timeout=0.3)  # late /clock samples
    finally:
        player.stop()
        thread.join(5.0)
        executor.shutdown()
        node.destroy_node()
    return got, clocks, player.stats


@pytest.mark.parametrize('storage,rate', [('mcap', 1.0), ('mcap', 2.0), ('sqlite3', 2.0),
                                          ('ros1', 2.0)])
def test_replay_count_order_timing_clock(tmp_path, ros_context, storage, rate):
    bag = (write_ros1_bag(tmp_path / 'in.bag') if storage == 'ros1'
           else write_ros2_bag(tmp_path / 'in', storage))
    remap = {'/chatter': '/chatter_remapped'} if storage == 'ros1' else None
    got, clocks, stats = _play_and_receive(ros_context, bag, rate, remap)
    assert [d for _, d in got] == [str(i) for i in range(N_CHATTER)]
    assert stats.published == N_CHATTER + 6 and not stats.skipped_topics
    expected = (N_CHATTER - 1) * PERIOD_NS / 1e9 / rate
    span = got[-1][0] - got[0][0]
    assert abs(span - expected) < 0.15 + 0.3 * expected, (span, expected)
    assert clocks, 'no /clock'
    assert all(b >= a for a, b in zip(clocks, clocks[1:])), '/clock went backwards'
    assert clocks[0] >= T0 and clocks[-1] == T0 + (N_CHATTER - 1) * PERIOD_NS


def test_playback_waits_for_every_subscriber_it_is_told_of(tmp_path, ros_context):
    """``wait_for`` as topic -> subscribers: a second node that subscribes a second after
    the first still gets the whole bag (the launcher passes the graph's counts; with one
    matched subscriber the player would start before the other node's was matched)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from std_msgs.msg import String
    bag = write_ros2_bag(tmp_path / 'in', 'mcap')
    executor = SingleThreadedExecutor(context=ros_context)
    got = {'early': [], 'late': []}
    nodes = []

    def subscribe(name):
        node = rclpy.create_node(f'player_wait_{name}', context=ros_context)
        node.create_subscription(String, '/chatter', lambda m: got[name].append(m.data),
                                 QoSProfile(depth=100))
        executor.add_node(node)
        nodes.append(node)

    subscribe('early')
    player = BagPlayer(bag, rate=2.0, wait_for={'/chatter': 2}, wait_timeout=15.0)
    thread = threading.Thread(target=player.run, daemon=True)
    thread.start()
    try:
        spin_until(executor, lambda: False, timeout=1.0)
        assert not got['early']                     # still waiting for the second node
        subscribe('late')
        assert spin_until(executor, lambda: not thread.is_alive()
                          and min(len(v) for v in got.values()) >= N_CHATTER, timeout=30.0)
        assert got['early'] == got['late'] == [str(i) for i in range(N_CHATTER)]
    finally:
        player.stop()
        thread.join(5.0)
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def test_parse_remaps():
    assert parse_remaps(['/a:=/b', 'c:=d']) == {'/a': '/b', 'c': 'd'}
    with pytest.raises(ValueError):
        parse_remaps(['/a=/b'])


def test_cli_bad_bags_exit_2_with_one_line(tmp_path):
    (tmp_path / 'corrupt.mcap').write_bytes(b'\x89MCAP0\r\n' + b'\x00garbage' * 100)
    from workzone_ros.bagio import BagWriter
    with BagWriter(tmp_path / 'empty') as bag:
        bag.add_topic('/chatter', 'std_msgs/msg/String')
    for path, text in [(tmp_path / 'missing', 'not found'),
                       (tmp_path / 'empty', 'empty'),
                       (tmp_path / 'corrupt.mcap', 'cannot read')]:
        proc = run_cli('play', str(path), timeout=60)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2, proc.stderr
        assert len(lines) == 1 and text in lines[0], proc.stderr
        assert 'Traceback' not in proc.stderr


def test_a_stalled_player_counts_the_messages_it_sent_late(tmp_path, ros_context):
    """A player kept from running (here: its reader stalls 0.4 s before the fifth message)
    sends what it owes back to back; it counts those messages as late, with the worst
    lateness, for the launcher's report (a burst can overflow the nodes' queues)."""
    bag = write_ros2_bag(tmp_path / 'in', 'mcap')
    player = BagPlayer(bag, rate=1.0, wait_for=[], wait_timeout=5.0, quiet=True)
    messages = player.reader.messages

    def stalling(*args, **kwargs):
        for i, msg in enumerate(messages(*args, **kwargs)):
            if i == 4:
                time.sleep(0.4)
            yield msg

    player.reader.messages = stalling
    player.run()
    assert player.stats.published == N_CHATTER + 6
    assert player.stats.late >= 1 and 0.25 < player.stats.late_max_s < 2.0
