"""``workzone-ros bench color``: what it reports (its figures are speed, not tested here)."""
import argparse

from workzone_ros.tools import bench_color


def test_bench_color_reports_each_frame_and_the_table_ratio():
    """A short run reports p50 / p99 for both colour sets, each bench frame's median and
    orange detections (signs in view on some frames), and the per-pixel costs of the boosted
    model and the table."""
    parser = argparse.ArgumentParser()
    bench_color.add_arguments(parser)
    out = bench_color.run(parser.parse_args(['--frames', '16', '--estimators', '5']))
    for label in ('orange', 'orange+red+yellow'):
        ms = out[f'frame_ms_{label}']
        assert 0 < ms['p50'] <= ms['p99']
        assert len(ms['per_frame_p50']) == len(out['detections_by_frame'])
        assert all(v > 0 for v in ms['per_frame_p50'])
    assert any(n > 0 for n in out['detections_by_frame'])
    assert out['detections_per_frame'] == sum(out['detections_by_frame']) / len(
        out['detections_by_frame'])
    assert {'boosted_predict_proba', 'lut', 'ratio'} <= set(out['per_pixel_ns'])
