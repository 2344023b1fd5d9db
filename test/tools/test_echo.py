"""echo: a late echo gets the transient-local state; bad payloads print the error line."""
import subprocess
import sys

from wz_tools_helpers import REPO, cli_env

from workzone_ros.interfaces import Header, Time, WorkzoneState, encode
from workzone_ros.tools.echo import format_message, format_payload

STATE = WorkzoneState(header=Header(stamp=Time(sec=12, nanosec=5), frame_id='camera'),
                      active=True, likelihood=0.82, phase='inside', speed_limit_mph=45,
                      lane_shift='left', lanes_closed=['right'], unknowns=['speed_limit_value'])
SUMMARY = ('ACTIVE inside likelihood=0.82 speed_limit=45 lane_shift=left closed=[right] '
           'unknown=[speed_limit_value]')


def test_format_payload_and_summaries():
    text = format_payload(encode(STATE))
    assert text.splitlines()[0] == SUMMARY
    assert 'stamp 12.000000005 frame camera' in text and '"likelihood": 0.82' in text
    assert format_payload('{"schema": "workzone_ros/WorkzoneState/1"}').startswith(
        'payload error: ')
    assert format_payload('not json').startswith('payload error: ')

    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from sensor_msgs.msg import Image, PointCloud2, PointField
    img = Image(width=640, height=480, encoding='bgr8')
    assert format_message(img, 'sensor_msgs/msg/Image').startswith('Image 640x480 bgr8 stamp')
    cloud = PointCloud2(width=5, height=1, fields=[PointField(name='x'), PointField(name='y')])
    assert format_message(cloud, 'sensor_msgs/msg/PointCloud2').startswith(
        'PointCloud2 5 points fields x,y')
    diag = DiagnosticArray(status=[DiagnosticStatus(
        level=DiagnosticStatus.WARN, name='tracker', message='2 dropped',
        values=[KeyValue(key='/camera/image_raw dropped', value='2')])])
    text = format_message(diag, 'diagnostic_msgs/msg/DiagnosticArray')
    assert '[WARN] tracker: 2 dropped' in text and '/camera/image_raw dropped = 2' in text


def test_late_echo_gets_transient_local_state_and_bad_payload(ros_context):
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    node = rclpy.create_node('echo_test_pub', context=ros_context)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    try:
        node.create_publisher(String, '/workzone/state', latched).publish(
            String(data=encode(STATE)))
        node.create_publisher(String, '/workzone/bad', latched).publish(
            String(data='{"schema": "workzone_ros/Detections/1", "header": 3}'))
        # started after publishing: only transient local can deliver the messages
        procs = [subprocess.Popen([sys.executable, '-m', 'workzone_ros.cli', 'echo', topic,
                                   '--once', '--timeout', '40'], cwd=REPO, env=cli_env(),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for topic in ('/workzone/state', '/workzone/bad')]
        outs = [p.communicate(timeout=60) for p in procs]
    finally:
        node.destroy_node()
    (state_out, state_err), (bad_out, bad_err) = outs
    assert procs[0].returncode == 0, state_err
    assert SUMMARY in state_out.splitlines(), state_out
    assert '"speed_limit_mph": 45' in state_out
    assert procs[1].returncode == 0, bad_err
    errors = [line for line in bad_out.splitlines() if line.startswith('payload error: ')]
    assert len(errors) == 1 and '$.header' in errors[0], bad_out
