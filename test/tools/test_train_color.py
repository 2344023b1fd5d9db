"""tools.train_color: colour augmentation and background hue rotation (no training run)."""
import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.tools import train_color as tc


def _frame():
    img = np.full((60, 80, 3), (120, 122, 125), np.uint8)        # grey asphalt
    img[:20] = (200, 150, 90)                                      # blue sky
    face = np.zeros(img.shape[:2], bool)
    img[30:50, 30:50] = (0, 110, 245)                              # orange sign
    face[30:50, 30:50] = True
    return img, face


def test_augment_stays_in_camera_ranges():
    img, face = _frame()
    rng = np.random.default_rng(0)
    hues = []
    for _ in range(20):
        out = tc.augment(img, rng)
        assert out.shape == img.shape and out.dtype == np.uint8
        hues.append(int(cv2.cvtColor(out[40:41, 40:41], cv2.COLOR_BGR2HSV)[0, 0, 0]))
    # the sign stays orange-ish (hue within the jitter plus white balance), never blue
    assert all(h <= 30 or h >= 170 for h in hues) and len(set(hues)) > 2


def _n_colours(img):
    return len(np.unique(img.reshape(-1, 3), axis=0))


def test_augment_compresses_most_copies_as_jpeg(monkeypatch):
    """The colour jitter maps each colour to one colour: a two-colour frame with a hard
    edge stays two colours, unless the JPEG round trip rings and blocks at the edge.  About
    the configured share of the copies show it; with share 0 none do."""
    img = np.full((48, 64, 3), (120, 122, 125), np.uint8)          # grey asphalt
    img[13:37, 21:45] = (0, 110, 245)                               # orange sign, off-block
    share, q_lo, q_hi = tc.AUGMENT['jpeg']
    assert 0.5 <= share <= 0.9 and 20 <= q_lo < q_hi <= 101
    rng = np.random.default_rng(3)
    n = 200
    hit = sum(_n_colours(tc.augment(img, rng)) > 2 for _ in range(n))
    assert abs(hit / n - share) < 0.1
    monkeypatch.setitem(tc.AUGMENT, 'jpeg', (0.0, q_lo, q_hi))
    assert all(_n_colours(tc.augment(img, rng)) <= 2 for _ in range(50))


def test_background_hue_rotation_keeps_the_sign():
    img, face = _frame()
    rng = np.random.default_rng(1)
    hsv0 = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    out = tc.rotate_background_hue(img, face, rng, warm=1.0)
    hsv = cv2.cvtColor(out, cv2.COLOR_BGR2HSV)
    assert abs(int(hsv[40, 40, 0]) - int(hsv0[40, 40, 0])) <= 1          # sign untouched
    assert hsv[5, 5, 0] <= 31                                          # sky into earth tones
    assert abs(int(hsv[5, 5, 1]) - int(hsv0[5, 5, 1])) <= 3             # same saturation


def test_table_hsv_normalises_saturation():
    img, _ = _frame()
    dull = cv2.addWeighted(img, 0.3, np.full_like(img, 150), 0.7, 0)   # haze
    norm = cm.SatNorm(0.9, 120.0, 4.0)
    raw = cv2.cvtColor(dull, cv2.COLOR_BGR2HSV)[40, 40, 1]
    assert tc.table_hsv(dull, False, norm, 30)[40, 40, 1] > 2 * raw
    assert tc.table_hsv(dull, False, None, 30)[40, 40, 1] == raw


def _folder(root, n, y_sign, seed):
    """``n`` frames with an orange sign whose top is at ``y_sign`` (images/ and masks/)."""
    (root / 'images').mkdir(parents=True)
    (root / 'masks').mkdir()
    rng = np.random.default_rng(seed)
    for k in range(n):
        img = np.full((120, 160, 3), (120, 122, 125), np.uint8)
        img[:60] = (200, 150, 90)
        img[60:70, 100:160] = (10, 205, 250)                       # saturated yellow
        img = cv2.add(img, rng.integers(0, 10, img.shape, dtype=np.uint8))
        mask = np.zeros(img.shape[:2], np.uint8)
        img[y_sign:y_sign + 20, 20 + k:40 + k] = (0, 110, 245)
        mask[y_sign:y_sign + 20, 20 + k:40 + k] = 255
        cv2.imwrite(str(root / 'images' / f'f{k}.png'), img)
        cv2.imwrite(str(root / 'masks' / f'f{k}.png'), mask)


def test_train_with_geometry_from_fixed_camera_renders(tmp_path, capsys):
    """The table separates orange from yellow, and ``--geometry-from`` takes the mounting
    limits from other (fixed-camera) folders."""
    _folder(tmp_path / 'train', 4, 70, 0)          # jittered camera: signs low
    _folder(tmp_path / 'fixed', 3, 20, 1)           # our camera: sign bottom 20 px above mid
    out = tmp_path / 'm.npz'
    rc = tc.main([str(tmp_path / 'train'), '-o', str(out),
                  '--estimators', '30', '--augment', '0', '--val-frac', '0',
                  '--geometry-from', str(tmp_path / 'fixed'), '--geometry-margin', '0',
                  '--no-sat-norm', '--no-gray-world'])
    assert rc == 0
    capsys.readouterr()
    model = cm.load_model(out)
    hsv = cv2.cvtColor(np.array([[(0, 110, 245), (10, 205, 250)]], np.uint8),
                       cv2.COLOR_BGR2HSV)[0]
    assert model.lut('orange')[hsv[0, 0], hsv[0, 1]] > 0.5
    assert model.lut('orange')[hsv[1, 0], hsv[1, 1]] < 0.5
    # the augmentation ranges, JPEG included, are recorded with the model
    assert model.metadata['augment_ranges']['jpeg'] == list(tc.AUGMENT['jpeg'])
    geo = model.extras['geometry']
    assert geo[0] == 0.5 and abs(geo[1] - (-1.0)) < 1e-6      # (40 - 60) / 20, not (90-60)/20
