"""How ``train cnn`` draws its training crops: class balance, real share, background share
(numpy only; the training itself needs PyTorch)."""
import numpy as np
import pytest

from workzone_ros.tools.train_cnn import TrainConfig, _weights


def _sample(counts: dict, real: dict) -> tuple:
    labels = np.array([k for k, n in counts.items() for _ in range(n)])
    is_real = np.zeros(len(labels), bool)
    for k, n in real.items():
        is_real[np.flatnonzero(labels == k)[:n]] = True
    return labels, is_real


def test_draws_balance_classes_by_the_square_root_and_share_real_and_background():
    """A class with four times the crops is drawn twice as often; real crops get the same
    share of every class that has both; background its fixed share of all draws."""
    labels, real = _sample({'stop': 100, 'road_work_ahead': 400, 'background': 2000},
                           real={'stop': 10, 'road_work_ahead': 40, 'background': 500})
    w = _weights(labels, real, TrainConfig(real_share=0.4, background_share=0.3))
    mass = {k: w[labels == k].sum() for k in ('stop', 'road_work_ahead', 'background')}
    assert sum(w) == pytest.approx(1.0) and (w > 0).all()
    assert mass['road_work_ahead'] == pytest.approx(2 * mass['stop'])
    assert mass['background'] == pytest.approx(0.3)
    for k in mass:
        sel = labels == k
        assert w[sel & real].sum() / w[sel].sum() == pytest.approx(0.4)
