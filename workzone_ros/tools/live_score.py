"""Table IV of a live run: what ``/workzone/state`` and ``/workzone/signs`` said, scored.

``workzone-ros launch --bag BAG --state --score DIR`` records every state and sign payload the
graph published while the bag played (:class:`LiveRecorder`), then builds the per-frame
records of ``workzone-ros evaluate workzone`` from the bag's ground truth (each camera
frame gets the newest state published for a stamp at or before it) and scores them with the
same code (:func:`workzone_ros.tools.eval_workzone.score`): zone begin and end recognised,
each driving-condition change, timing errors, flicker, and the seed's Fig. 3 timeline in
``DIR/README.md``.  A frame the graph never answered counts as ``unknown`` (a dropped frame
is a wrong frame).
"""
from __future__ import annotations

import bisect
import threading
from typing import Any, Optional

__all__ = ['LiveRecorder', 'score_live', 'evaluate_live']


class LiveRecorder:
    """Keeps every ``WorkzoneState`` and ``Signs`` payload of a run, by image stamp."""

    def __init__(self, node: Any) -> None:
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String
        self._lock = threading.Lock()
        self.states: dict[int, Any] = {}
        self.signs: dict[int, Any] = {}
        latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(String, '/workzone/state', self._on_state, latched)
        node.create_subscription(String, '/workzone/signs', self._on_signs,
                                 QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))

    def _keep(self, into: dict, text: str, cls: type) -> None:
        from workzone_ros.interfaces import PayloadError, decode
        try:
            payload = decode(text, cls)
        except PayloadError:
            return
        with self._lock:
            into[payload.header.stamp.to_ns()] = payload

    def _on_state(self, msg: Any) -> None:
        from workzone_ros.interfaces import WorkzoneState
        self._keep(self.states, msg.data, WorkzoneState)

    def _on_signs(self, msg: Any) -> None:
        from workzone_ros.interfaces import Signs
        self._keep(self.signs, msg.data, Signs)


def _frames(bag: str, recorder: LiveRecorder, legible_px: float):
    """(GtWorkzone, frames) from the bag's ground truth and the recorded outputs."""
    from workzone_ros.bagio import read_messages
    from workzone_ros.core.odometry import TravelledDistance
    from workzone_ros.interfaces import GtSigns, GtWorkzone, decode
    from workzone_ros.tools.eval_workzone import Frame, _xywh, legible
    with recorder._lock:
        stamps = sorted(recorder.states)
        states = dict(recorder.states)
        signs = dict(recorder.signs)
    odo, gtw, frames, t0 = TravelledDistance(), None, [], None
    topics = ['/groundtruth/workzone', '/groundtruth/signs', '/odom']
    for topic, _, msg in read_messages(bag, topics):
        if topic == '/groundtruth/workzone':
            gtw = gtw or decode(msg.data, GtWorkzone)
            t0 = gtw.header.stamp.to_ns()
        elif topic == '/odom':
            p = msg.pose.pose.position
            stamp = msg.header.stamp
            odo.update(stamp.sec + stamp.nanosec * 1e-9, float(p.x), float(p.y))
        elif gtw is not None:
            gt = decode(msg.data, GtSigns)
            ns = gt.header.stamp.to_ns()
            k = bisect.bisect_right(stamps, ns) - 1
            st = states[stamps[k]] if k >= 0 else None
            f = Frame(t=(ns - t0) * 1e-9, odom_m=odo.distance_m)
            if st is not None:
                f.phase, f.likelihood, f.speed = st.phase, st.likelihood, st.speed_limit_mph
                f.lane_shift, f.lanes_closed = st.lane_shift, tuple(st.lanes_closed)
            pay = signs.get(ns)
            f.pred = [] if pay is None else [(s.class_key, _xywh(s.box), s.track_id)
                                             for s in pay.signs if s.category != 'unknown']
            f.gt = [(s.sign_id, s.class_key, _xywh(s.box)) for s in gt.signs
                    if legible(s, legible_px)]
            frames.append(f)
    return gtw, frames


def score_live(bag: str, recorder: LiveRecorder, report_dir: Optional[str] = None,
               tolerance_s: float = 3.0, legible_px: float = 12.0) -> Optional[dict]:
    """Score the recorded run against ``bag``'s ground truth; None without ground truth.

    Prints the Table IV block; with ``report_dir`` writes the Markdown report and timeline.
    """
    from workzone_ros.tools import eval_workzone as ev
    gtw, frames = _frames(bag, recorder, legible_px)
    if gtw is None or not frames:
        return None
    result = {'bag': bag, **ev.score(frames, gtw, tolerance_s, legible_px), 'wall_s': 0.0,
              'answered_frames': sum(1 for f in frames if f.phase != 'unknown')}
    ev.print_bag(result)
    if report_dir:
        from workzone_ros.tools.workzone_report import write_report
        opts = ev.EvalOptions(signs='live graph', tolerance_s=tolerance_s,
                              legible_px=legible_px)
        path = write_report(report_dir, [{**result, '_frames': frames}],
                            ev.summarise([result]), opts, ['(live run of the launcher)'])
        print(f'   report: {path}')
    return result


def evaluate_live(bag: str, rate: float = 1.0, params: Optional[str] = None,
                  report_dir: Optional[str] = None) -> dict:
    """``evaluate workzone --live``: the whole graph on ``bag`` through the launcher and the
    player at ``rate``; the figures of :func:`score_live` (``{'bag', 'error'}`` on failure)."""
    import tempfile
    from pathlib import Path

    from workzone_ros.tools import launcher as lch
    argv = ['--bag', bag, '--rate', str(rate), '--quiet-play', '--log-file', '',
            '--score', report_dir or tempfile.mkdtemp(prefix='workzone_live_')]
    args = lch.build_parser().parse_args(argv + (['--params', params] if params else []))
    path = Path(params) if params else lch.default_params_file()
    if path is None or not path.is_file():
        return {'bag': bag, 'error': f'params file not found: {path}'}
    args.dds_profile_file = lch.apply_dds_profile(args.dds_profile)
    run = lch.Launcher(args, lch.resolve_nodes(None), path.resolve())
    code = run.run()
    if run.score_result is None:
        return {'bag': bag, 'error': f'live run gave no score (launcher exit code {code})'}
    return run.score_result
