"""Tests for core/sync.py: message_filters ApproximateTime semantics, baseline, pose buffer.

The stamped input/output sequences are the scenarios of message_filters'
``test_approximate_time_policy.cpp`` (same inputs, same expected sets), run on our pure
Python port with no ROS graph.
"""
import numpy as np
import pytest

from workzone_ros.core.sync import (
    ApproximateTimeSync, LatestSync, PoseBuffer, SyncError, matrix_to_quat, quat_to_matrix,
    slerp,
)

S = 1_000_000_000


def run(inputs, n=2, queue_size=10, **kw):
    """Feed (time_s, topic) pairs; return the emitted sets as tuples of seconds."""
    sync = ApproximateTimeSync(n, queue_size, **kw)
    out = []
    for t, topic in inputs:
        for stamps, msgs in sync.add(topic, int(t * S), (topic, t)):
            assert [m[1] for m in msgs] == pytest.approx([s / S for s in stamps], abs=1e-9)
            out.append(tuple(s / S for s in stamps))
    return out


def test_exact_match():
    inp = [(0, 0), (0, 1), (3, 0), (3, 1), (6, 0), (6, 1)]
    assert run(inp) == [(0, 0), (3, 3), (6, 6)]


def test_perfect_match():
    inp = [(0, 0), (1, 1), (3, 0), (4, 1), (6, 0), (7, 1)]
    assert run(inp) == [(0, 1), (3, 4)]       # (6, 7) waits for proof of optimality


def test_imperfect_match():
    inp = [(0, 0), (1, 1), (2, 0), (3, 0), (5, 1), (6, 0), (7, 1)]
    assert run(inp) == [(0, 1), (6, 5)]


def test_acceleration():
    inp = [(0, 0), (7, 1), (12, 0), (15, 1), (17, 0), (18, 1)]
    assert run(inp) == [(12, 7), (17, 18)]


def test_dropped_messages_queue_too_small_and_just_enough():
    inp = [(0, 0), (1, 1), (3, 1), (4, 0), (7, 1), (8, 0), (10, 0), (11, 1), (13, 0), (14, 1)]
    assert run(inp, queue_size=1) == [(4, 3), (10, 11)]
    assert run(inp, queue_size=2) == [(0, 1), (4, 3), (8, 7), (10, 11)]


def test_long_queue():
    a = [(t, 0) for t in range(9)] + [(3, 1)] + [(t, 0) for t in (9, 10, 11, 12)] + \
        [(10, 1), (13, 0)]
    assert run(a, queue_size=5) == [(10, 10)]


def test_double_publish():
    assert run([(0, 0), (1, 1), (3, 1), (3, 0)]) == [(0, 1), (3, 3)]


def test_four_topics():
    inp = [(0, 0), (1, 1), (2, 2), (3, 3), (5, 0), (5, 3), (6, 1), (6, 2), (8, 0), (9, 1),
           (10, 2), (11, 3), (10, 0), (13, 0), (14, 1)]
    assert run(inp, n=4) == [(0, 1, 2, 3), (5, 6, 6, 5), (10, 9, 10, 11)]


def test_early_publish():
    inp = [(0, 0), (1, 1), (2, 2), (3, 3), (7, 0)]
    assert run(inp, n=4) == [(0, 1, 2, 3)]


def test_rate_bound_proves_optimality_earlier():
    inp = [(0, 0), (1, 1), (3, 0), (4, 1), (6, 0), (7, 1)]
    assert run(inp, lower_bounds_ns=[int(1.5 * S), 0]) == [(0, 1), (3, 4)]
    assert run(inp, lower_bounds_ns=[2 * S, 0]) == [(0, 1), (3, 4), (6, 7)]


def test_slop_rejects_sets_wider_than_the_maximum_interval():
    # Camera 15 Hz, LiDAR 10 Hz shifted by 50 ms: pairs are 16.7 ms apart, over a 10 ms slop.
    cam = [(i / 15.0, 0) for i in range(16)]
    lidar = [(0.05 + i / 10.0, 1) for i in range(10)]
    inp = sorted(cam + lidar)
    wide = run(inp, slop_ns=int(0.1 * S))
    tight = run(inp, slop_ns=int(0.01 * S))
    assert all(abs(a - b) <= 0.1 + 1e-9 for a, b in wide)
    assert all(abs(a - b) <= 0.01 + 1e-9 for a, b in tight)
    assert len(tight) < len(wide)
    used = [a for a, _ in wide]
    assert len(used) == len(set(used))                 # each image used at most once
    assert used == sorted(used)                        # sets come out in time order


def test_every_message_used_once_and_optimal_pairs_for_regular_streams():
    cam = [(i / 15.0, 0) for i in range(30)]
    lidar = [(0.05 + i / 10.0, 1) for i in range(20)]
    pairs = run(sorted(cam + lidar, key=lambda x: x[0]), slop_ns=int(0.05 * S))
    assert len({b for _, b in pairs}) == len(pairs)
    for a, b in pairs:                                 # each lidar stamp with its nearest image
        nearest = min((c for c, _ in cam), key=lambda c: abs(c - b))
        assert a == pytest.approx(nearest)


def test_callback_and_bad_arguments():
    got = []
    sync = ApproximateTimeSync(2, 5, callback=lambda a, b: got.append((a, b)))
    sync.add(0, 0, 'a')
    sync.add(1, 0, 'A')
    assert got == [('a', 'A')]
    with pytest.raises(SyncError):
        sync.add(2, 0, 'x')
    with pytest.raises(SyncError):
        ApproximateTimeSync(1)


def test_latest_baseline_pairs_each_image_with_the_last_cloud():
    base = LatestSync()
    assert base.add_image(0) is None
    base.add_cloud(100, 'c1')
    assert base.add_image(150) == (100, 'c1')
    assert base.add_image(190) == (100, 'c1')          # reused: the seed's behaviour
    base.add_cloud(200, 'c2')
    assert base.add_image(180) == (200, 'c2')          # even a cloud newer than the image


def _yaw_quat(yaw):
    return np.array([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)])


def test_pose_buffer_interpolates_position_and_orientation():
    buf = PoseBuffer()
    buf.add(0, [0, 0, 0], _yaw_quat(0.0))
    buf.add(20_000_000, [0.54, 0, 0], _yaw_quat(0.2))      # 27 m/s, turning
    mid = buf.at(10_000_000)
    assert mid[:3, 3] == pytest.approx([0.27, 0, 0])
    assert np.arctan2(mid[1, 0], mid[0, 0]) == pytest.approx(0.1)
    ext = buf.at(60_000_000)                                # 40 ms past the newest
    assert ext[:3, 3] == pytest.approx([1.62, 0, 0])
    assert buf.at(200_000_000) is None                      # too far to extrapolate
    assert buf.at(-200_000_000) is None


def test_pose_buffer_out_of_order_gap_and_pruning():
    buf = PoseBuffer(max_age_ns=1 * S, max_gap_ns=int(0.5 * S))
    buf.add(2 * S, [2, 0, 0], _yaw_quat(0))
    buf.add(0, [0, 0, 0], _yaw_quat(0))                     # out of order: inserted
    assert buf.span() == (2 * S, 2 * S) or len(buf) == 1    # the old one is pruned
    buf.add(int(2.2 * S), [2.2, 0, 0], _yaw_quat(0))
    buf.add(int(3.0 * S), [3.0, 0, 0], _yaw_quat(0))
    assert buf.at(int(2.1 * S))[0, 3] == pytest.approx(2.1)
    assert buf.at(int(2.6 * S)) is None                     # 0.8 s gap in the odometry
    with pytest.raises(SyncError):
        buf.add(0, [np.nan, 0, 0], _yaw_quat(0))


def test_quaternion_helpers():
    q = np.array([0.1, -0.2, 0.3, 0.9])
    q /= np.linalg.norm(q)
    assert matrix_to_quat(quat_to_matrix(q)) == pytest.approx(q)
    a, b = _yaw_quat(0.0), _yaw_quat(np.pi / 2)
    assert slerp(a, b, 0.5) == pytest.approx(_yaw_quat(np.pi / 4))
