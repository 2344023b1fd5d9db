"""``evaluate tracker``: the trackers on the real dashcam clips (skipped without them); errors."""
import os
from pathlib import Path

import pytest

from workzone_ros.tools import eval_tracker as et

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'

_needs_real = pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(),
                                reason=f'real clips not found in {REAL}')


@_needs_real
def test_tracking_on_the_real_approach_keeps_the_sign_the_detector_finds():
    """On the first 110 frames of the Charlotte clip (the work-zone diamond approached,
    labelled by hand) the mean-shift tracker's outputs cover at least the sign frames the
    detections alone do: tracking never replaces a found sign by a wrong box."""
    cfgs = {k: v for k, v in et._configs().items() if k in ('detection_only', 'meanshift')}
    out = et.evaluate_real(REAL, None, cfgs, max_frames=110)
    clip = out['charlotte.mp4']
    det, ours = clip['detection_only'], clip['meanshift']
    assert det['sign_frames'] == ours['sign_frames'] > 80
    assert det['sign_share'] > 0.5                       # the detector sees the real sign
    assert ours['sign_share'] >= det['sign_share']
    assert det['covered'] == 0 and ours['covered'] <= ours['misses']
    assert out['denver.mp4']['meanshift']['sign_frames'] > 0


def test_missing_real_folder_is_a_clear_error(tmp_path, capsys):
    assert et.main(['--real', str(tmp_path / 'nope')]) == 2
    assert 'no such folder' in capsys.readouterr().err


def test_a_folder_that_is_not_a_bag_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / 'pixels').mkdir()
    assert et.main([str(tmp_path / 'pixels'), '--detector', 'gt']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'pixels' in err[0] and 'Traceback' not in err[0]
