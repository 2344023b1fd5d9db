"""A stand-in perception node: one ``Detections`` payload per camera image, same stamp.

Subscribes ``/camera/image_raw`` (reliable, so a replayed bag is not thinned) and publishes
``/workzone/detections`` with one detection per image, so the launcher's report can compute a
100 % coarse recall on a bag whose ground truth has a sign in every frame.
"""
import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import Image
from std_msgs.msg import String

from workzone_ros.interfaces import Box, Detection, Detections, Header, Time, encode


class DummyNode(Node):
    """Image in, Detections out."""

    def __init__(self, **kwargs):
        super().__init__('dummy', **kwargs)
        self._pub = self.create_publisher(String, '/workzone/detections', 100)
        self._sub = self.create_subscription(Image, '/camera/image_raw', self._on_image, 100)
        self.get_logger().info('dummy node up')

    def _on_image(self, msg: Image) -> None:
        stamp = Time(sec=msg.header.stamp.sec, nanosec=msg.header.stamp.nanosec)
        det = Detection(box=Box(x=1.0, y=2.0, w=3.0, h=4.0), confidence=0.9)
        payload = Detections(header=Header(stamp=stamp, frame_id=msg.header.frame_id),
                             detections=[det])
        self._pub.publish(String(data=encode(payload)))


NODE_CLASS = DummyNode


def main(args=None) -> int:
    """Spin until Ctrl-C."""
    rclpy.init(args=args)
    node = None
    try:
        node = DummyNode()
        print('dummy ready', flush=True)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
