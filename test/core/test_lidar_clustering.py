"""Tests for core/lidar_clustering.py on hand-made clouds (Cahail et al. section 1)."""
import numpy as np
import pytest

from workzone_ros.core.lidar_clustering import (
    CANDIDATE_DTYPE,
    SIZED_CANDIDATE_DTYPE,
    Candidates,
    CandidateTracker,
    ClusterParams,
    LidarClusterError,
    PersistenceError,
    candidates_to_array,
    cluster_cloud,
    region_grow,
)
from workzone_ros.core.pointcloud import make_points

AZ_RES = np.radians(0.17)      # HDL-64E-like column spacing
EL_RES = np.radians(0.42)      # ring spacing


def plate(x, y_center, z_center, width, height, intensity=220.0, thickness=0.0):
    """Returns of a vertical plate facing the sensor, sampled like a spinning LiDAR."""
    r = np.hypot(x, y_center)
    ny = max(int(width / (r * AZ_RES)), 1)
    nz = max(int(height / (r * EL_RES)), 1)
    yy, zz = np.meshgrid(np.linspace(y_center - width / 2, y_center + width / 2, ny),
                         np.linspace(z_center - height / 2, z_center + height / 2, nz))
    xx = np.full(yy.size, float(x)) + np.random.default_rng(0).normal(0, thickness, yy.size)
    return np.column_stack([xx, yy.ravel(), zz.ravel(), np.full(yy.size, intensity)])


def cloud(*parts):
    a = np.vstack(parts) if parts else np.zeros((0, 4))
    return make_points(x=a[:, 0].astype(np.float32), y=a[:, 1].astype(np.float32),
                       z=a[:, 2].astype(np.float32), intensity=a[:, 3].astype(np.float32))


def ground(n=2000, intensity=8.0, z=-1.95):
    rng = np.random.default_rng(1)
    return np.column_stack([rng.uniform(2, 80, n), rng.uniform(-15, 15, n), np.full(n, z),
                            np.full(n, intensity)])


def test_two_signs_close_together_stay_apart():
    # Two 1.2 m signs at 20 m, 0.8 m apart edge to edge (threshold at 20 m: 0.3 + 0.24 m).
    pts = cloud(plate(20, -6.0, 0.8, 1.2, 1.2), plate(20, -8.0, 0.8, 1.2, 1.2), ground())
    res = cluster_cloud(pts)
    c = res.candidates
    assert len(c) == 2
    assert sorted(np.round(c.center[:, 1], 1)) == [-8.0, -6.0]
    assert np.all(c.radius < 1.0)


def test_sign_and_its_post_give_one_candidate_on_the_face():
    face = plate(25, -9.0, 0.75, 1.2, 1.2)                        # bottom 2.1 m above road
    post = plate(25, -9.0, -1.0, 0.1, 1.9, intensity=40.0)        # dull galvanised post
    res = cluster_cloud(cloud(face, post, ground()))
    c = res.candidates
    assert len(c) == 1
    assert c.center[0] == pytest.approx([25, -9.0, 0.75], abs=0.05)
    assert c.count[0] == face.shape[0]


def test_bright_post_below_the_band_does_not_reject_the_sign():
    face = plate(25, -9.0, 0.75, 1.2, 1.2)
    res = cluster_cloud(cloud(face, plate(25, -9.0, -1.0, 0.1, 1.9, intensity=40.0)))
    assert len(res.candidates) == 1


def test_sparse_far_sign_on_one_ring():
    # The PJLab guide board: 12 points on one ring at ~97 m, ~0.3 m apart.
    y = np.linspace(2.4, -1.4, 12)
    far = np.column_stack([np.full(12, 97.0), y, np.full(12, 5.2), np.full(12, 180.0)])
    res = cluster_cloud(cloud(far, ground()))
    assert len(res.candidates) == 1
    assert res.candidates.count[0] == 12
    assert res.candidates.center[0, 0] == pytest.approx(97.0)


def test_empty_cloud():
    res = cluster_cloud(cloud())
    assert len(res.candidates) == 0 and res.n_clusters == 0
    assert candidates_to_array(res.candidates).dtype == SIZED_CANDIDATE_DTYPE
    assert set(CANDIDATE_DTYPE.names) < set(SIZED_CANDIDATE_DTYPE.names)


def test_all_nan_cloud():
    a = np.full((500, 4), np.nan)
    res = cluster_cloud(cloud(a))
    assert len(res.candidates) == 0


def test_nan_points_are_ignored_next_to_a_sign():
    a = np.full((50, 4), np.nan)
    a[:, 3] = 250.0
    res = cluster_cloud(cloud(a, plate(20, -7, 0.8, 1.2, 1.2)))
    assert len(res.candidates) == 1


def test_cloud_without_intensity_is_a_clear_error():
    pts = make_points(x=np.ones(3, np.float32), y=np.ones(3, np.float32),
                      z=np.ones(3, np.float32))
    with pytest.raises(LidarClusterError, match="no 'intensity' field"):
        cluster_cloud(pts)


def test_prefilter_region_height_and_intensity():
    params = ClusterParams()
    parts = [
        plate(20, -7, 0.8, 1.2, 1.2, intensity=60.0),     # too dull
        plate(20, -7, -1.5, 1.2, 0.4),                    # plate height: below the band
        plate(-20, -7, 0.8, 1.2, 1.2),                    # behind
        plate(20, 9.0, 0.8, 1.2, 1.2),                    # left side, on by default
    ]
    res = cluster_cloud(cloud(*parts, ground()), params)
    left = res.candidates
    assert len(left) == 1 and left.center[0, 1] == pytest.approx(9.0, abs=0.05)
    # Where each bright point went: 4 plates bright, 3 in the region, 2 in the band.
    assert res.funnel['bright'] == sum(len(p) for p in parts[1:])
    assert len(cluster_cloud(cloud(*parts), params.with_(left_max=4.0)).candidates) == 0


def test_range_dependent_threshold():
    # Two points 0.8 m apart: separate at 10 m (d = 0.42 m), joined at 60 m (d = 1.02 m).
    near = np.array([[10.0, 0.0, 0.0], [10.0, -0.8, 0.0]])
    far = np.array([[60.0, 0.0, 0.0], [60.0, -0.8, 0.0]])
    assert len(set(region_grow(near, 0.3, 0.012))) == 2
    assert len(set(region_grow(far, 0.3, 0.012))) == 1


def test_region_grow_equals_dbscan_min_samples_1():
    sklearn = pytest.importorskip('sklearn.cluster')
    rng = np.random.default_rng(3)
    for _ in range(10):
        pts = rng.random((int(rng.integers(2, 1500)), 3)) * rng.uniform(2, 20)
        pts[: len(pts) // 2] *= 0.05                       # a dense blob
        r = float(rng.uniform(0.1, 0.8))
        ours = region_grow(pts, r)
        ref = sklearn.DBSCAN(eps=r, min_samples=1).fit_predict(pts)
        pairs = np.unique(np.column_stack([ours, ref]), axis=0)
        assert len(pairs) == len(set(ours)) == len(set(ref))


def test_check_to_add_size_and_count():
    huge = plate(20, -8, 1.0, 8.0, 1.0)                  # a wall 8 m wide
    two = np.array([[30.0, -7.0, 1.0, 200.0], [30.0, -7.1, 1.0, 200.0]])
    res = cluster_cloud(cloud(huge, two))
    assert len(res.candidates) == 0
    assert res.rejected['too_large'] == 1 and res.rejected['few_points'] == 1


def test_flatness_rejects_a_bright_blob():
    rng = np.random.default_rng(0)
    blob = np.column_stack([rng.uniform(14.5, 15.5, 400), rng.uniform(-8.5, -7.5, 400),
                            rng.uniform(0.3, 1.3, 400), np.full(400, 200.0)])
    res = cluster_cloud(cloud(blob))
    assert len(res.candidates) == 0 and res.rejected['not_flat'] == 1
    ok = cluster_cloud(cloud(plate(15, -8, 0.8, 1.2, 1.2, thickness=0.02)))
    assert len(ok.candidates) == 1


def test_reflector_tape_outline_on_a_truck_is_rejected_as_hollow():
    # The rear of a truck outlined with retroreflective tape (PJLab scene_truck_reflectors):
    # top edge at sign height, sides down to the bumper strip: one flat, hollow cluster.
    x, y0, w = 25.0, -3.7, 2.4
    top = plate(x, y0, 1.2, w, 0.1)
    left = plate(x, y0 - w / 2, -0.2, 0.1, 2.6)
    right = plate(x, y0 + w / 2, -0.2, 0.1, 2.6)
    bumper = plate(x, y0, -1.4, w, 0.1)
    res = cluster_cloud(cloud(top, left, right, bumper, ground()))
    assert len(res.candidates) == 0
    assert res.rejected['hollow'] == 1
    off = cluster_cloud(cloud(top, left, right, bumper), ClusterParams(hollow_frac=1.0))
    assert len(off.candidates) == 1                       # the hollow test is what does it


def test_bright_strip_above_plate_and_tail_reflectors_is_rejected():
    # A van's rear: a reflective strip at sign height, a plate and two tail reflectors under it.
    x, y0 = 22.0, -3.7
    strip = plate(x, y0, -0.1, 1.4, 0.4)
    plate_ = plate(x, y0, -1.4, 0.31, 0.15)
    tails = [plate(x, y0 + dy, -1.05, 0.12, 0.1) for dy in (-0.7, 0.7)]
    res = cluster_cloud(cloud(strip, plate_, *tails, ground()))
    assert len(res.candidates) == 0 and res.rejected['reflectors_below'] == 1
    off = cluster_cloud(cloud(strip, plate_, *tails), ClusterParams(max_bright_below=-1))
    assert len(off.candidates) == 1


def diamond(x, y_center, bottom, side, ground_z=-1.95):
    """Returns of a warning diamond (side ``side`` m) whose lowest corner is ``bottom`` m up."""
    half = side * np.sqrt(0.5)
    sq = plate(x, y_center, ground_z + bottom + half, 2 * half, 2 * half)
    du = np.abs(sq[:, 1] - y_center) + np.abs(sq[:, 2] - (ground_z + bottom + half))
    return sq[du <= half]


def drum(x, y_center, radius=0.29, bands=((0.18, 0.30), (0.42, 0.54), (0.66, 0.78)),
         ground_z=-1.95):
    """Returns of a drum's reflective bands (the half cylinder facing the sensor)."""
    r = np.hypot(x, y_center)
    rows = []
    for lo, hi in bands:
        for z in np.arange(lo, hi, r * EL_RES / 3) + ground_z:
            a = np.linspace(-np.pi / 2, np.pi / 2, max(int(2 * radius / (r * AZ_RES)), 3))
            rows.append(np.column_stack([x - radius * np.cos(a), y_center + radius * np.sin(a),
                                         np.full(a.size, z), np.full(a.size, 210.0)]))
    return np.vstack(rows)


def test_low_sign_on_a_stand_is_a_candidate_and_drums_are_not():
    # A 48-in diamond (freeway size) on a portable stand, lowest corner 0.3 m above the road
    # (MUTCD 6F.03): most of its face is below the seed's 1.55 m band.  Drums and a plate
    # stay below.  (A 36-in diamond that low tops out at 1.59 m: the band's limit.)
    sign = diamond(20.0, -8.0, 0.3, 1.22)
    drums = [drum(20.0 + dx, -5.5) for dx in (-8.0, 0.0, 8.0)]
    car_plate = plate(15.0, -3.7, -1.4, 0.31, 0.15)
    res = cluster_cloud(cloud(sign, *drums, car_plate, ground()))
    c = res.candidates
    assert len(c) == 1
    assert c.center[0, :2] == pytest.approx([20.0, -8.0], abs=0.1)
    assert c.extent[0, 2] > 1.0                       # the whole face, not its top corner
    assert res.rejected['too_low'] == 4
    # The seed's per-point band keeps only the top corner of the face, if anything.
    seed = cluster_cloud(cloud(sign, *drums, car_plate, ground()),
                         ClusterParams(min_point_height=1.55))
    assert len(seed.candidates) == 0 or seed.candidates.extent[0, 2] < 0.2


def test_white_pole_is_not_a_candidate():
    pole = plate(15.0, -7.6, -0.4, 0.08, 2.6, intensity=135.0)     # PJLab scene_sign_board
    res = cluster_cloud(cloud(pole, ground()))
    assert len(res.candidates) == 0 and res.rejected['too_thin'] == 1


def _cands(centers):
    c = np.asarray(centers, float).reshape(-1, 3)
    n = len(c)
    return Candidates(c, np.full(n, 0.8), np.full(n, 200.0), np.full(n, 20), np.ones((n, 3)),
                      np.arange(n), np.ones(n, bool), np.arange(n))


def _pose(x):
    t = np.eye(4)
    t[0, 3] = x
    return t


def test_persistence_with_odometry_keeps_ids_while_moving():
    tr = CandidateTracker(k=2, n=3)
    sign_world = np.array([60.0, -8.0, 0.8])
    seen = []
    for i in range(5):
        ego = 2.7 * i                                         # 27 m/s, 10 Hz
        cands = [sign_world - [ego, 0, 0]]
        if i == 2:
            cands.append([30.0, -5.0, 1.0])                   # one-scan false positive
        out = tr.update(_cands(cands), _pose(ego))
        seen.append(out)
    ids = [int(o.ids[0]) for o in seen]
    assert len(set(ids)) == 1
    assert [bool(o.confirmed[0]) for o in seen] == [False, True, True, True, True]
    assert not seen[2].confirmed[1]


def test_persistence_without_odometry_uses_a_wide_gate():
    tr = CandidateTracker(k=2, n=3, gate_no_odom=3.5)
    a = tr.update(_cands([[60.0, -8.0, 0.8]]))
    b = tr.update(_cands([[57.3, -8.0, 0.8]]))
    assert a.ids[0] == b.ids[0] and b.confirmed[0]
    c = tr.update(_cands([[40.0, -8.0, 0.8]]))              # too far: a new track
    assert c.ids[0] != b.ids[0] and not c.confirmed[0]


def test_track_is_forgotten_after_n_misses():
    tr = CandidateTracker(k=1, n=2)
    first = tr.update(_cands([[20.0, -7.0, 0.8]]), _pose(0))
    tr.update(_cands([]), _pose(0))
    tr.update(_cands([]), _pose(0))
    again = tr.update(_cands([[20.0, -7.0, 0.8]]), _pose(0))
    assert again.ids[0] != first.ids[0]


def test_bad_parameters():
    with pytest.raises(LidarClusterError, match='min_point_height'):
        ClusterParams(min_point_height=2.0, max_point_height=1.0)
    with pytest.raises(PersistenceError, match='persistence_k'):
        CandidateTracker(k=4, n=3)
