"""Lost inputs and files from outside, in small: an input whose publisher is gone is reported in
``/diagnostics``; the player withholds a topic for a window (``--cut``); files from outside
(params files, model files, bad options) are refused with one line and the right exit code."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Image
from wz_tools_helpers import N_CHATTER, PERIOD_NS, write_ros2_bag

from workzone_ros.nodes.base import WorkzoneNode
from workzone_ros.nodes.conversions import numpy_to_image
from workzone_ros.tools.player import BagPlayer, Cut, parse_cut


class _Listener(WorkzoneNode):
    def __init__(self, **kwargs):
        super().__init__('gap_listener', **kwargs)
        self.got = []
        self.sensor_subscription(Image, 'gap/image', self.got.append)


def test_an_input_whose_publisher_is_gone_is_reported(ros):
    node = ros.add(_Listener(context=ros.context, diagnostics_period_s=0.2,
                             silent_input_warn_s=0.5))
    upstream = ros.node('gap_upstream')
    pub = upstream.create_publisher(Image, 'gap/image', 5)
    watcher = ros.node('gap_watcher')
    diags = []
    watcher.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 50)
    img = numpy_to_image(np.zeros((2, 2, 3), np.uint8))
    assert ros.spin_until(lambda: node.got, each=lambda: pub.publish(img))
    upstream.destroy_publisher(pub)            # the upstream node is killed

    def gap():
        return [s for d in diags for s in d.status if s.name == 'gap_listener'
                and 'no publisher left' in s.message]

    assert ros.spin_until(gap, timeout=15)
    assert gap()[0].level == b'\x01'
    assert 'no message on /gap/image for' in gap()[0].message


def test_parse_cut():
    assert parse_cut('/camera:10:5') == Cut('/camera', 10.0, 5.0)
    assert Cut('/camera', 1, 2).covers('/camera/image_raw/compressed', 1.5)
    assert not Cut('/camera', 1, 2).covers('/camera_info', 1.5)
    assert not Cut('/camera', 1, 2).covers('/camera/camera_info', 3.0)
    for bad in ('camera:1:2', '/camera:1', '/camera:x:2', '/camera:1:0', '/camera:-1:2'):
        with pytest.raises(ValueError, match='bad cut'):
            parse_cut(bad)


def test_player_withholds_a_topic_for_the_window_only(tmp_path, ros_context):
    bag = write_ros2_bag(tmp_path / 'bag')
    lines = []
    player = BagPlayer(bag, rate=0.0, context=ros_context, cuts=[Cut('/chatter', 0.3, 0.3)],
                       log=lines.append)
    stats = player.run()
    window = range(int(0.3e9 / PERIOD_NS), int(0.6e9 / PERIOD_NS))
    assert stats.withheld == {'/chatter': len(window)}
    assert stats.per_topic['/chatter'] == N_CHATTER - len(window)
    assert stats.per_topic['/camera/image_raw'] == 5            # the other topics play on
    assert any('cut /chatter at 0.30 s for 0.3 s' in line for line in lines), lines
    assert any('cut /chatter over at 0.60 s' in line for line in lines), lines


def _run(*args):
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=60)


def test_launcher_and_player_refuse_a_bad_cut_with_one_line(capsys):
    from workzone_ros.tools import launcher, player
    for main in (launcher.main, player.main):
        argv = ['--cut', 'camera:1:2'] + (['bags/x'] if main is player.main else [])
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and 'bad cut' in err[0], err


def test_a_node_with_a_missing_or_unparsable_params_file_exits_2_with_one_line(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('fusion:\n  ros__parameters: [\n')
    for path, text in ((tmp_path / 'missing.yaml', 'params file not found'),
                       (bad, "Couldn't parse params file")):
        res = _run('-m', 'workzone_ros.nodes.fusion', '--ros-args', '--params-file',
                   str(path))
        assert res.returncode == 2, res.stderr
        ours = [line for line in res.stderr.splitlines()
                if line.startswith('configuration error:')]
        assert len(ours) == 1 and text in ours[0], res.stderr
        assert 'Traceback' not in res.stderr


def test_pickled_model_files_are_refused_without_unpickling(tmp_path):
    from workzone_ros.core import classifier, color_model
    path = tmp_path / 'pickled.npz'
    # an object array: loading it would run pickle; allow_pickle=False refuses it
    np.savez(path, metadata=np.array([{'schema': 'workzone_ros/SignClassifier'}],
                                     dtype=object),
             weights=np.array([print], dtype=object))    # a pickled callable
    with pytest.raises(classifier.ModelError) as err:
        classifier.load_model(path)
    assert '\n' not in str(err.value) and 'pickle' in str(err.value).lower()
    with pytest.raises(color_model.ModelError) as err:
        color_model.load_model(path)
    assert '\n' not in str(err.value)


def _calls(tree):
    import ast
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = (f.id if isinstance(f, ast.Name) else
                    f'{getattr(f.value, "id", "?")}.{f.attr}' if isinstance(f, ast.Attribute)
                    else '?')
            yield name, node


def test_no_input_can_make_a_node_execute_code_or_write_files():
    """Nothing a node reads (messages, model and parameter files) is executed: no pickle,
    marshal, eval / exec or unsafe YAML anywhere a node runs, every np.load without pickles;
    the only file any node writes is the fusion's phase checkpoint (in its run folder)."""
    import ast
    from pathlib import Path

    import workzone_ros
    root = Path(workzone_ros.__file__).parent
    unsafe = {'pickle.load', 'pickle.loads', 'marshal.loads', 'eval', 'exec', 'yaml.load',
              'joblib.load', 'torch.load'}
    writers = []
    for path in sorted((root / 'nodes').glob('*.py')) + sorted((root / 'core').rglob('*.py')):
        tree = ast.parse(path.read_text())
        for name, call in _calls(tree):
            assert name not in unsafe, f'{path.name}: {name}'
            if name.endswith('.load') and name != 'json.load':
                kw = {k.arg: k.value for k in call.keywords}
                if name == 'np.load':
                    assert isinstance(kw.get('allow_pickle'), ast.Constant) \
                        and kw['allow_pickle'].value is False, f'{path.name}: np.load'
            if name.endswith(('.write_text', '.write_bytes', '.savez_compressed', '.imwrite')) \
                    or (name == 'open' and len(call.args) > 1):
                writers.append((path.relative_to(root).as_posix(), name))
    # nodes write nothing but the fusion checkpoint; core writes only through the trainers'
    # save functions (model files a user asks for)
    assert [w for w in writers if w[0].startswith('nodes/')] == [
        ('nodes/fusion.py', 'tmp.write_text')]
    assert {w[0] for w in writers if w[0].startswith('core/')} <= {
        'core/model_files.py', 'core/color_model.py'}
