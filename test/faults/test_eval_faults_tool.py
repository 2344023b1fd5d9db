"""``workzone-ros evaluate faults`` end to end on one target: the node in its own process,
the table printed, the JSON written."""
import json

from workzone_ros.tools import eval_faults


def test_evaluate_faults_on_the_fusion(tmp_path, capsys):
    out = tmp_path / 'faults.json'
    code = eval_faults.main(['--examples', '2', '--nodes', 'fusion', '--json', str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert '| fusion | `signs` | 2 |' in text and ' 0 crash(es)' in text
    rows = json.loads(out.read_text())['rows']
    assert {r['topic'].rsplit('/', 1)[-1] for r in rows} == {
        'odom', 'camera_info', 'lidar', 'detections', 'signs'}
    assert all(r['crashes'] == 0 and r['recovered_pct'] == 100.0 for r in rows)
    assert all(r['diagnostics_agree'] and r['stamps_ok'] for r in rows)
