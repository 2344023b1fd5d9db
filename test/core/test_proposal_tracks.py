"""Proposal tracks: a one-frame blob is never published, a repeated one keeps its id."""
import pytest

from workzone_ros.core.track.proposal_tracks import ProposalTrackConfig, ProposalTracks


def test_a_one_frame_proposal_is_never_published():
    pt = ProposalTracks()
    assert pt.step([(10, 10, 20, 20)], [0.9]) == []
    for _ in range(5):
        assert pt.step([], []) == []
    assert len(pt) == 0                      # ended after max_misses


def test_a_repeated_proposal_is_published_with_one_id():
    pt = ProposalTracks()
    out = [pt.step([(10 + k, 10, 20, 20)], [0.8]) for k in range(5)]
    assert out[0] == []
    ids = {o[0][0] for o in out[1:]}
    assert len(ids) == 1 and all(len(o) == 1 for o in out[1:])
    assert out[-1][0][1] == (14.0, 10.0, 20.0, 20.0)


def test_a_box_that_grows_past_twice_its_size_ends():
    pt = ProposalTracks()
    for side in (20, 26, 32, 38):
        out = pt.step([(10, 10, side, side)], [0.8])
    assert len(out) == 1                               # 38 px: still under twice 20 px
    assert pt.step([(10, 10, 44, 44)], [0.8]) == []    # 44 px: the blob merged, it ends
    assert len(pt) == 0


def test_two_signs_keep_apart_and_bad_parameters_are_errors():
    pt = ProposalTracks()
    for _ in range(3):
        out = pt.step([(10, 10, 20, 20), (200, 10, 20, 20)], [0.8, 0.7])
    assert len({o[0] for o in out}) == 2
    with pytest.raises(ValueError, match='min_hits'):
        ProposalTrackConfig(min_hits=4, window=3)


def _frame():
    import numpy as np
    img = np.full((240, 320, 3), 90, np.uint8)
    img[40:80, 200:240] = (0, 120, 250)
    return img


def test_the_tracker_publishes_a_proposal_only_once_repeated():
    from workzone_ros.core.track import MultiTracker
    from workzone_ros.interfaces import Box, Detection
    tracker = MultiTracker()
    prop = Detection(box=Box(200, 40, 40, 40), confidence=0.4, proposal=True)
    first = tracker.step(_frame(), [prop], stamp=0.0)
    assert first == []                       # one frame: never a track
    second = tracker.step(_frame(), [prop], stamp=1 / 30)
    assert len(second) == 1 and second[0].track_id > 0 and second[0].source == 'detection'
    assert second[0].proposal               # the classifier weighs it by the proposals' prior
    third = tracker.step(_frame(), [prop], stamp=2 / 30)
    assert third[0].track_id == second[0].track_id


def test_a_proposal_on_a_tracked_sign_is_not_repeated():
    from workzone_ros.core.track import MultiTracker
    from workzone_ros.interfaces import Box, Detection
    tracker = MultiTracker()
    det = Detection(box=Box(200, 40, 40, 40), confidence=0.9)
    prop = Detection(box=Box(201, 41, 39, 39), confidence=0.4, proposal=True)
    for k in range(4):
        out = tracker.step(_frame(), [det, prop], stamp=k / 30)
    assert len(out) == 1 and not out[0].proposal
