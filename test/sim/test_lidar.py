"""Tests of the LiDAR ray caster (workzone_ros/sim/lidar.py) on small hand-built scenes."""
import numpy as np
import pytest

from workzone_ros.sim.lidar import LidarError, LidarModel, Scan, cast_scan, sign_shape_contains
from workzone_ros.sim.scenario import sign_bottom, sign_mount, stand_parts
from workzone_ros.sim.world import (
    LIDAR_IN_BASE,
    SIGN_BOTTOM_HEIGHT,
    SIGN_LATERAL,
    Box,
    Cone,
    Cylinder,
    Pose,
    Road,
    Scene,
    SignPanel,
)

DIAMOND = 1.2 * np.sqrt(2.0)          # bounding size of a 48 in diamond
SIGMA = LidarModel().range_noise_m
H = float(LIDAR_IN_BASE[2])           # lidar height above the road


def static_pose(x: float = 0.0, y: float = 0.0):
    """A lidar standing still at (x, y), looking along +x."""
    return lambda t: Pose(np.array([x, y, H]), 0.0)


def moving_pose(speed: float, x0: float = 0.0):
    """A lidar driving along +x in the middle lane."""
    return lambda t: Pose(np.array([x0 + speed * t, 0.0, H]), 0.0)


def diamond_sign(object_id: int, x: float) -> SignPanel:
    """A 1.2 m warning diamond on the right shoulder facing the ego traffic."""
    centre = np.array([x, SIGN_LATERAL, SIGN_BOTTOM_HEIGHT + DIAMOND / 2])
    return SignPanel(object_id, 'road_work_ahead', centre, np.pi, DIAMOND, DIAMOND)


def drum(object_id: int, x: float, y: float) -> Cylinder:
    """A channelizing drum with two retroreflective bands."""
    return Cylinder(object_id, 'drum', np.array([x, y, 0.0]), 0.3, 1.0, 'drum_orange',
                    [(0.75, 0.85, 'drum_band'), (0.5, 0.6, 'drum_band')])


def scene_with(*items) -> Scene:
    """A straight 2 km road with the given signs and objects."""
    scene = Scene('test', 0, Road([(2000, 0.0)]))
    for it in items:
        (scene.signs if isinstance(it, SignPanel) else scene.objects).append(it)
    return scene


@pytest.fixture(scope='module')
def sign_scan() -> tuple[Scene, Scan]:
    scene = scene_with(diamond_sign(7, 40.0),
                       Cylinder(8, 'post', np.array([40.05, SIGN_LATERAL, 0.0]), 0.04,
                                SIGN_BOTTOM_HEIGHT, 'post'),
                       drum(9, 15.0, -4.0))
    return scene, cast_scan(scene, 0.0, static_pose())


def world_xyz(scan: Scan, pose: Pose) -> np.ndarray:
    p = np.column_stack([scan.points['x'], scan.points['y'], scan.points['z']]).astype(float)
    return pose.to_world(p)


def test_points_layout_and_rings(sign_scan):
    _, scan = sign_scan
    pts = scan.points
    assert pts.dtype.names == ('x', 'y', 'z', 'intensity', 'ring')
    assert all(pts.dtype[n] == np.float32 for n in ('x', 'y', 'z', 'intensity'))
    assert pts.dtype['ring'] == np.uint16
    assert scan.object_ids.dtype == np.int32 and scan.object_ids.shape == pts.shape
    assert pts['ring'].min() == 0 and pts['ring'].max() <= 63
    assert np.isfinite(pts['x']).all()                      # misses are omitted, not NaN
    # Ring 0 is the lowest beam: on flat ground it lands nearest to the sensor.
    rng = np.hypot(pts['x'], pts['y'])
    ground = scan.object_ids == -1
    near0 = np.median(rng[ground & (pts['ring'] == 0)])
    near20 = np.median(rng[ground & (pts['ring'] == 20)])
    assert near0 < near20
    elev = np.degrees(np.arctan2(pts['z'], rng))
    assert abs(np.median(elev[pts['ring'] == 0]) - LidarModel().fov_down_deg) < 0.2


def test_sign_hits_on_plane_inside_shape_and_bright(sign_scan):
    scene, scan = sign_scan
    sign = scene.signs[0]
    idx = scan.sign_hits[7]
    assert 15 <= idx.size <= 80
    assert (scan.object_ids[idx] == 7).all()
    p = world_xyz(scan, static_pose()(0.0))[idx]
    rel = p - sign.center
    dist = rel @ sign.normal
    assert np.mean(np.abs(dist) <= 3 * SIGMA) >= 0.95
    assert np.all(np.abs(dist) <= 5 * SIGMA)
    corners = sign.corners()
    right = (corners[1] - corners[0]) / np.linalg.norm(corners[1] - corners[0])
    up = (corners[0] - corners[3]) / np.linalg.norm(corners[0] - corners[3])
    u, v = rel @ right, rel @ up
    tol = 0.03
    assert sign_shape_contains('diamond', u, v, DIAMOND / 2 + tol, DIAMOND / 2 + tol).all()
    assert (scan.points['intensity'][idx] > 150).all()


def test_drum_band_bright_body_not(sign_scan):
    _, scan = sign_scan
    on = scan.object_ids == 9
    assert on.sum() > 20
    z = world_xyz(scan, static_pose()(0.0))[on, 2]
    inten = scan.points['intensity'][on]
    band = ((z > 0.77) & (z < 0.83)) | ((z > 0.52) & (z < 0.58))
    body = ((z > 0.05) & (z < 0.45)) | ((z > 0.65) & (z < 0.72))
    assert band.sum() >= 3 and body.sum() >= 3
    assert (inten[band] > 150).all()
    assert (inten[body] < 100).all()


def test_ground_low_and_flat(sign_scan):
    _, scan = sign_scan
    ground = scan.object_ids == -1
    z = scan.points['z'][ground]
    assert np.abs(z + H).max() < 0.1
    inten = scan.points['intensity'][ground]
    assert np.median(inten) < 20 and np.percentile(inten, 99.9) < 80


def test_lane_paint_brighter_than_asphalt():
    scan = cast_scan(scene_with(), 0.0, static_pose(), LidarModel(dropout=0.0))
    pts = scan.points
    d = pts['y'].astype(float)
    near = (pts['x'] > 4) & (pts['x'] < 30)
    paint = near & (np.abs(np.abs(d) - 5.55) < 0.04)          # solid edge lines
    asphalt = near & (np.abs(d) > 2.3) & (np.abs(d) < 5.0)
    assert paint.sum() > 20 and asphalt.sum() > 200
    assert np.median(pts['intensity'][paint]) > 3 * np.median(pts['intensity'][asphalt])


def test_box_occludes_sign():
    sign = diamond_sign(7, 40.0)
    truck = Box(20, 'truck', np.array([20.0, -5.0, 0.0]), 8.0, 2.5, 3.8, 0.0, 'vehicle_paint',
                speed=0.0)
    clear = cast_scan(scene_with(sign), 0.0, static_pose())
    blocked = cast_scan(scene_with(sign, truck), 0.0, static_pose())
    assert clear.sign_hits.get(7, np.zeros(0)).size > 15
    assert blocked.sign_hits.get(7, np.zeros(0)).size == 0
    assert (blocked.object_ids == 20).sum() > 100


def test_plate_is_bright():
    car = Box(30, 'car', np.array([10.0, 0.0, 0.0]), 4.5, 1.8, 1.5, 0.0, 'vehicle_orange')
    scan = cast_scan(scene_with(car), 0.0, static_pose(), LidarModel(dropout=0.0))
    on = scan.object_ids == 30
    p = world_xyz(scan, static_pose()(0.0))[on]
    inten = scan.points['intensity'][on]
    rear = np.abs(p[:, 0] - (10.0 - 2.25)) < 0.1
    plate = rear & (np.abs(p[:, 1]) < 0.13) & (p[:, 2] > 0.47) & (p[:, 2] < 0.58)
    paint = rear & (np.abs(p[:, 1]) > 0.3) & (np.abs(p[:, 1]) < 0.6) & (p[:, 2] > 1.0)
    assert plate.sum() >= 1 and paint.sum() >= 5
    assert (inten[plate] > 150).all() and (inten[paint] < 100).all()


def test_cone_hits_within_its_surface():
    cone = Cone(40, 'cone', np.array([8.0, -2.0, 0.0]), 0.2, 0.7)
    scan = cast_scan(scene_with(cone), 0.0, static_pose(), LidarModel(dropout=0.0))
    p = world_xyz(scan, static_pose()(0.0))[scan.object_ids == 40]
    assert len(p) > 10
    radial = np.hypot(p[:, 0] - 8.0, p[:, 1] + 2.0)
    expected = 0.2 * (1 - p[:, 2] / 0.7)
    assert np.abs(radial - expected).max() < 4 * SIGMA


def test_deterministic_and_seeded(sign_scan):
    scene, scan = sign_scan
    again = cast_scan(scene, 0.0, static_pose())
    assert again.points.tobytes() == scan.points.tobytes()
    assert np.array_equal(again.object_ids, scan.object_ids)
    assert again.sign_hits.keys() == scan.sign_hits.keys()
    assert all(np.array_equal(again.sign_hits[k], scan.sign_hits[k]) for k in scan.sign_hits)
    other = cast_scan(scene, 0.0, static_pose(), scan_index=1)
    assert other.points.tobytes() != scan.points.tobytes()


def test_open_road_point_count():
    scan = cast_scan(scene_with(), 0.0, moving_pose(22.4))
    assert 100_000 <= len(scan.points) <= 135_000


def test_far_sign_gives_a_handful_of_points():
    scan = cast_scan(scene_with(diamond_sign(3, 97.0)), 0.0, static_pose())
    idx = scan.sign_hits.get(3, np.zeros(0, int))
    assert 2 <= idx.size <= 20
    assert 1 <= np.unique(scan.points['ring'][idx]).size <= 4
    assert (scan.points['intensity'][idx] > 150).all()


def test_points_in_lidar_frame_at_firing_time():
    # Static sign straight ahead: the forward column fires half a spin after t0, so a moving
    # sensor (no deskew) sees the face about speed * 0.05 s closer.
    sign = SignPanel(5, 'end_road_work', np.array([30.0, 0.0, 2.0]), np.pi, 1.2, 0.6)
    scene = scene_with(sign)
    still = cast_scan(scene, 0.0, static_pose(), LidarModel(range_noise_m=0.0))
    moving = cast_scan(scene, 0.0, moving_pose(20.0), LidarModel(range_noise_m=0.0))
    x_still = still.points['x'][still.sign_hits[5]].mean()
    x_moving = moving.points['x'][moving.sign_hits[5]].mean()
    assert x_still - x_moving == pytest.approx(20.0 * 0.05, abs=0.05)


def test_back_face_is_not_a_sign_hit():
    sign = diamond_sign(7, 40.0)
    scan = cast_scan(scene_with(sign), 0.0, static_pose(x=80.0))      # behind the sign
    assert 7 not in scan.sign_hits
    back = scan.object_ids == 7
    assert back.sum() > 5 and (scan.points['intensity'][back] < 100).all()


def test_moving_box_moves_between_scans():
    car = Box(30, 'car', np.array([20.0, 0.0, 0.0]), 4.5, 1.8, 1.5, 0.0, 'vehicle_paint',
              speed=10.0)
    scene = scene_with(car)
    a = cast_scan(scene, 0.0, static_pose(), LidarModel(range_noise_m=0.0))
    b = cast_scan(scene, 1.0, static_pose(), LidarModel(range_noise_m=0.0))
    xa = a.points['x'][a.object_ids == 30].min()
    xb = b.points['x'][b.object_ids == 30].min()
    assert xb - xa == pytest.approx(10.0, abs=0.1)


def test_octagon_and_faded_sign():
    stop = SignPanel(11, 'stop', np.array([20.0, -8.0, 2.5]), np.pi, 0.9, 0.9, fade=1.0)
    scan = cast_scan(scene_with(stop), 0.0, static_pose(), LidarModel(dropout=0.0))
    idx = scan.sign_hits[11]
    assert idx.size > 20
    rel = world_xyz(scan, static_pose()(0.0))[idx] - stop.center
    u, v = -rel[:, 1], rel[:, 2]          # the face looks along -x: its right is world -y
    assert sign_shape_contains('octagon', u, v, 0.45 + 0.03, 0.45 + 0.03).all()
    inten = scan.points['intensity'][idx]
    assert 120 < np.median(inten) < 200   # worn sheeting: 70 % of a new sign


def test_shapes():
    u = np.array([0.0, 0.55, 0.45, 0.0])
    v = np.array([0.0, 0.55, 0.0, -0.65])
    assert sign_shape_contains('diamond', u, v, 0.6, 0.6).tolist() == [True, False, True, False]
    assert sign_shape_contains('rectangle', u, v, 0.6, 0.6).tolist() == [True, True, True, False]
    assert sign_shape_contains('octagon', u, v, 0.6, 0.6).tolist() == [True, False, True, False]
    # Yield points down: the bottom-centre vertex is in, the bottom corners are out.
    tri = sign_shape_contains('triangle', np.array([0.0, 0.5]), np.array([-0.58, -0.5]),
                              0.6, 0.6)
    assert tri.tolist() == [True, False]


def test_bad_model():
    with pytest.raises(LidarError):
        LidarModel(n_beams=0)
    with pytest.raises(LidarError):
        LidarModel(fov_up_deg=-30.0)


@pytest.mark.parametrize('bottom', [0.3, 1.5])
def test_stand_mounted_sign_hits_lie_on_its_face(bottom):
    centre = np.array([20.0, -8.4, bottom + DIAMOND / 2])
    sign = SignPanel(21, 'road_work_ahead', centre, np.pi, DIAMOND, DIAMOND)
    assert sign_mount(sign) == 'stand' and sign_bottom(sign) == pytest.approx(bottom)
    ids = iter(range(100, 110))
    parts = stand_parts(sign, True, lambda: next(ids))
    scene = scene_with(sign, *parts)
    scan = cast_scan(scene, 0.0, static_pose())
    idx = scan.sign_hits[21]
    assert idx.size >= 40
    p = world_xyz(scan, static_pose()(0.0))[idx]
    rel = p - sign.center
    assert np.all(np.abs(rel @ sign.normal) <= 5 * SIGMA)
    u, v = -rel[:, 1], rel[:, 2]          # the face looks along -x: its right is world -y
    assert sign_shape_contains('diamond', u, v, DIAMOND / 2 + 0.03, DIAMOND / 2 + 0.03).all()
    assert p[:, 2].min() >= bottom - 0.03
    assert (scan.points['intensity'][idx] > 150).all()
    # the stand's parts are hit too, but never reported as the sign
    part_ids = {o.object_id for o in parts}
    on_parts = np.isin(scan.object_ids, list(part_ids))
    assert on_parts.sum() > 0 and not np.isin(idx, np.nonzero(on_parts)[0]).any()
    assert (scan.points['intensity'][on_parts] < 150).all()
