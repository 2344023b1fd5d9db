"""The recall-first colour proposals: what a user relies on (core.proposals)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from workzone_ros.core import color_model as cm
from workzone_ros.core.proposals import (
    FEATURES,
    Proposal,
    ProposalConfig,
    Ranker,
    SignProposer,
    candidate_labels,
    detect_frame,
    fit_ranker,
    proposals_as_detections,
    stage_plan,
)
from workzone_ros.interfaces import Box, Detection
from workzone_ros.resources import config_path

ORANGE = (0, 120, 250)      # BGR of fresh orange sheeting


@pytest.fixture(scope='module')
def proposer() -> SignProposer:
    return SignProposer(cm.load_model(config_path('models/color_proposals.npz')))


def _road(h: int = 406, w: int = 722) -> np.ndarray:
    rng = np.random.default_rng(0)
    img = np.empty((h, w, 3), np.uint8)
    img[: h // 2] = (200, 170, 140)                      # sky
    img[h // 2:] = (90, 92, 95)                          # asphalt
    return cv2.add(img, rng.integers(0, 12, img.shape, dtype=np.uint8))


def _diamond(img: np.ndarray, cx: int, cy: int, r: int, legend: bool = True) -> tuple:
    pts = np.array([[cx, cy - r], [cx + r, cy], [cx, cy + r], [cx - r, cy]], np.int32)
    cv2.fillConvexPoly(img, pts, ORANGE)
    cv2.polylines(img, [pts], True, (20, 20, 20), max(1, r // 15))
    if legend:
        cv2.putText(img, 'ROAD', (cx - r // 2, cy + r // 8), cv2.FONT_HERSHEY_SIMPLEX,
                    r / 70.0, (15, 15, 15), max(1, r // 20))
    return (cx - r, cy - r, 2 * r, 2 * r)


def _best_iou(props: list[Proposal], box) -> float:
    return max((Box(*p.box).iou(Box(*box)) for p in props), default=0.0)


def test_a_sign_on_the_roadside_is_proposed(proposer):
    img = _road()
    box = _diamond(img, 520, 150, 30)
    assert _best_iou(proposer.propose(img), box) >= 0.5


def test_a_sign_cut_by_the_frame_edge_is_still_a_candidate(proposer):
    img = _road()
    cx = img.shape[1] - 10                 # two thirds of the diamond outside the frame
    box = _diamond(img, cx, 150, 30)
    visible = (box[0], box[1], img.shape[1] - box[0], box[3])
    assert _best_iou(proposer.propose(img), visible) >= 0.4


def test_a_sign_in_front_of_its_own_colour_is_separated(proposer):
    img = _road()
    cv2.rectangle(img, (470, 182), (570, 260), ORANGE, -1)     # an orange barrier below
    box = _diamond(img, 520, 150, 32)                          # touching it
    props = proposer.propose(img)
    assert _best_iou(props, box) >= 0.5


def test_a_saturated_sign_before_duller_foliage_as_bright_is_separated():
    img = _road()
    foliage = cv2.cvtColor(np.uint8([[[12, 140, 190]]]), cv2.COLOR_HSV2BGR)[0, 0]
    noise = np.random.default_rng(1).normal(0, 8, (120, 200, 3))
    img[100:220, 450:650] = np.clip(foliage + noise, 0, 255).astype(np.uint8)   # autumn tree
    img[160:182, 560:600] = (0, 110, 255)      # a small sign, as bright, far more saturated
    box = (560, 160, 40, 22)
    model = cm.load_model(config_path('models/color_proposals.npz'))
    found = SignProposer(model).propose(img)
    brightness_only = SignProposer(model, ProposalConfig(saturation_edges=False)).propose(img)
    assert _best_iou(found, box) >= 0.5 > _best_iou(brightness_only, box)


def test_the_work_per_frame_is_bounded():
    model = cm.load_model(config_path('models/color_proposals.npz'))
    prop = SignProposer(model, ProposalConfig(max_candidates=5))
    img = _road()
    for i in range(12):
        for j in range(6):
            cv2.rectangle(img, (20 + 58 * i, 20 + 60 * j), (50 + 58 * i, 50 + 60 * j), ORANGE, -1)
    props = prop.propose(img)
    assert len(props) == 5
    assert [p.score for p in props] == sorted((p.score for p in props), reverse=True)


@pytest.mark.parametrize('value', [0, 255])
def test_black_or_overexposed_frames_give_nothing(proposer, value):
    assert proposer.propose(np.full((406, 722, 3), value, np.uint8)) == []


def test_bad_input_and_parameters_are_one_line_errors(proposer):
    with pytest.raises(ValueError, match='BGR image'):
        proposer.propose(np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match='threshold'):
        ProposalConfig(threshold=0.0)
    with pytest.raises(ValueError, match='max_candidates'):
        ProposalConfig(max_candidates=0)
    with pytest.raises(ValueError, match='unknown proposal parameter'):
        ProposalConfig.from_mapping({'treshold': 0.5})


def test_the_ranker_round_trips_and_refuses_a_wrong_size():
    f = len(FEATURES)
    r = Ranker(np.zeros(f), np.ones(f), np.arange(f, dtype=float), -1.0)
    back = Ranker.from_array(r.to_array())
    x = np.random.default_rng(1).normal(size=(4, f))
    assert np.allclose(back.score(x), r.score(x))
    with pytest.raises(ValueError, match='proposal_ranker'):
        Ranker.from_array(np.zeros(5))


def test_the_ranker_learns_which_candidates_are_signs():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(400, len(FEATURES)))
    y = (x[:, 0] + 0.3 * rng.normal(size=400) > 0.5).astype(int)
    r = fit_ranker(x, y)
    assert r.score(x[y == 1]).mean() > r.score(x[y == 0]).mean() + 0.3
    with pytest.raises(ValueError, match='both'):
        fit_ranker(x, np.zeros(400, int))


def test_candidates_are_labelled_by_overlap_with_true_signs():
    lab = candidate_labels([(0, 0, 10, 10), (50, 50, 10, 10)], [(1, 1, 10, 10)])
    assert lab.tolist() == [1, 0]


def test_proposals_already_detected_are_not_repeated():
    det = Detection(box=Box(100, 100, 40, 40), confidence=0.9)
    props = [Proposal((102, 101, 40, 38), 0.8), Proposal((300, 50, 30, 30), 0.6)]
    out = proposals_as_detections(props, [det])
    assert len(out) == 1 and out[0].proposal and out[0].box.x == 300
    assert out[0].confidence == pytest.approx(0.6)


@pytest.mark.parametrize('proposals,rules,own,expected', [
    ('auto', 'on', True, (True, False)),      # the model's camera: the rules alone
    ('auto', 'on', False, (True, True)),      # any other camera: the proposals beside them
    ('auto', 'auto', False, (False, True)),   # ... or instead of them
    ('auto', 'auto', True, (True, False)),
    ('on', 'auto', True, (True, True)),
    ('on', 'auto', False, (False, True)),
    ('off', 'auto', False, (True, False)),    # nothing proposes: the rules run
    ('off', 'off', False, (False, False)),
])
def test_which_stages_see_a_frame(proposals, rules, own, expected):
    assert stage_plan(proposals, rules, own) == expected


def test_an_unknown_stage_mode_is_a_one_line_error():
    with pytest.raises(ValueError, match="proposals must be one of auto, on, off, got 'yes'"):
        stage_plan('yes', 'on', True)


class _Rules:
    """A stand-in rule detector: one detection; remembers how it was asked to measure."""

    frame_view = None

    def __init__(self, own: bool) -> None:
        self.own, self.calls = own, []

    def same_camera(self, width, height):
        return self.own

    def detect(self, bgr, rois, lean):
        self.calls.append(lean)
        return [Detection(box=Box(10, 10, 20, 20), confidence=0.9)]


class _Proposer:
    def view_of(self, detector):
        return 'view'

    def propose(self, bgr, view):
        self.view = view
        return [Proposal((10, 10, 20, 20), 0.8), Proposal((60, 10, 20, 20), 0.7)]


@pytest.mark.parametrize('own,lean_beside,expected', [
    (False, True, ([True], 2, True)),       # another camera: lean rules, proposals beside
    (False, False, ([False], 2, True)),
    (True, True, ([False], 1, False)),      # the model's camera: the rules alone, in full
])
def test_a_frame_goes_through_the_stages_the_node_runs(own, lean_beside, expected):
    rules, prop = _Rules(own), _Proposer()
    dets, ran_rules, ran_props = detect_frame(rules, prop, np.zeros((4, 4, 3), np.uint8),
                                              lean_beside=lean_beside)
    assert (rules.calls, len(dets), ran_props) == expected and ran_rules
    if ran_props:            # the proposal repeating the rule box is left out; view reused
        assert [d.proposal for d in dets] == [False, True] and prop.view == 'view'


def test_without_a_proposer_no_frame_is_proposed():
    dets, _, ran_props = detect_frame(_Rules(False), None, np.zeros((4, 4, 3), np.uint8))
    assert len(dets) == 1 and not ran_props
