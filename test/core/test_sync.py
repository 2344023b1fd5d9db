"""Tests for core/sync.py: message_filters ApproximateTime semantics, baseline, pose buffer.

The stamped input/output sequences are the scenarios of message_filters'
``test_approximate_time_policy.cpp`` (same inputs, same expected sets), run on our pure
Python port with no ROS graph.
"""
import numpy as np
import pytest

from workzone_ros.core.sync import (
    ApproximateTimeSync,
    ExactStampPairs,
    LatestSync,
    NearestSync,
    PoseBuffer,
    SyncError,
    matrix_to_quat,
    quat_to_matrix,
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


MS = 1_000_000


def nearest_run(events, **kw):
    """Feed ('i'|'c', stamp_ms) events to a NearestSync; return {image_ms: set_ms or None}
    and the order in which images were decided."""
    sync = NearestSync(**kw)
    got, order = {}, []
    for kind, t in events:
        out = sync.add_image(t * MS, ('img', t)) if kind == 'i' else \
            sync.add_candidates(t * MS, ('set', t))
        for t_img, image, t_set, cands in out:
            assert image == ('img', t_img // MS)
            assert (cands is None and t_set is None) or cands == ('set', t_set // MS)
            got[t_img // MS] = None if t_set is None else t_set // MS
            order.append(t_img // MS)
    return got, order


def test_nearest_picks_the_nearest_set_and_reuses_sets():
    # All sets already there: each image takes the nearest, a set serves several images.
    ev = [('c', 0), ('c', 100), ('c', 200), ('i', 30), ('i', 60), ('i', 90), ('i', 140)]
    got, _ = nearest_run(ev, slop_ns=100 * MS, min_period_ns=100 * MS)
    assert got == {30: 0, 60: 100, 90: 100, 140: 100}


def test_nearest_ties_go_to_the_earlier_set_and_slop_is_enforced():
    ev = [('c', 0), ('c', 100), ('c', 300), ('i', 50), ('i', 200), ('i', 250)]
    got, _ = nearest_run(ev, slop_ns=60 * MS, min_period_ns=100 * MS)
    assert got == {50: 0, 200: None, 250: 300}    # 200 is 100 ms from both: over the slop


def test_nearest_waits_for_a_later_set_only_when_it_could_be_nearer():
    # 15 Hz camera, 10 Hz LiDAR stamped 50 ms later, candidates arriving after the next image.
    kw = dict(slop_ns=100 * MS, min_period_ns=100 * MS, max_wait_ns=150 * MS)
    got, order = nearest_run([('c', 50), ('i', 67)], **kw)
    assert got == {67: 50}                        # the next set (>= 150) cannot be nearer
    got, order = nearest_run([('c', 50), ('i', 133)], **kw)
    assert got == {}                              # 150 could be nearer (17 < 83 ms): wait
    got, order = nearest_run([('c', 50), ('i', 133), ('i', 200), ('c', 150)], **kw)
    assert got == {133: 150, 200: 150} and order == [133, 200]
    # Tie with the next possible set (0 is 50 ms from -50 and from 50): no wait.
    got, _ = nearest_run([('c', -50), ('i', 0)], **kw)
    assert got == {0: -50}


def test_nearest_wait_is_bounded_on_the_image_clock():
    kw = dict(slop_ns=100 * MS, min_period_ns=100 * MS, max_wait_ns=150 * MS)
    # The LiDAR stalls after 50: image 133 gives up when an image 150 ms younger arrives.
    got, order = nearest_run([('c', 50), ('i', 133), ('i', 200), ('i', 267), ('i', 283)], **kw)
    assert got == {133: 50} and order == [133]
    # No set at all yet: the images wait, then leave with none.
    got, order = nearest_run([('i', 0), ('i', 67), ('i', 133), ('i', 217)], **kw)
    assert got == {0: None, 67: None} and order == [0, 67]
    # max_wait 0: never wait, take the best set already there.
    got, _ = nearest_run([('c', 50), ('i', 133)], slop_ns=100 * MS, min_period_ns=100 * MS)
    assert got == {133: 50}


def test_nearest_pending_images_are_capped_and_a_newer_set_decides():
    kw = dict(slop_ns=100 * MS, min_period_ns=0, max_wait_ns=10 ** 12, max_pending=2)
    # No period bound: images newer than the newest set wait until a set at or after them.
    got, order = nearest_run([('c', 0), ('i', 40), ('i', 50), ('i', 60)], **kw)
    assert got == {40: 0} and order == [40]       # the oldest is forced out by the cap
    got, order = nearest_run([('c', 0), ('i', 40), ('i', 50), ('c', 70)], **kw)
    assert got == {40: 70, 50: 70}


def test_nearest_time_offset_and_late_sets():
    # Sets matched by stamp + half a spin (when the LiDAR looks forward).
    ev = [('c', 50), ('i', 133), ('c', 150), ('i', 200)]
    got, _ = nearest_run(ev, slop_ns=100 * MS, min_period_ns=100 * MS, max_wait_ns=150 * MS,
                         time_offset_ns=50 * MS)
    assert got == {133: 50, 200: 150}             # 100 vs 133 and 200 vs 200
    # A set arriving out of order is placed by its stamp for the images that follow.
    got, _ = nearest_run([('c', 0), ('c', 200), ('c', 130), ('i', 140)], slop_ns=100 * MS,
                         min_period_ns=100 * MS)
    assert got == {140: 130}


def test_nearest_bad_arguments():
    with pytest.raises(SyncError):
        NearestSync(-1)
    with pytest.raises(SyncError):
        NearestSync(10, history=0)


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


def test_frame_gaps_count_the_frames_a_busy_node_never_saw():
    from workzone_ros.core.sync import FrameGaps
    gaps = FrameGaps()
    period = 66_666_667
    got = [k for k in range(40) if k % 5 != 3]        # frames 3, 8, ..., 38 overwritten
    for k in got:
        gaps.add(1_000_000_000 + k * period)
    # the first gap comes before three steps have given the period: 7 of the 8 are counted
    assert gaps.frames == 32 and gaps.skipped == 7
    gaps.add(0)                                        # a looping bag: no gap counted
    gaps.add(period)
    assert gaps.skipped == 7 and gaps.frames == 34


def test_exact_stamp_pairs_in_either_order_and_every_unpaired_box_reported():
    """An image and its boxes pair by stamp whichever comes first; boxes more than ``size``
    frames late, boxes whose image never came and boxes over the waiting limit are each
    reported with a reason, never silently forgotten."""
    pairs = ExactStampPairs(2)
    assert pairs.add_image(1, 'i1') is None
    assert pairs.add_boxes(1, 'b1') == (('i1', 'b1'), [])          # image first
    assert pairs.add_boxes(2, 'b2') == (None, [])
    assert pairs.add_image(2, 'i2') == ('i2', 'b2')                 # boxes first
    for ns in (3, 4, 5):
        assert pairs.add_image(ns, f'i{ns}') is None                # 3 leaves the ring
    pair, dropped = pairs.add_boxes(3, 'b3')
    assert pair is None and len(dropped) == 1 and 'left the buffer' in dropped[0]
    assert pairs.processed(3) == []
    assert pairs.add_boxes(6, 'b6') == (None, [])                   # 6's image never comes
    assert pairs.add_boxes(5, 'b5') == (('i5', 'b5'), [])
    assert pairs.processed(5) == []
    assert pairs.add_boxes(8, 'b8') == (None, [])
    assert pairs.add_image(7, 'i7') is None
    assert pairs.processed(8) == ['no image with their stamp arrived']   # 6
    assert pairs.add_image(9, 'i9') is None and pairs.add_image(10, 'i10') is None
    for ns in (11, 12, 13):
        pair, dropped = pairs.add_boxes(ns, f'b{ns}')
    assert dropped == ['no image with their stamp arrived']        # over the limit of 2
    pairs.clear()
    assert pairs.add_boxes(9, 'b9') == (None, [])                   # forgotten, not late
    with pytest.raises(ValueError):
        ExactStampPairs(0)
