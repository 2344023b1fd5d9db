"""End to end: a generated synthetic bag replayed through the real node graph by the launcher.

Real processes, real DDS topics: `workzone-ros synth` writes a short bag, `workzone-ros launch
--bag ... --report` starts every node in its own process (and once in a single process),
plays the bag with /clock and reports what each output topic carried.
"""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NODES = 'lidar_cluster,projector,color_detector,tracker'


def _cli(*args, timeout=240):
    env = dict(os.environ)
    return subprocess.run([sys.executable, '-m', 'workzone_ros.cli', *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope='module')
def demo_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('e2e') / 'demo'
    res = _cli('synth', '--scenario', 'demo', '--duration', '2.5', '-o', str(out))
    assert res.returncode == 0, res.stderr[-2000:]
    return out


def _report(stdout: str) -> dict[str, int]:
    counts = {}
    for line in stdout.splitlines():
        m = re.match(r'^\s+(/\S+)\s+(\d+)\s', line)
        if m:
            counts[m.group(1)] = int(m.group(2))
    return counts


@pytest.mark.parametrize('mode', [[], ['--single-process']], ids=['processes', 'single'])
def test_graph_processes_a_synthetic_bag(demo_bag, mode):
    # Half rate: nodes drop frames by design when they fall behind (latest frame wins), and a
    # loaded 2-core CI machine should not turn that into a test failure.
    res = _cli('launch', '--bag', str(demo_bag), '--rate', '0.5', '--report', '--nodes', NODES,
               *mode)
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    counts = _report(res.stdout)
    frames = counts.get('/groundtruth/signs', 0)
    assert frames >= 30, out[-3000:]            # 2.5 s of 15 Hz camera
    # Every stage produced output on its topic, at the rate of its input.
    assert counts.get('/workzone/lidar/candidates', 0) >= 15, out[-3000:]
    assert counts.get('/workzone/rois', 0) >= 10, out[-3000:]
    assert counts.get('/workzone/detections', 0) >= 0.8 * frames, out[-3000:]
    assert counts.get('/workzone/tracks', 0) >= 0.8 * frames, out[-3000:]
    # The demo opens with signs in view: the detector and the tracker find them.
    m = re.search(r'ground truth: (\d+) frames, (\d+) with signs; with detections \d+ '
                  r'\(([\d.]+) %\); with tracks \d+ \(([\d.]+) %\)', res.stdout)
    assert m, out[-3000:]
    assert int(m.group(2)) > 0
    assert float(m.group(3)) >= 50.0 and float(m.group(4)) >= 50.0, m.group(0)
    # No node dropped inputs as invalid: the bag is well-formed.
    drops = re.search(r'dropped inputs \(diagnostics\): (.*)', res.stdout)
    assert drops and not re.search(r'\b[1-9]\d*\b', drops.group(1).replace('worst WARN', '')), \
        drops.group(0) if drops else out[-2000:]
