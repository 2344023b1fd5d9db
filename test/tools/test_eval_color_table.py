"""tools.eval_color: Table I accumulation and its per-size breakdown."""
import pytest

from workzone_ros.interfaces import Box
from workzone_ros.tools import eval_color as ec


def test_size_bins():
    assert [ec.size_bin(v) for v in (16, 23.9, 24, 40, 60, 200)] == [
        '<24', '<24', '24-32', '32-48', '48-80', '>=80']


def test_table_by_size_counts_found_and_area_scores_per_sign():
    t = ec.TableI()
    small, large = Box(100, 100, 20, 20), Box(300, 100, 60, 60)
    # frame 1: the small sign boxed exactly, the large one a little loose; frame 2: missed
    t.add(('all', 'dusk'), [Box(100, 100, 20, 20), Box(298, 98, 64, 64)],
          [(small, 'warning'), (large, 'regulatory')], [small, large])
    t.add(('all', 'dusk'), [], [(small, 'warning')], [small])
    s = t.summary()
    w = s['by_size']['warning']['<24']
    assert w['eligible'] == 2 and w['found'] == 0.5
    assert w['precision'] == pytest.approx(1.0) and w['recall'] == pytest.approx(1.0)
    r = s['by_size']['regulatory']['48-80']
    assert r['eligible'] == 1 and r['found'] == 1.0
    assert r['precision'] == pytest.approx(3600 / 4096) and r['recall'] == pytest.approx(1.0)
    assert s['all']['warning']['detection_rate'] == 0.5 and s['dusk']['frames'] == 2
