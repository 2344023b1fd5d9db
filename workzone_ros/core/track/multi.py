"""Track life: the multi-target bookkeeping of :class:`MultiTracker`.

A track starts from a detection; detections are associated to tracks by IoU, then by
histogram similarity; every live track is localised by mean-shift (:mod:`.meanshift`) on
every frame; an associated detection corrects or replaces the tracked box; a track runs on
its own only while it looks like a sign (:mod:`.appearance`) that the camera approaches
(:mod:`.motion`), and ends when it is lost, leaves the image, grows too large or duplicates
another.  The package docstring (:mod:`workzone_ros.core.track`) gives the rules in full.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Iterable, Optional, Sequence

import numpy as np

from workzone_ros.core.track.appearance import TargetModel, build_target
from workzone_ros.core.track.boxes import blend as _blend
from workzone_ros.core.track.boxes import box_iou
from workzone_ros.core.track.boxes import ioa as _ioa
from workzone_ros.core.track.config import TrackerConfig, TrackingError
from workzone_ros.core.track.confirmation import Confirmations
from workzone_ros.core.track.meanshift import (
    SearchWindow,
    _luts,
    _stride,
    bhattacharyya,
    camshift_localise,
    meanshift_localise,
    score_box,
)
from workzone_ros.core.track.motion import (
    approach_rate,
    inverse_size_fit,
    predicted_size,
    size_from_fit,
)
from workzone_ros.core.track.proposal_tracks import ProposalTracks
from workzone_ros.interfaces import Box, Detection, Track

__all__ = ['box_iou', 'MultiTracker']


#: Clock of the per-track timing (``last_localise_s``); the bench may use CPU time instead.
_clock = time.perf_counter


def _check_frame(frame) -> None:
    """Raise :class:`TrackingError` unless ``frame`` is an (H, W, 3) uint8 image."""
    if not isinstance(frame, np.ndarray) or frame.ndim != 3 or frame.shape[2] != 3 \
            or frame.dtype != np.uint8:
        raise TrackingError('frame must be an (H, W, 3) uint8 BGR image, got '
                            f'{getattr(frame, "shape", None)} '
                            f'{getattr(frame, "dtype", type(frame).__name__)}')


@dataclass
class _Track:
    track_id: int
    target: TargetModel
    anchor: tuple[float, float, float, float]
    box: tuple[float, float, float, float]
    kind: str
    color: str
    confidence: float
    age: int = 1
    hits: int = 1
    lost: int = 0
    coast: int = 0
    similarity: float = 1.0
    velocity: tuple[float, float] = (0.0, 0.0)
    pred_anchor: Optional[tuple[float, float, float, float]] = None
    pred_box: Optional[tuple[float, float, float, float]] = None
    pred_rho: float = 0.0
    pred_ring: float = 0.0
    growth: float = 0.0              # log anchor-size change per frame (EMA)
    inv_rate: float = 0.0            # fall of 1 / anchor width per frame, from detections
    ref_width: float = 0.0           # anchor width at the last detection-led update
    ref_height: float = 0.0          # anchor height then
    since_ref: int = 0               # frames since then
    trend_known: bool = False        # inv_rate / growth measured between two detections
    fused_share: float = 1.0         # detection's weight in the last update
    ref_ring: float = 0.0            # ring similarity at the last detection
    det_sizes: list = field(default_factory=list)   # (frame, anchor w, anchor h) detected
    was_lost: bool = False           # similarity below min_similarity since the last detection
    motion: list = field(default_factory=list)      # (frame, cx, cy, w, h) of the anchor
    approach: Optional[float] = None  # last approach_rate (None: not judged)
    size_fit: Optional[tuple] = None  # (key, inverse_size_fit of det_sizes), cached


@dataclass
class _DetModel:
    det: Detection
    box: tuple[float, float, float, float]
    target: Optional[TargetModel]


class MultiTracker:
    """Track life around the per-track localiser (see the module docstring).

    Usage::

        tracker = MultiTracker(TrackerConfig())
        for frame, detections in stream:
            tracks = tracker.step(frame, detections)     # list of interfaces.Track
    """

    def __init__(self, config: Optional[TrackerConfig] = None) -> None:
        """Create an empty tracker.

        Args:
            config: parameters (defaults when None).
        """
        self.config = config or TrackerConfig()
        self._luts = _luts(self.config.hue_bins, self.config.sat_bins)
        self._tracks: list[_Track] = []
        self._next_id = 1
        # recall-first colour proposals: followed by overlap, published once repeated
        self._proposals = ProposalTracks(new_id=self._take_id)
        self._verdicts = Confirmations()    # the classifier's (confirm), needs_confirmation
        self.frames = 0
        self._frame: Optional[np.ndarray] = None
        self._stamps: list[float] = []       # the last frames' stamps (s), for the frame rate
        self._fps: Optional[float] = None     # frame rate of those stamps (None: not known)
        #: seconds spent in localisation per track in the last step (for the bench).
        self.last_localise_s: list[float] = []

    def reconfigure(self, config: TrackerConfig) -> None:
        """Use new parameters from the next frame on (keeps the tracks)."""
        self.config = config
        self._luts = _luts(config.hue_bins, config.sat_bins)

    def _take_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    def reset(self) -> None:
        """Drop every track (e.g. when the bag loops or time jumps back)."""
        self._tracks.clear()
        self._proposals.reset()
        self._verdicts.clear()
        self._stamps.clear()
        self._fps = None

    @property
    def active_ids(self) -> list[int]:
        """Ids of the live tracks."""
        return [t.track_id for t in self._tracks]

    def confirm(self, signs: Iterable[int] = (), rejected: Iterable[int] = ()) -> None:
        """The classifier's answers on tracks it classified: ids it found a sign on, ids it
        rejected as background (:func:`~workzone_ros.core.track.confirmation.
        classifier_verdicts`); with ``needs_confirmation`` they decide which tracks run on
        their own (:mod:`~workzone_ros.core.track.confirmation`)."""
        self._verdicts.note(signs, rejected, self.active_ids)

    def _localise(self, frame: np.ndarray, tr: _Track) -> None:
        cfg = self.config
        x, y, w, h = tr.anchor
        ax, ay = w / 2.0, h / 2.0
        zx, zy = x + ax, y + ay
        if cfg.use_velocity:
            zx += tr.velocity[0]
            zy += tr.velocity[1]
        g = self._perspective_scale(tr) if cfg.method == 'meanshift' else 1.0
        alt = not min(cfg.scales) <= g <= max(cfg.scales)
        big = max(g, 1.0) if alt else 1.0          # the window holds both candidate sets
        smax = max(cfg.scales) * big
        mx = ax * (smax + cfg.search_margin) + 2
        my = ay * (smax + cfg.search_margin) + 2
        stride = _stride(ax * big, ay * big, cfg.max_samples)
        win = SearchWindow(frame, zx - mx, zy - my, zx + mx + 1, zy + my + 1, stride,
                           self._luts)
        fn = meanshift_localise if cfg.method == 'meanshift' else camshift_localise
        best = fn(win, tr.target, zx, zy, ax, ay, cfg)
        if alt:
            # Perspective: the candidates around the predicted size compete with those
            # around the previous size (same score: rho minus the surround term).
            other = fn(win, tr.target, zx, zy, ax * g, ay * g, cfg)
            sw = cfg.surround_weight
            if other[4] - sw * (other[5] or 0.0) > best[4] - sw * (best[5] or 0.0):
                best = other
        cx, cy, bx, by, rho, ring = best
        if ring is None and (cfg.association == 'fuse' or cfg.max_ring_similarity < 1.0):
            ring = score_box(win, tr.target, cx, cy, bx, by, cfg)[1]
        tr.pred_anchor = (cx - bx, cy - by, 2 * bx, 2 * by)
        tr.pred_box = tr.target.box_from_anchor(tr.pred_anchor)
        tr.pred_rho = rho
        tr.pred_ring = ring or 0.0

    def step(self, frame: np.ndarray, detections: Sequence[Detection] = (),
             stamp: Optional[float] = None) -> list[Track]:
        """Process one frame and its detections; returns the tracks to publish.

        Detections flagged ``proposal`` (the recall-first colour candidates) never start a
        mean-shift track: they get identities by box overlap
        (:class:`~workzone_ros.core.track.proposal_tracks.ProposalTracks`) and are published
        only once repeated, unless a published track already covers them.  A track running
        on its own is published only under the classifier's rule (:meth:`confirm`).

        Args, returns and errors: as :meth:`_step_rules`.
        """
        rules = [d for d in detections if not getattr(d, 'proposal', False)]
        out = self._verdicts.gate(self._step_rules(frame, rules, stamp),
                                  self.config.needs_confirmation, self.active_ids)
        props = [d for d in detections if getattr(d, 'proposal', False)]
        if not props and not len(self._proposals):
            return out
        have = [(t.box.x, t.box.y, t.box.w, t.box.h) for t in out]
        free = [d for d in props
                if not any(box_iou((d.box.x, d.box.y, d.box.w, d.box.h), h) >= 0.3
                           for h in have)]
        for tid, box, conf, age, hits in self._proposals.step(
                [(d.box.x, d.box.y, d.box.w, d.box.h) for d in free],
                [d.confidence for d in free]):
            out.append(Track(track_id=tid, box=Box(*box), source='detection', age=age,
                             hits=hits, similarity=0.0, confidence=conf, kind='unknown',
                             color='orange', proposal=True))
        return out

    def _step_rules(self, frame: np.ndarray, detections: Sequence[Detection] = (),
                    stamp: Optional[float] = None) -> list[Track]:
        """Process one frame and its detections; returns the tracks to publish.

        Args:
            frame: BGR uint8 image (H, W, 3).
            detections: the detector's output for this very frame (empty when it missed).
            stamp: the frame's time in seconds (the image header), for the frame rate the
                motion cue needs (``TrackerConfig.frame_rate`` when never given).

        Returns:
            One :class:`~workzone_ros.interfaces.Track` per published track, detections first
            in input order, then tracks running on their own.

        Raises:
            TrackingError: ``frame`` is not an (H, W, 3) uint8 image.
        """
        _check_frame(frame)
        self.frames += 1
        self._frame = frame
        if stamp is not None:
            self._note_stamp(stamp)
        H, W = frame.shape[:2]
        tracking = self.config.mode == 'detection_and_tracking'
        self.last_localise_s = []
        # 1. Localise every live track in this frame.
        self._localise_all(frame, tracking)
        # 2. Detection models.
        dets = self._detection_models(frame, detections)
        # 3. Associate: IoU first, then histogram similarity (greedy on the combined score).
        t_match, d_used = self._associate(dets, tracking)
        # Matched tracks take their detection; the others run on their own or end.
        survivors, out_det, out_trk = self._update_tracks(frame, dets, t_match, tracking, W, H)
        # 4. Unmatched detections start tracks.
        self._start_tracks(frame, dets, d_used, tracking, survivors, out_det)
        # 5. Duplicates: two tracks on one sign -> the one with fewer hits ends.
        kept = self._drop_duplicates(survivors, tracking)
        kept_ids = {t.track_id for t in kept}
        self._tracks = sorted(kept, key=lambda t: t.track_id)
        out_det.sort(key=lambda p: p[0])
        return [t for _, t in out_det] + [t for t in out_trk if t.track_id in kept_ids]

    def _note_stamp(self, stamp: float) -> None:
        """Remember a frame's stamp; the frame rate is the median gap of the last 31."""
        self._stamps.append(float(stamp))
        del self._stamps[:-31]
        gaps = np.diff(self._stamps)
        gaps = gaps[gaps > 0]
        self._fps = float(1.0 / np.median(gaps)) if gaps.size else None

    def _localise_all(self, frame: np.ndarray, tracking: bool) -> None:
        """Step 1: localise every live track in ``frame`` (timing each in
        ``last_localise_s``); without tracking the prediction is the last box."""
        if tracking:
            for tr in self._tracks:
                t0 = _clock()
                self._localise(frame, tr)
                self.last_localise_s.append(_clock() - t0)
        else:
            for tr in self._tracks:
                tr.pred_anchor, tr.pred_box, tr.pred_rho = tr.anchor, tr.box, 0.0

    def _detection_models(self, frame: np.ndarray,
                          detections: Sequence[Detection]) -> list[_DetModel]:
        """Step 2: the target model of every detection at least ``min_box_px`` on a side."""
        cfg = self.config
        dets: list[_DetModel] = []
        for d in detections:
            b = d.box
            if b.w < cfg.min_box_px or b.h < cfg.min_box_px:
                continue
            box = (float(b.x), float(b.y), float(b.w), float(b.h))
            dets.append(_DetModel(d, box, build_target(frame, box, cfg, self._luts)))
        return dets

    def _associate(self, dets: list[_DetModel], tracking: bool
                   ) -> tuple[dict[int, tuple[int, float]], set[int]]:
        """Step 3: pair tracks and detections, IoU first, then histogram similarity (greedy
        on the combined score).  Returns ``(t_match, d_used)``: track index -> (detection
        index, similarity), and the detections taken (including those a confident track
        disagrees with: they belong to it, but the tracker keeps its own box)."""
        cfg = self.config
        pairs = []
        for ti, tr in enumerate(self._tracks):
            ref = tr.pred_box if tr.pred_box is not None else tr.box
            ref_anchor = tr.pred_anchor if tr.pred_anchor is not None else tr.anchor
            for di, dm in enumerate(dets):
                # The anchor term lets a detection of only the orange top of a two-colour box
                # agree with the track of the whole box.
                iou = max(box_iou(ref, dm.box), box_iou(tr.box, dm.box),
                          box_iou(ref_anchor, dm.box))
                if iou <= 0.0:
                    continue
                sim = bhattacharyya(tr.target.q, dm.target.q) if dm.target is not None else 0.0
                if iou >= cfg.iou_gate or sim >= cfg.similarity_gate:
                    pairs.append((iou + sim, iou, sim, ti, di))
        pairs.sort(reverse=True)
        t_match: dict[int, tuple[int, float]] = {}
        d_used: set[int] = set()
        for _, iou, sim, ti, di in pairs:
            if ti in t_match or di in d_used:
                continue
            d_used.add(di)
            tr = self._tracks[ti]
            if tracking and iou < cfg.agree_iou and tr.pred_rho >= cfg.min_similarity \
                    and tr.pred_box is not None:
                continue          # belongs to the track but disagrees: the tracker keeps it
            t_match[ti] = (di, sim)
        return t_match, d_used

    def _update_tracks(self, frame: np.ndarray, dets: list[_DetModel],
                       t_match: dict[int, tuple[int, float]], tracking: bool, W: int, H: int
                       ) -> tuple[list[_Track], list[tuple[int, Track]], list[Track]]:
        """Every live track one frame on: a matched one takes its detection, the others run
        on their own or end.  Returns ``(survivors, out_det, out_trk)``: the tracks that
        live on, the detection-led outputs (keyed by detection index) and the tracks
        published while running on their own."""
        out_det: list[tuple[int, Track]] = []
        out_trk: list[Track] = []
        survivors: list[_Track] = []
        for ti, tr in enumerate(self._tracks):
            tr.age += 1
            tr.since_ref += 1
            if ti in t_match:
                di, sim = t_match[ti]
                self._take_detection(frame, ti, tr, dets[di], sim, tracking)
                survivors.append(tr)
                out_det.append((di, self._payload(tr, 'detection')))
                continue
            lives, published = self._unmatched(tr, tracking, W, H)
            if lives:
                survivors.append(tr)
            if published:
                out_trk.append(self._payload(tr, 'tracking'))
        return survivors, out_det, out_trk

    def _take_detection(self, frame: np.ndarray, ti: int, tr: _Track, dm: _DetModel,
                        sim: float, tracking: bool) -> None:
        """A matched track: fused with its detection when it is confident enough to outvote
        it (``association='fuse'``), else corrected to it."""
        cfg = self.config
        if tracking and cfg.association == 'fuse' and dm.target is not None \
                and self._confident(tr) \
                and min(tr.pred_box[2], tr.pred_box[3]) >= cfg.fuse_min_px:
            t0 = _clock()
            self._fuse(frame, tr, dm, sim)
            self.last_localise_s[ti] += _clock() - t0
        else:
            self._correct(tr, dm, sim)

    def _unmatched(self, tr: _Track, tracking: bool, W: int, H: int) -> tuple[bool, bool]:
        """A track no detection matched this frame: ``(lives, published)``, whether it lives
        on and whether it is published as running on its own."""
        cfg = self.config
        if not tracking:
            tr.lost += 1
            return tr.lost <= cfg.max_lost_frames, False
        # The detector missed: the track runs on its own.
        tr.coast += 1
        if tr.coast > cfg.max_coast_frames:
            return False, False
        if tr.pred_rho < cfg.min_similarity:
            # Lost (occluded?): not published; the box coasts on the velocity and the
            # next frame searches there again, until max_lost_frames.
            tr.lost += 1
            tr.was_lost = True
            if tr.lost <= cfg.max_lost_frames:
                vx, vy = tr.velocity
                a, b = tr.anchor, tr.box
                tr.anchor = (a[0] + vx, a[1] + vy, a[2], a[3])
                tr.box = (b[0] + vx, b[1] + vy, b[2], b[3])
                return True, False
            return False, False
        if tr.pred_ring > cfg.max_ring_similarity and (
                cfg.ring_margin < 0 or tr.hits < cfg.ring_margin_min_hits
                or tr.pred_ring > tr.ref_ring + cfg.ring_margin):
            # Drift guard: the target's colour continues all around the box (the box sits
            # in a much larger region of sign colour, e.g. an orange vehicle): not a sign
            # anymore; coast blind like an occlusion and end unless a detection returns.
            tr.lost += 1
            return tr.lost <= cfg.max_lost_frames, False
        pb = tr.pred_box
        if not self._inside(pb, W, H) or pb[2] > cfg.max_box_fraction * W \
                or pb[3] > cfg.max_box_fraction * H or self._overgrown(tr):
            return False, False
        self._advance(tr, tr.pred_anchor, pb)
        tr.similarity = tr.pred_rho
        tr.lost = 0
        published = tr.hits >= cfg.min_hits_to_coast and self._may_coast(tr.target) \
            and (not tr.was_lost or tr.hits >= cfg.min_hits_after_loss) \
            and self._approaching(tr, W, H)
        return True, published

    def _start_tracks(self, frame: np.ndarray, dets: list[_DetModel], d_used: set[int],
                      tracking: bool, survivors: list[_Track],
                      out_det: list[tuple[int, Track]]) -> None:
        """Step 4: every detection no track took starts a track (one without a target model
        is published as is); adds them to ``survivors`` and ``out_det``."""
        cfg = self.config
        for di, dm in enumerate(dets):
            if di in d_used or dm.target is None:
                if di not in d_used:
                    out_det.append((di, self._det_only(dm)))
                continue
            tr = _Track(self._next_id, dm.target, dm.target.anchor, dm.box, dm.det.kind,
                        dm.det.color, dm.det.confidence,
                        ref_width=max(dm.target.anchor[2], 1.0),
                        ref_height=max(dm.target.anchor[3], 1.0))
            self._record_size(tr, dm.target.anchor)
            self._record_motion(tr)
            if tracking and cfg.ring_margin >= 0:
                tr.ref_ring = self._ring_at(frame, dm.target, dm.target.anchor)
            self._next_id += 1
            survivors.append(tr)
            out_det.append((di, self._payload(tr, 'detection')))

    def _drop_duplicates(self, survivors: list[_Track], tracking: bool) -> list[_Track]:
        """Step 5: two tracks on one sign -> the one with fewer hits ends.  Besides
        overlapping boxes (IoU), a track whose coloured anchor lies inside another's box
        (the orange top of a two-colour sign next to the whole sign) is a duplicate
        (``duplicate_containment``, not in the seed).  Sorts ``survivors`` (most hits
        first); returns the tracks kept in that order."""
        contain = tracking and self.config.duplicate_containment < 1.0
        survivors.sort(key=lambda t: (-t.hits, t.track_id))
        kept: list[_Track] = []
        for tr in survivors:
            if any(self._duplicate(tr, k, contain) for k in kept):
                continue
            kept.append(tr)
        return kept

    def _duplicate(self, a: _Track, b: _Track, contain: bool) -> bool:
        """Tracks ``a`` and ``b`` follow one sign: their boxes overlap by more than
        ``duplicate_iou`` or (``contain``) the smaller box's coloured anchor lies at least
        ``duplicate_containment`` inside the larger box, which is at most
        ``duplicate_area_ratio`` times larger (a big box merging a sign with its
        surroundings does not swallow the sign's own track)."""
        cfg = self.config
        if box_iou(a.box, b.box) > cfg.duplicate_iou:
            return True
        if not contain:
            return False
        area_a = a.box[2] * a.box[3]
        area_b = b.box[2] * b.box[3]
        small, big = (a, b) if area_a <= area_b else (b, a)
        if max(area_a, area_b) > cfg.duplicate_area_ratio * max(min(area_a, area_b), 1e-9):
            return False
        return _ioa(big.box, small.anchor) >= cfg.duplicate_containment

    def _inside(self, box: Sequence[float], W: int, H: int) -> bool:
        """At least ``min_inside_fraction`` of ``box`` is inside the image."""
        x, y, w, h = box
        if w <= 0 or h <= 0:
            return False
        iw = max(0.0, min(x + w, W) - max(x, 0.0))
        ih = max(0.0, min(y + h, H) - max(y, 0.0))
        return iw * ih >= self.config.min_inside_fraction * w * h

    def _advance(self, tr: _Track, anchor, box) -> None:
        ox = tr.anchor[0] + tr.anchor[2] / 2
        oy = tr.anchor[1] + tr.anchor[3] / 2
        nx = anchor[0] + anchor[2] / 2
        ny = anchor[1] + anchor[3] / 2
        vx, vy = tr.velocity
        tr.velocity = (0.5 * vx + 0.5 * (nx - ox), 0.5 * vy + 0.5 * (ny - oy))
        tr.anchor, tr.box = anchor, box
        self._record_motion(tr)

    @property
    def frame_rate(self) -> float:
        """Frames per second: the median gap of the last stamps given to :meth:`step`
        (``TrackerConfig.frame_rate`` before two increasing stamps); updated once per
        step."""
        return self.config.frame_rate if self._fps is None else self._fps

    def approach_threshold(self, width: int) -> float:
        """The motion cue's minimum fall of ``1 / size`` per frame (1/px) for frames
        ``width`` pixels wide: ``min_approach_speed / (f sign_size_m fps)``."""
        cfg = self.config
        f = 0.5 * width / math.tan(math.radians(cfg.camera_hfov_deg) / 2.0)
        return cfg.min_approach_speed / (f * cfg.sign_size_m * self.frame_rate)

    def _record_motion(self, tr: _Track) -> None:
        """Remember the anchor of this frame for :func:`approach_rate`."""
        cfg = self.config
        if cfg.min_approach_speed <= 0:
            return
        a = tr.anchor
        tr.motion.append((float(self.frames), a[0] + a[2] / 2, a[1] + a[3] / 2, a[2], a[3]))
        while tr.motion and tr.motion[0][0] < self.frames - cfg.motion_window:
            del tr.motion[0]

    def _approaching(self, tr: _Track, W: int, H: int) -> bool:
        """Motion cue: the track does not behave like a vehicle driving ahead (see
        ``TrackerConfig.min_approach_speed``)."""
        cfg = self.config
        if cfg.min_approach_speed <= 0:
            return True
        minimum = self.approach_threshold(W)
        fx, fy = cfg.focus_of_expansion
        tr.approach = approach_rate(tr.motion, (fx * W, fy * H), cfg.motion_window,
                                    cfg.motion_min_frames, cfg.radial_min_offset)
        if cfg.approach_from_detections and tr.approach is not None \
                and tr.approach < minimum:
            # The detected sizes measure the same rate, free of the tracker's own scale lag
            # (a box that started too wide grows too slowly).
            det = approach_rate([(f, 0.0, 0.0, w, h) for f, w, h in tr.det_sizes], None,
                                max(cfg.motion_window, self.frames), cfg.motion_min_frames)
            if det is not None:
                tr.approach = max(tr.approach, det)
        return tr.approach is None or tr.approach >= minimum

    def _may_coast(self, target: TargetModel) -> bool:
        """The track may be published while it runs on its own: a coloured target that does
        not look like its surroundings, nor have white bands in the shape (drums, cones)."""
        cfg = self.config
        bg = target.background_similarity
        if not target.colored or bg > min(cfg.max_background_similarity,
                                          cfg.max_coast_background_similarity):
            return False
        if target.saturation_contrast < cfg.min_saturation_contrast \
                or target.chroma_contrast < cfg.min_chroma_contrast:
            return False
        if target.white_below >= cfg.white_bottom_share:
            return True       # white bottom under an orange top: a regulatory sign's face
        return not (cfg.anchor_on_color and target.white_fraction > cfg.max_coast_white_fraction)

    def _confident(self, tr: _Track) -> bool:
        """The track may outvote a detection: detected often enough, tracked well."""
        cfg = self.config
        return tr.pred_box is not None and tr.hits >= cfg.min_hits_to_fuse \
            and tr.target.colored and tr.pred_rho >= cfg.min_similarity \
            and tr.target.background_similarity <= cfg.max_background_similarity

    def _lost_white_part(self, tr: _Track, new: TargetModel,
                         box: Sequence[float]) -> bool:
        """Two-colour guard: the track knows a box reaching well beyond its coloured anchor
        (the white part of a regulatory sign) and this detection (``new``, box ``box``)
        covers much less of it."""
        cfg = self.config
        if not cfg.anchor_on_color:
            return False
        rel = tr.target.relation
        top = -rel[1]                            # box above the anchor, in anchor heights
        bottom = rel[1] + rel[3] - 1.0           # box below the anchor: the white part
        two_colour = bottom >= 0.4 and bottom >= 3.0 * max(top, 0.02)
        if not two_colour:
            return False
        # Only a detection that is not already extended (its box does not reach well below
        # the coloured part) is truncated: the colour detector now extends regulatory boxes
        # itself, and replacing its extension by the track's older one lost accuracy.
        new_bottom = new.relation[1] + new.relation[3] - 1.0
        if new_bottom >= 0.5 * bottom:
            return False
        # ... and only when the detection's coloured anchor is the same part of the sign as
        # the one the relation was measured on: an anchor much taller for its width than the
        # track's (the whole face took the dominant hue, the track knows the orange band)
        # already holds the white part, and the band's relation would triple its box.
        if cfg.anchor_kind_ratio > 0:
            ta, na = tr.anchor, new.anchor
            aspect_t = ta[3] / max(ta[2], 1e-6)
            aspect_n = na[3] / max(na[2], 1e-6)
            if aspect_n > cfg.anchor_kind_ratio * aspect_t:
                return False
        # ... and only when the box itself is short for the sign: its height over width
        # well below that of the track's box.  The coloured anchor is not a stable measure
        # of the orange part (in dim light the hull of the dominant hue often covers the
        # whole face), so a complete detection whose anchor is the whole face also has no
        # box below its anchor; extending it by the relation of an orange-band anchor
        # tripled its height (tuning paper_c 1111).
        if cfg.truncated_aspect > 0:
            tb = tr.box
            aspect_t = tb[3] / max(tb[2], 1e-6)
            aspect_d = box[3] / max(box[2], 1e-6)
            if aspect_d >= cfg.truncated_aspect * aspect_t:
                return False
        return True

    def _overgrown(self, tr: _Track) -> bool:
        """Drift guard: the tracked anchor grew past what perspective and the track's own
        detections allow.  A static sign's inverse image size falls linearly with time
        (size = f S / d, d falling at the ego speed); ``inv_rate`` is that slope measured
        between detections.  A track without a measured trend (one detection) whose anchor
        reached ``max_size_ratio`` times its detected size (either side) has drifted."""
        if tr.ref_width <= 0 or tr.pred_anchor is None:
            return False
        if not tr.trend_known:
            ratio = self.config.max_size_ratio
            if ratio > 0 and (tr.pred_anchor[2] >= ratio * tr.ref_width
                              or tr.pred_anchor[3] >= ratio * tr.ref_height):
                return True
            if self.config.growth_guard_needs_trend:
                return False
        excess = self.config.max_growth_excess
        if excess <= 0:
            return False
        inv = 1.0 / tr.ref_width - tr.since_ref * tr.inv_rate
        expected = 1.0 / max(inv, 1e-3)
        return tr.pred_anchor[2] > (1.0 + excess) * expected + 2.0

    def _perspective_scale(self, tr: _Track) -> float:
        """Second candidate size for this frame, relative to the track's anchor: the
        anchor size a static sign has now by the Theil-Sen trend of the track's detected
        sizes (``perspective_scale``) over the anchor's size; 1 without a usable trend (too
        few detections, or further past the last one than they span) or with the rule off.
        """
        cfg = self.config
        if not cfg.perspective_scale \
                or tr.target.background_similarity > cfg.perspective_max_background:
            return 1.0
        sizes = tr.det_sizes
        if len(sizes) < cfg.perspective_min_detections \
                or self.frames - sizes[-1][0] > sizes[-1][0] - sizes[0][0]:
            return 1.0
        key = (len(sizes), sizes[-1][0])
        if tr.size_fit is None or tr.size_fit[0] != key:
            tr.size_fit = (key, inverse_size_fit(sizes))       # refit only after a detection
        fit = tr.size_fit[1]
        if fit is None or len({d[0] for d in sizes}) < cfg.perspective_min_detections:
            return 1.0
        pred = size_from_fit(fit, self.frames)
        if pred is None:
            return 1.0
        g = math.sqrt(pred[0] * pred[1] / max(tr.anchor[2] * tr.anchor[3], 1.0))
        return min(max(g, cfg.perspective_min), cfg.perspective_max)

    def _measure_growth(self, tr: _Track) -> None:
        """After a detection-led update: the per-frame growth and inverse-size slope."""
        aw = max(tr.anchor[2], 1.0)
        if tr.ref_width > 0 and tr.since_ref > 0:
            n = tr.since_ref
            g = min(max(math.log(aw / tr.ref_width) / n, -0.05), 0.2)
            inv = max((1.0 / tr.ref_width - 1.0 / aw) / n, 0.0)
            tr.growth = 0.6 * tr.growth + 0.4 * g
            if tr.trend_known or not self.config.growth_guard_needs_trend:
                tr.inv_rate = 0.6 * tr.inv_rate + 0.4 * inv
            else:
                tr.inv_rate = inv             # the first measured trend, not averaged with 0
            tr.trend_known = True
        tr.ref_width, tr.ref_height = aw, max(tr.anchor[3], 1.0)
        tr.since_ref = 0

    def _fuse(self, frame: np.ndarray, tr: _Track, dm: _DetModel, sim: float) -> None:
        """Association rule ``fuse``: weigh the tracked and the detected box (see
        :class:`TrackerConfig`) and update the track with the result."""
        cfg = self.config
        new = dm.target
        ad = new.anchor
        ax, ay = max(ad[2], 1.0) / 2, max(ad[3], 1.0) / 2
        cx, cy = ad[0] + ax, ad[1] + ay
        m = cfg.surround_size
        win = SearchWindow(frame, cx - m * ax - 2, cy - m * ay - 2, cx + m * ax + 3,
                           cy + m * ay + 3, _stride(ax, ay, cfg.max_samples), self._luts)
        rho_d, ring_d = score_box(win, tr.target, cx, cy, ax, ay, cfg)
        tr.ref_ring = ring_d
        s_d = rho_d - cfg.surround_weight * ring_d + cfg.fuse_bias
        s_t = tr.pred_rho - cfg.surround_weight * tr.pred_ring
        g = math.exp(tr.growth)
        refs = [(max(tr.anchor[2], 1.0) * g, max(tr.anchor[3], 1.0) * g)]
        pred = predicted_size(tr.det_sizes, self.frames) if cfg.size_history > 0 else None
        if pred is not None:
            refs.append(pred)
        self._record_size(tr, ad)

        def size_factor(a) -> float:
            d2 = min(math.log(max(a[2], 1.0) / pw) ** 2 + math.log(max(a[3], 1.0) / ph) ** 2
                     for pw, ph in refs)
            return math.exp(-0.5 * d2 / cfg.size_sigma ** 2)

        top = max(s_d, s_t)
        w_d = math.exp((s_d - top) / cfg.fuse_temperature) * size_factor(ad)
        w_t = math.exp((s_t - top) / cfg.fuse_temperature) * size_factor(tr.pred_anchor)
        share = w_d / (w_d + w_t) if w_d + w_t > 0 else 1.0
        box_d = dm.box
        truncated = self._lost_white_part(tr, new, box_d)
        if truncated:
            box_d = tr.target.box_from_anchor(ad)        # two-colour guard (see _correct)
        at, bt = tr.pred_anchor, tr.pred_box
        overlap = box_iou(at, ad) >= cfg.fuse_iou
        if not overlap:
            share = 1.0 if share >= 0.5 else 0.0         # disjoint: one of them, not between
        anchor = _blend(at, ad, share)
        box = _blend(bt, box_d, share)
        if overlap and cfg.prefer_detection and not truncated and share >= 0.5:
            box = box_d                                  # agreeing and complete: its box
        base = new if share >= 0.5 else tr.target
        a = cfg.model_update * share
        q = (1 - a) * tr.target.q + a * new.q
        qw = (1 - a) * tr.target.qw + a * new.qw
        aw, ah = max(anchor[2], 1.0), max(anchor[3], 1.0)
        rel = ((box[0] - anchor[0]) / aw, (box[1] - anchor[1]) / ah, box[2] / aw, box[3] / ah)
        tr.target = replace(base, q=q / q.sum(), qw=qw / qw.sum(), relation=rel,
                            anchor=anchor)
        self._advance(tr, anchor, box)
        if share >= 0.5:
            self._measure_growth(tr)
        tr.fused_share = share
        tr.hits += 1
        tr.lost = 0
        tr.was_lost = False
        tr.coast = 0
        tr.similarity = min(1.0, max(0.0, sim))
        tr.kind, tr.color, tr.confidence = dm.det.kind, dm.det.color, dm.det.confidence

    def _ring_at(self, frame: np.ndarray, target: TargetModel,
                 anchor: Sequence[float]) -> float:
        """Ring similarity (:func:`score_box`) of ``target`` around ``anchor``."""
        cfg = self.config
        ax, ay = max(anchor[2], 1.0) / 2, max(anchor[3], 1.0) / 2
        cx, cy = anchor[0] + ax, anchor[1] + ay
        m = cfg.surround_size
        win = SearchWindow(frame, cx - m * ax - 2, cy - m * ay - 2, cx + m * ax + 3,
                           cy + m * ay + 3, _stride(ax, ay, cfg.max_samples), self._luts)
        return score_box(win, target, cx, cy, ax, ay, cfg)[1]

    def _record_size(self, tr: _Track, anchor: Sequence[float]) -> None:
        """Remember a detected anchor size for :func:`predicted_size`."""
        n = self.config.size_history
        if n > 0:
            tr.det_sizes.append((float(self.frames), float(anchor[2]), float(anchor[3])))
            del tr.det_sizes[:-n]

    def _correct(self, tr: _Track, dm: _DetModel, sim: float) -> None:
        cfg = self.config
        tracking = cfg.mode == 'detection_and_tracking'
        new = dm.target
        if new is not None:
            self._record_size(tr, new.anchor)
            a = cfg.model_update
            q = (1 - a) * tr.target.q + a * new.q
            qw = (1 - a) * tr.target.qw + a * new.qw
            box = dm.box
            rel = tr.target.relation
            if tracking and self._lost_white_part(tr, new, box):
                # Two-colour guard: this detection covers only the coloured part of a box
                # whose full extent the track knows (the detector missed the white bottom):
                # keep the measured geometry instead of shrinking the box to the orange top.
                new = replace(new, relation=rel)
                box = new.box_from_anchor(new.anchor)
            tr.target = replace(new, q=q / q.sum(), qw=qw / qw.sum())
            self._advance(tr, new.anchor, box)
            if tracking and cfg.ring_margin >= 0:
                tr.ref_ring = self._ring_at(self._frame, tr.target, new.anchor)
            self._measure_growth(tr)
        else:
            tr.box = dm.box           # no model from this box (mostly outside): keep the old
        tr.hits += 1
        tr.lost = 0
        tr.was_lost = False
        tr.coast = 0
        tr.similarity = min(1.0, max(0.0, sim))
        tr.kind, tr.color, tr.confidence = dm.det.kind, dm.det.color, dm.det.confidence

    def _payload(self, tr: _Track, source: str) -> Track:
        x, y, w, h = tr.box
        return Track(track_id=tr.track_id, box=Box(x=float(x), y=float(y), w=float(max(w, 0)),
                                                   h=float(max(h, 0))),
                     source=source, age=tr.age, hits=tr.hits,
                     similarity=float(min(1.0, max(0.0, tr.similarity))),
                     confidence=float(min(1.0, max(0.0, tr.confidence))), kind=tr.kind,
                     color=tr.color)

    def _det_only(self, dm: _DetModel) -> Track:
        """A detection that cannot start a track (outside the image): published, id 0."""
        return Track(track_id=0, box=dm.det.box, source='detection', age=1, hits=1,
                     similarity=0.0, confidence=dm.det.confidence, kind=dm.det.kind,
                     color=dm.det.color)
