"""The launcher's report (``--report``) from the nodes' ``/diagnostics``."""
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from workzone_ros.nodes.color_detector import LEAN_KEY as NODE_LEAN_KEY
from workzone_ros.tools.launch_report import LEAN_KEY, ReportCollector


class _Node:
    """What the collector needs of the launcher's node, without DDS."""

    def create_subscription(self, *args, **kwargs):
        return None

    def create_timer(self, *args, **kwargs):
        return None


def _status(name, **values):
    return DiagnosticStatus(name=name, level=DiagnosticStatus.OK, values=[
        KeyValue(key=k, value=str(v)) for k, v in values.items()])


def test_the_report_says_which_frames_were_skipped_and_which_measured_lean():
    report = ReportCollector(_Node())
    topic = '/camera/image_raw'
    report._on_diag(DiagnosticArray(status=[
        _status('color_detector', **{f'{topic} messages': 453,
                                     f'{topic} skipped while busy': 2,
                                     f'{topic} dropped': 0, 'frames detected': 453,
                                     NODE_LEAN_KEY: 15}),
        _status('tracker', **{f'{topic} messages': 455, f'{topic} skipped while busy': 0,
                              'frames detected': 455, LEAN_KEY: 0})]))
    text = report.render('== report')
    assert (f'color_detector: 2 of 455 frames on {topic} skipped while busy (its input queue '
            'was full)') in text
    assert ('color_detector: 15 of 453 frames measured lean (it had fallen behind the '
            'camera)') in text
    assert 'tracker:' not in text                   # nothing skipped, nothing lean
