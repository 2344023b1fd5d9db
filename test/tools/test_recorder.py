"""recorder: what a node publishes lands in an MCAP bag that reads back with rosbags."""
import signal

from wz_tools_helpers import LineReader, ros_context, spin_until, start_cli  # noqa: F401

from workzone_ros import bagio
from workzone_ros.interfaces import Header, Time, WorkzoneState, decode, encode


def test_record_string_payloads_until_sigint(tmp_path, ros_context):  # noqa: F811
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    out = tmp_path / 'rec'
    proc = start_cli('record', '-o', str(out), '/workzone/state')
    reader = LineReader(proc)
    node = rclpy.create_node('rec_pub', context=ros_context)
    pub = node.create_publisher(String, '/workzone/state', 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        # Publish until the recorder's subscription is matched, then a known sequence.
        assert spin_until(ex, lambda: pub.get_subscription_count() > 0, 30), reader.text()
        sent = []
        for i in range(5):
            state = WorkzoneState(header=Header(stamp=Time(sec=100 + i)), active=bool(i % 2),
                                  likelihood=0.1 * i, phase='inside' if i % 2 else 'none')
            pub.publish(String(data=encode(state)))
            sent.append(state)
            spin_until(ex, lambda: False, 0.1)
        spin_until(ex, lambda: False, 1.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(15) == 0, reader.text()
    finally:
        if proc.poll() is None:
            proc.kill()
        ex.shutdown()
        node.destroy_node()
    got = [decode(msg.data, WorkzoneState)
           for _, _, msg in bagio.read_messages(out, topics=['/workzone/state'])]
    assert got == sent
    assert any(p.suffix == '.mcap' for p in out.iterdir())
