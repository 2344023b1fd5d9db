"""Tests for the shared tool output helpers (tools/outputs.py)."""
import json

import cv2
import numpy as np
import pytest

from workzone_ros.tools.outputs import json_default, print_json, tile_grid, write_contact_sheet


def test_json_default_writes_numpy_values_and_rejects_others():
    text = json.dumps({'a': np.arange(3), 'b': np.float32(0.5), 'c': np.int64(7)},
                      default=json_default)
    assert json.loads(text) == {'a': [0, 1, 2], 'b': 0.5, 'c': 7}
    with pytest.raises(TypeError):
        json.dumps({'x': object()}, default=json_default)


def test_print_json_prints_and_writes_the_same_report(tmp_path, capsys):
    out = tmp_path / 'report.json'
    text = print_json({'share': np.float64(0.5), 'frames': np.arange(2)}, str(out))
    assert capsys.readouterr().out.strip() == text
    assert json.loads(out.read_text()) == {'share': 0.5, 'frames': [0, 1]}
    print_json({'p': tmp_path}, None, default=str)
    assert json.loads(capsys.readouterr().out) == {'p': str(tmp_path)}


def test_tile_grid_pads_the_last_row():
    tiles = [np.full((2, 3, 3), v, np.uint8) for v in (10, 20, 30, 40)]
    grid = tile_grid(tiles, cols=3, fill=255)
    assert grid.shape == (4, 9, 3)
    assert grid[0, 0, 0] == 10 and grid[2, 0, 0] == 40 and grid[2, 3, 0] == 255


def test_write_contact_sheet(tmp_path):
    tiles = [np.full((40, 60, 3), v, np.uint8) for v in (50, 100, 150, 200)]
    out = tmp_path / 'sub' / 'sheet.png'
    assert write_contact_sheet(tiles, out, cols=3, width=30)
    assert cv2.imread(str(out)).shape == (40, 90, 3)
    assert write_contact_sheet(tiles, out, cols=2, scale=0.5)
    assert cv2.imread(str(out)).shape == (40, 60, 3)
    assert not write_contact_sheet([], tmp_path / 'none.png')
    assert not (tmp_path / 'none.png').exists()


def test_seed_lists_take_ranges_and_single_seeds():
    from workzone_ros.tools.outputs import seed_list
    assert seed_list('300-303') == [300, 301, 302, 303]
    assert seed_list('1,2,5') == [1, 2, 5]
    assert seed_list('7,10-11') == [7, 10, 11]
