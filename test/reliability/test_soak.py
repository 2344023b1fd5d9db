"""Time, killed nodes, lost sensors and load on the live graph: minutes of real processes,
behind the ``soak`` marker (``make soak``; ``make test`` skips them).

* the campaign of ``workzone-ros evaluate reliability`` on a short synthetic bag: a loop, a
  killed node, a lost LiDAR, a 2x replay;
* the RSS of every process over a looping bag (``WORKZONE_SOAK_S``, default 600 s): flat.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.soak


def _cli(*args, timeout):
    return subprocess.run([sys.executable, '-m', 'workzone_ros.cli', *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ))


def _campaign(tmp_path, *args, timeout):
    out = tmp_path / 'report.json'
    res = subprocess.run([sys.executable, '-m', 'workzone_ros.tools.eval_reliability',
                          '--json', str(out), *args], cwd=REPO, capture_output=True,
                         text=True, timeout=timeout, env=dict(os.environ))
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return json.loads(out.read_text())


@pytest.fixture(scope='module')
def short_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('soak') / 'zone'
    res = _cli('synth', '--scenario', str(REPO / 'test/data/scenarios/short_zone.yaml'),
               '--compressed', '-o', str(out), timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return out


@pytest.mark.timeout(1800)
def test_loop_kill_cut_and_load_on_the_live_graph(short_bag, tmp_path):
    rep = _campaign(tmp_path, '--bag', str(short_bag), '--only', 'loop,kill,cut,load',
                    '--nodes', 'projector,fusion', '--kill-at', '8', '--cuts', '/lidar:10',
                    '--rates', '2', '--hog', '0', timeout=1700)
    loop = rep['loop']
    assert loop['jump_to_unknown_s'] is not None and loop['jump_to_unknown_s'] < 1.0
    assert loop['exceptions'] == 0
    assert all(v == '1' for v in loop['time_jumps_counted'].values()), loop
    for kill in rep['kill']:
        assert kill['restarted_s'] is not None and kill['first_output_s'] is not None, kill
        assert kill['state']['false_none'] == 0, kill
    cut = rep['cut']['cuts'][0]
    assert cut['stale_listed_after_s'] is not None and cut['stale_listed_after_s'] < 1.5
    assert cut['false_none_during'] == 0 and cut['signs_during'] > 0      # camera-only
    assert rep['load'][0]['exceptions'] == 0


@pytest.mark.timeout(3600)
def test_memory_is_flat_over_a_looping_bag(tmp_path):
    seconds = float(os.environ.get('WORKZONE_SOAK_S', '600'))
    bag = REPO / 'bags' / 'demo'
    if not (bag / 'metadata.yaml').is_file():
        pytest.skip('bags/demo missing: `make demo` writes it')
    rep = _campaign(tmp_path, '--bag', str(bag), '--only', 'soak', '--soak-s',
                    f'{seconds:g}', timeout=seconds + 900)
    soak = rep['soak']
    assert soak['exceptions'] == 0 and soak['rss'], soak
    for name, rss in soak['rss'].items():
        # flat: less than 10 % (and 30 MB) growth after the first minute
        assert rss['growth_mb'] < max(30.0, 0.1 * rss['rss_mb_at_60s']), (name, rss)
