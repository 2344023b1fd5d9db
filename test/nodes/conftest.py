"""Node tests: a private rclpy Context and executor per test (STYLE.md, rclpy test_executor).

The ``ros`` fixture owns the context, adds nodes to one executor, spins until a condition
holds or a deadline passes (never fixed sleeps) and tears everything down afterwards.
"""
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor


class Ros:
    """A private context and executor with spin-until-condition."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, node):
        """Add ``node`` to the executor (destroyed at teardown); returns it."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def node(self, name):
        """A plain helper node (publishers / subscriptions of the test)."""
        return self.add(rclpy.create_node(name, context=self.context))

    def spin_until(self, condition, timeout=15.0, each=None):
        """Spin until ``condition()`` is true (calling ``each()`` every turn) or the deadline."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if each is not None:
                each()
            self.executor.spin_once(timeout_sec=0.1)
            if condition():
                return True
        return False

    def close(self):
        """Shut the executor down, destroy the nodes and the context."""
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def ros():
    """A :class:`Ros` for one test."""
    r = Ros()
    try:
        yield r
    finally:
        r.close()
