"""``evaluate real_signs``: the per-frame real-clip figures (clips optional), clear errors."""
import os
from pathlib import Path

import pytest

from workzone_ros.tools import eval_real_signs as ers

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'


def test_the_sign_ranges_cover_the_labelled_work_zone_signs():
    ranges = ers.sign_ranges()
    assert ranges['charlotte.mp4'][0] == (0, 102)
    assert 'chicago.mp4' not in ranges          # no work-zone sign in view


def test_missing_folder_and_model_are_one_line_errors(tmp_path, capsys):
    assert ers.main(['--real', str(tmp_path / 'nope')]) == 2
    assert 'no such folder' in capsys.readouterr().err
    assert ers.main(['--real', str(tmp_path), '--model', str(tmp_path / 'm.npz')]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'm.npz' in err


@pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(), reason=f'no clips in {REAL}')
def test_a_few_frames_of_a_real_clip_give_the_figures():
    from workzone_ros.core.classifier import DEFAULT_MODEL, load_model
    from workzone_ros.resources import config_path
    r = ers.evaluate_clip(REAL / 'charlotte.mp4', load_model(config_path(DEFAULT_MODEL)), 60.0,
                          max_frames=6)
    assert r['frames'] == 6 and r['sign_frames'] == 6 and 0.0 <= r['sign_share'] <= 1.0
