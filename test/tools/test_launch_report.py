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


def test_the_bag_waits_until_every_node_has_matched_its_inputs():
    """The launcher plays only once each node's ``/diagnostics`` says that every
    subscription is matched with each publisher of its topic the launcher sees (a reliable,
    volatile topic keeps nothing for a subscription matched late); a node that publishes no
    ``/diagnostics`` is not waited for."""
    from types import SimpleNamespace

    from workzone_ros.tools.launch_supervisor import Launcher
    publishers = {'/workzone/detections': 1, '/camera/image_raw': 0}
    reporting = [SimpleNamespace(node_name=n) for n in ('tracker', 'fusion')]
    launcher = SimpleNamespace(
        specs=[SimpleNamespace(name=n) for n in ('tracker', 'fusion', 'someone_elses_node')],
        _node=SimpleNamespace(count_publishers=lambda topic: publishers.get(topic, 0),
                              get_publishers_info_by_topic=lambda topic: reporting),
        _node_inputs={})

    def diag(name, matched):
        Launcher._on_diag(launcher, DiagnosticArray(status=[_status(name, **{
            '/workzone/detections publishers matched': matched,
            '/camera/image_raw publishers matched': -1})]))     # not subscribed

    ready = lambda: Launcher._inputs_matched(launcher)   # noqa: E731
    diag('tracker', 0)
    assert not ready()                        # fusion not heard from, tracker not matched
    diag('fusion', 1)
    assert not ready()
    diag('tracker', 1)
    assert ready()
    publishers['/workzone/detections'] = 2    # a second publisher appeared
    assert not ready()


def test_the_report_names_a_stalled_player():
    """A player that sent messages late (kept from running, then a burst) is named in the
    report's head with the count and the worst lateness; a punctual one is not."""
    import time
    from types import SimpleNamespace

    from workzone_ros.tools.launch_supervisor import Launcher
    from workzone_ros.tools.player import PlayStats
    stats = PlayStats(published=1068, bag_s=17.8)
    launcher = SimpleNamespace(_t_start=time.monotonic(), reader=SimpleNamespace(path='bag'),
                               _player=SimpleNamespace(stats=stats),
                               args=SimpleNamespace(rate=1.0))
    assert 'player:' not in Launcher._report_header(launcher)
    stats.late, stats.late_max_s = 6, 0.198
    head = Launcher._report_header(launcher)
    assert head.startswith('== report: bag 17.8 s of bag at rate 1, 1068 messages played')
    assert 'player: 6 messages sent over 100 ms late (worst 198 ms)' in head
