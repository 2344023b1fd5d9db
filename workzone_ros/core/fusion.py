"""Work-zone state from classified signs: Seo et al. III.C made causal, plus a state machine.

One camera frame's :class:`~workzone_ros.interfaces.Signs` at a time (and metres travelled
from odometry when there is odometry), :class:`WorkzoneFusion` answers the planner's
question on ``/workzone/state``: is the vehicle approaching, inside or leaving a work zone,
and how does the zone change the road (speed limit, lane shift, closed lanes).  No rclpy
import; the ``fusion`` node and ``workzone-ros evaluate workzone`` run this same code.

Algorithm (docs/fusion.md has the parameters, the rules and measured numbers):

1. **Discounted temporal voting** (Seo et al., eq. 4), per tracked sign (``Sign.track_id``):
   ``y_t = argmax_c [h_t(c) + sum_{l=1..T} gamma^l h_{t-l}(c)]`` over the track's last
   ``T + 1`` classifications, ``h`` = the sign's ``probabilities`` (a one-hot of
   ``class_key`` x ``score`` when empty).  The vote's *confidence* is the discounted mean
   ``V(y_t) / sum_l gamma^l`` in [0, 1].  A sign without a track id votes alone; such signs
   are pooled per voted class into one pseudo-track while they keep coming (hits count).
   Category ``unknown`` (unclassifiable crop) is no observation; ``background`` and general
   signs take part in a track's vote but are never work-zone evidence.
2. **Confirmation** (hysteresis): a track becomes evidence when it has ``min_hits``
   observations and its vote is a work-zone class with confidence >= ``min_confidence``.
   A single stray frame never is.
3. **Where the sign stands**: each observation places the sign at ``s + distance_m`` along
   the travelled path ``s`` (odometry metres, else ``time x assumed_speed_mps``); the
   track's last ``T + 1`` estimates are averaged with weights ``1 / distance^2`` (near
   looks are the accurate ones; older ones drift with ``s``).  The vehicle *reaches*
   (passes) the sign when ``s`` gets there.
4. **Gaussian propagation** (eq. 3), causal: every confirmed sign's confidence is carried
   forward over the distance travelled since it was last seen,
   ``c * exp(-(s - s_seen)^2 / (2 sigma^2))`` (the seed smoothed both ways offline; a
   vehicle can only use the past).  ``likelihood = 1 - prod_k (1 - c_k g_k)`` (a noisy-or,
   so it stays in [0, 1] however many signs) together with the channelizer term.  Over
   distance, a car that slows down in a zone keeps its likelihood; without odometry over
   time at ``assumed_speed_mps`` (the seed's 50 mph).
5. **State machine** ``unknown -> none -> approaching -> inside -> leaving -> none``:

   * ``unknown`` until ``warmup_s`` of input has passed with no work-zone evidence (or
     after a reset: a stamp that jumps back);
   * ``approaching`` on any confirmed work-zone sign other than END ROAD WORK (W20-1,
     lane closed / lane ends, the work-zone speed limit, lane shifts, other orange signs,
     and a WORK ZONE BEGINS not reached yet);
   * ``inside`` when the vehicle *reaches* a WORK ZONE BEGINS sign (effect ``begin``);
     with channelizers on, also after a sustained density of drums / cones while
     approaching with no begin sign ahead (a missed R22-1).  Other orange signs
     (``in_zone``) do not start it: they stand in advance warning areas too, and W20-1 /
     W20-5 are often classified as them;
   * ``leaving`` on a confirmed END ROAD WORK still ahead while approaching or inside (from
     ``none`` an end sign starts nothing: it is never a zone's first evidence); ``none``
     once it is passed.  An END placed within ``colocated_m`` of another confirmed sign is
     part of that sign's assembly (a stand's flags, a plaque boxed alone), not an end;
   * back to ``none`` from approaching, inside or leaving when no evidence was seen for
     ``timeout_m`` metres (``timeout_s`` seconds when there is no odometry);
   * with ``stale_inputs`` no transition ever goes to ``none`` (timeouts and passed end
     signs wait for live inputs) and ``none`` is published as ``unknown``.

   Every transition records a ``reason`` naming its evidence; the zone's fields and memory
   are cleared when it ends.
6. **Fields**: ``speed_limit_mph`` from the latest confirmed work-zone speed-limit sign
   (values voted over its frames by reading confidence; ``speed_limit_value`` in
   ``unknowns`` while that sign has no readable value), ``lane_shift`` from the latest lane
   shift sign (plain W1-4: ``unknown`` + ``lane_shift_direction``), ``lanes_closed`` from
   lane closed / lane ends signs.
7. **Channelizers** (drums / cones per frame, weaker in-zone evidence): their density (the
   median count per frame over the last ``channelizer_window_m``: a line of drums is in
   view frame after frame, a roadside cluster of cones for a second) adds
   ``channelizer_weight x min(1, density / channelizer_saturation)`` to the likelihood;
   while a zone is active a density >= ``channelizer_inside_density`` counts as in-zone
   evidence (keeps the zone from timing out) and promotes ``approaching`` to ``inside``
   when no begin sign is ahead.  They never start a zone: from ``none`` they only raise
   the likelihood.

What a planner reads: ``active`` is true exactly while the vehicle is *between* the begin
and end of the zone (phase ``inside`` or ``leaving``); ``approaching`` means a zone is ahead
(its speed limit and closed lanes are already in the state; ``Evidence.ahead_m`` says how
far); ``unknown`` means do not assume there is no zone.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields
from typing import Any, Hashable, Optional, Sequence

from workzone_ros.core import signs as catalogue
from workzone_ros.core.knobs import knob
from workzone_ros.interfaces import Evidence, Header, Signs, Time, WorkzoneState

__all__ = ['FusionConfig', 'WorkzoneFusion', 'PHASES', 'ACTIVE_PHASES', 'ROLES', 'MPH',
           'role_of']

MPH = 0.44704                     # m/s per mile per hour
PHASES = ('unknown', 'none', 'approaching', 'inside', 'leaving')
#: Phases in which ``WorkzoneState.active`` is true: between the begin and the end sign.
ACTIVE_PHASES = ('inside', 'leaving')
#: Catalogue ``effect`` -> the sign's role in the state machine.
ROLES = {
    'approaching': 'advance', 'speed_limit': 'advance', 'lane_shift': 'advance',
    'lane_shift_left': 'advance', 'lane_shift_right': 'advance',
    'lane_closed_left': 'advance', 'lane_closed_right': 'advance',
    'begin': 'begin', 'end': 'end',
    # Other orange signs (W20-4 ONE LANE ROAD AHEAD, W20-7 flagger, W21-5 SHOULDER WORK)
    # stand in the advance warning area as often as inside, and the classifier takes
    # W20-1 and W20-5 for them (60 of 148 W20-1 frames on the tuning bags): reaching one
    # is no zone start.
    'in_zone': 'advance',
}
_WORKZONE = frozenset(catalogue.WORKZONE_KEYS)
_MIN_CHANNEL_FRAMES = 10          # a channelizer density needs this many frames at least
_MAX_CHANNEL_FRAMES = 900         # and keeps at most this many (a standing car)
_MAX_PHASE_EVIDENCE = 8


def role_of(class_key: str) -> Optional[str]:
    """``advance``, ``begin``, ``end`` for work-zone classes, None for the others."""
    c = catalogue.BY_KEY.get(class_key)
    return ROLES.get(c.effect) if c is not None and c.category == 'workzone' else None


def _knob(default: Any, doc: str, lo: Optional[float] = None, hi: Optional[float] = None,
          open_lo: bool = False):
    """A FusionConfig field (:func:`~workzone_ros.core.knobs.knob`); ``open_lo``: the lower
    bound itself is excluded (the node parameter's range stays closed)."""
    return knob(default, doc, lo, hi, open_lo=open_lo)


@dataclass(frozen=True)
class FusionConfig:
    """Every knob of the fusion (each field's ``metadata['doc']`` says what it does).

    Raises:
        ValueError: naming the field, for a value of the wrong type or out of range.
    """

    gamma: float = _knob(0.9, 'discount of older classifications in the per-track vote '
                         '(Seo et al. eq. 4; the seed found 0.9 best)', 0.0, 1.0, True)
    vote_window: int = _knob(5, 'T of eq. 4: earlier classifications of a track that vote '
                             'with the newest (the seed found 5 best)', 0, 100)
    min_hits: int = _knob(3, 'observations a track needs before it is evidence (a stray '
                          'frame never is; a small END ROAD WORK is legible for ~10 frames)',
                          1, 1000)
    min_confidence: float = _knob(0.4, 'discounted mean score of the voted class a track '
                                  'needs to be evidence', 0.0, 1.0)
    sigma_m: float = _knob(600.0, "Gaussian propagation of a sign's confidence along the "
                           'path (m; Seo et al.: 490-1120 m); over time it is sigma_m / '
                           'assumed_speed_mps', 1.0, 1e5)
    assumed_speed_mps: float = _knob(22.35, 'speed that turns time into distance when there '
                                     "is no odometry (m/s; 22.35 = the seed's 50 mph)",
                                     0.1, 100.0)
    default_sign_distance_m: float = _knob(15.0, 'distance to a sign whose Sign.distance_m '
                                           'is unknown when it was seen (m)', 0.0, 500.0)
    track_gap_m: float = _knob(60.0, 'a track unseen for this distance is closed (m); a '
                               "retired sign's observations are ignored this long",
                               1.0, 1e4)
    track_gap_s: float = _knob(4.0, 'a track unseen for this time is closed (s)',
                               0.1, 600.0)
    warmup_s: float = _knob(1.0, 'input time before a quiet start is published as none '
                            '(unknown until then; also after a reset)', 0.0, 600.0)
    timeout_m: float = _knob(2000.0, 'no evidence for this distance ends a zone (m; with '
                             'odometry)', 1.0, 1e6)
    timeout_s: float = _knob(90.0, 'no evidence for this time ends a zone (s; without '
                             'odometry)', 0.1, 1e5)
    use_channelizers: bool = _knob(True, 'drums / cones counted by the colour stage are '
                                   'weak in-zone evidence')
    channelizer_weight: float = _knob(0.3, 'most the channelizer density adds to the '
                                      'likelihood', 0.0, 1.0)
    channelizer_window_m: float = _knob(150.0, 'distance over which the channelizer '
                                        'density (median devices per frame) is taken (m)',
                                        1.0, 1e4)
    channelizer_saturation: float = _knob(3.0, 'devices per frame at which the channelizer '
                                          'term is full', 0.0, 1000.0, True)
    channelizer_inside_density: float = _knob(2.0, 'devices per frame that support inside '
                                              'and keep an active zone alive', 0.0, 1000.0,
                                              True)
    colocated_m: float = _knob(10.0, 'an END ROAD WORK placed within this of another '
                               "confirmed sign of the zone is part of that sign's assembly "
                               "(a plaque, a stand's flags), not an end: work-zone signs "
                               'stand at least ~30 m apart (MUTCD 6F); 0 = off', 0.0, 1000.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            _check(f, getattr(self, f.name))


def _check(f, value: Any) -> None:
    """Type and range of one FusionConfig field (ValueError naming it)."""
    name = f'FusionConfig.{f.name}'
    kind = type(f.default)
    if kind is bool:
        if not isinstance(value, bool):
            raise ValueError(f'{name} must be true or false, got {value!r}')
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or (kind is int and not float(value).is_integer()):
        raise ValueError(f'{name} must be {"an integer" if kind is int else "a number"}, '
                         f'got {value!r}')
    if not math.isfinite(value):
        raise ValueError(f'{name} must be finite, got {value!r}')
    lo, hi, open_lo = f.metadata['min'], f.metadata['max'], f.metadata['open_lo']
    if (lo is not None and (value < lo or (open_lo and value == lo))) \
            or (hi is not None and value > hi):
        raise ValueError(f'{name} must be in {"(" if open_lo else "["}{lo}, {hi}], '
                         f'got {value!r}')


# --- one sign over time ---------------------------------------------------------------------

class _Track:
    """One physical sign: its recent classifications, where it stands, what it says."""

    def __init__(self, key: Hashable, track_id: Optional[int], window: int) -> None:
        self.key, self.track_id = key, track_id
        self.history: deque[dict[str, float]] = deque(maxlen=window + 1)
        self.hits = 0
        self.vote_class, self.vote_conf = 'background', 0.0
        self.evidence_class: Optional[str] = None      # confirmed class (sticky)
        self.evidence_conf = 0.0
        self.last_ns = 0
        self.last_s = 0.0
        self.distance: Optional[float] = None
        self.looks: deque[tuple[float, float]] = deque(maxlen=window + 1)   # (s + d, weight)
        self.speed_votes: dict[int, float] = {}

    def observe(self, h: dict[str, float], ns: int, s: float, distance: Optional[float],
                default_distance: float) -> None:
        """Add one classification seen at path position ``s``."""
        self.history.append(h)
        self.hits += 1
        self.last_ns, self.last_s = ns, s
        if distance is not None:
            self.distance = distance
        d = distance if distance is not None else default_distance
        self.looks.append((s + d, 1.0 / max(d, 1.0) ** 2))

    def vote(self, gamma: float) -> tuple[str, float]:
        """Seo et al., eq. 4 over the history (newest last): (class, discounted mean)."""
        votes: dict[str, float] = {}
        norm = 0.0
        for lag, h in enumerate(reversed(self.history)):
            g = gamma ** lag
            norm += g
            for c, p in h.items():
                votes[c] = votes.get(c, 0.0) + g * p
        if not votes:
            return 'background', 0.0
        best = max(sorted(votes), key=votes.__getitem__)
        return best, min(1.0, votes[best] / norm)

    @property
    def x(self) -> float:
        """Estimated position of the sign along the travelled path (m): its recent looks.

        Only the last ``T + 1`` looks: the path coordinate of older ones drifts (without
        odometry it assumes a speed; a car standing before a sign in view must not reach it).
        """
        den = sum(w for _, w in self.looks)
        return sum(x * w for x, w in self.looks) / den if den else self.last_s

    def speed_value(self) -> Optional[int]:
        """The speed limit read on this sign, voted over its frames by confidence."""
        if not self.speed_votes:
            return None
        return max(sorted(self.speed_votes), key=self.speed_votes.__getitem__)


# --- the fusion -----------------------------------------------------------------------------

class WorkzoneFusion:
    """Signs (+ odometry, + channelizer counts) -> :class:`WorkzoneState`, frame by frame.

    Attributes:
        unknown_classes: signs (or probability keys) with a class key not in the catalogue,
            ignored; the node reports the count in ``/diagnostics``.
        resets: memory resets because a stamp went backwards (a looping bag).
    """

    def __init__(self, config: FusionConfig = FusionConfig()) -> None:
        """Start in phase ``unknown`` with an empty memory.

        Raises:
            TypeError: ``config`` is not a FusionConfig.
        """
        self.config = config
        self.unknown_classes = 0
        self.resets = 0
        self.reset()

    @property
    def config(self) -> FusionConfig:
        """The configuration; assigning a new one keeps the memory."""
        return self._config

    @config.setter
    def config(self, config: FusionConfig) -> None:
        if not isinstance(config, FusionConfig):
            raise TypeError(f'config must be a FusionConfig, got {type(config).__name__}')
        self._config = config

    def reset(self) -> None:
        """Back to phase ``unknown``; every track, evidence and travelled metre forgotten."""
        self._phase = 'unknown'
        self._reason = 'no input yet'
        self._open: dict[Hashable, _Track] = {}
        self._memory: list[_Track] = []          # confirmed signs of the current zone
        self._retired: dict[Hashable, tuple[float, int]] = {}   # key -> (s, ns) last seen
        self._cause: list[_Track] = []           # the evidence of the last transition
        self._first_ns: Optional[int] = None
        self._ns: Optional[int] = None           # the timeline: the newest stamp seen
        self._update_ns: Optional[int] = None    # the last update's stamp (resets)
        self._frame_id = ''
        self._s = 0.0
        self._odom: Optional[float] = None
        self._odom_mode = False
        self._channel: deque[tuple[float, int]] = deque(maxlen=_MAX_CHANNEL_FRAMES)
        self._channel_ns: Optional[int] = None   # last frame the density supported a zone
        self._channel_s = 0.0
        self._evidence_ns: Optional[int] = None
        self._evidence_s = 0.0
        self._quiet_m = 0.0
        self._quiet_s = 0.0
        self._ended_s: Optional[float] = None
        self._hold_none = ''                     # why unknown may not become none yet

    def hold_none(self, reason: str) -> None:
        """Stay ``unknown`` rather than claim ``none`` until evidence rebuilds.

        For a fusion restarted while a zone was active (the node checkpoints its phase): the
        zone may still be around the vehicle with no sign in view, so ``unknown`` becomes
        ``none`` only by evidence -- an END ROAD WORK passed -- or after the zone timeout
        (``timeout_m`` / ``timeout_s`` without evidence), not after ``warmup_s``.
        """
        self._hold_none = reason
        self._reason = f'unknown: {reason}; no none before an END sign or the timeout'

    @property
    def phase(self) -> str:
        """The internal phase (before the stale-input rule of the published state)."""
        return self._phase

    # --- inputs -----------------------------------------------------------------------------

    def update(self, signs: Signs, *, odom_distance_m: Optional[float] = None,
               channelizers: Optional[int] = None,
               stale_inputs: Sequence[str] = ()) -> WorkzoneState:
        """Fuse one camera frame's classified signs (may be empty: a quiet scene).

        Args:
            signs: the classifier's output for one frame.
            odom_distance_m: cumulative metres travelled (odometry); None without odometry
                (the fusion then assumes ``assumed_speed_mps``).
            channelizers: drums / cones the colour stage counted in this frame (None: not
                counted).
            stale_inputs: input topics whose last message is too old (passed through).

        Returns:
            The state, stamped like ``signs``.  A stamp older than the previous update's
            resets the memory first (counted in :attr:`resets`).  A stamp older than the
            last :meth:`tick` (the clock runs ahead of the images) is no time passing.
        """
        ns = signs.header.stamp.to_ns()
        if self._update_ns is not None and ns < self._update_ns:
            self.reset()
            self.resets += 1
            self._reason = 'memory reset: the stamp jumped back (a looping bag?)'
        self._update_ns = ns
        self._frame_id = signs.header.frame_id
        stale = bool(stale_inputs)
        self._advance(ns if self._ns is None else max(ns, self._ns), odom_distance_m, stale)
        for sign in signs.signs:
            self._observe(sign, ns)
        if channelizers is not None and self._config.use_channelizers:
            self._channel.append((self._s, max(0, int(channelizers))))
        self._step(stale)
        return self._state(signs.header, stale_inputs)

    def tick(self, stamp: Time, *, odom_distance_m: Optional[float] = None,
             stale_inputs: Sequence[str] = ()) -> WorkzoneState:
        """Re-publication without new signs: ages the evidence, may time out.

        A ``stamp`` older than the last one is taken as the last one (only :meth:`update`
        resets the memory).  Before the first update nothing is aged: the state is
        ``unknown`` at ``stamp`` (a node's clock and the images' stamps may differ).
        """
        stale = bool(stale_inputs)
        if self._update_ns is None:
            return self._state(Header(stamp=stamp, frame_id=self._frame_id), stale_inputs)
        ns = max(stamp.to_ns(), self._ns)
        self._advance(ns, odom_distance_m, stale)
        self._step(stale)
        return self._state(Header(stamp=Time.from_ns(ns), frame_id=self._frame_id),
                           stale_inputs)

    def _advance(self, ns: int, odom: Optional[float], stale: bool) -> None:
        """Move the path coordinate and the quiet counters to ``ns``."""
        dt = 0.0 if self._ns is None else (ns - self._ns) * 1e-9
        if self._first_ns is None:
            self._first_ns = ns
        if odom is not None and math.isfinite(odom):
            ds = max(0.0, odom - self._odom) if self._odom is not None \
                else dt * self._config.assumed_speed_mps
            self._odom, self._odom_mode = float(odom), True
        else:
            ds = dt * self._config.assumed_speed_mps
            self._odom, self._odom_mode = None, False
        self._s += ds
        if not stale:
            self._quiet_m += ds
            self._quiet_s += dt
        self._ns = ns
        self._close_tracks()

    def _scores(self, sign) -> Optional[dict[str, float]]:
        """``h`` of eq. 4 for one sign: its probabilities, else class one-hot x score."""
        h = {}
        unknown = False
        for c, p in sign.probabilities.items():
            if c in catalogue.BY_KEY:
                if math.isfinite(p) and p > 0:
                    h[c] = float(p)
            else:
                unknown = True
        if not sign.probabilities or not h:
            if sign.class_key in catalogue.BY_KEY:
                h = {sign.class_key: float(sign.score)}
            else:
                unknown = True
        if unknown:
            self.unknown_classes += 1
        return h or None

    def _observe(self, sign, ns: int) -> None:
        """One sign of the frame: into its track's vote; confirm the track when it is."""
        cfg = self._config
        if sign.category == 'unknown':
            return
        h = self._scores(sign)
        if h is None:
            return
        if sign.track_id is None:                      # votes alone; pooled per class
            c = max(sorted(h), key=h.__getitem__)
            if c not in _WORKZONE:
                return
            key: Hashable = ('untracked', c)
            h = {c: h[c]}
        else:
            key = int(sign.track_id)
        if key in self._retired:                       # a sign the zone is done with
            self._retired[key] = (self._s, ns)
            return
        track = self._open.get(key)
        if track is None:
            track = self._open[key] = _Track(key, sign.track_id, cfg.vote_window)
        track.observe(h, ns, self._s, sign.distance_m, cfg.default_sign_distance_m)
        track.vote_class, track.vote_conf = track.vote(cfg.gamma)
        if sign.speed_limit_mph is not None:
            w = sign.speed_limit_confidence if sign.speed_limit_confidence is not None \
                else sign.score
            track.speed_votes[int(sign.speed_limit_mph)] = \
                track.speed_votes.get(int(sign.speed_limit_mph), 0.0) + float(w) + 1e-6
        if track.hits >= cfg.min_hits and track.vote_class in _WORKZONE \
                and track.vote_conf >= cfg.min_confidence:
            if self._is_echo_of_end(track):
                self._retire(track)
                return
            track.evidence_class, track.evidence_conf = track.vote_class, track.vote_conf
            if track not in self._memory:
                self._memory.append(track)
        if track.evidence_class is not None and track.vote_class == track.evidence_class:
            self._evidence_ns, self._evidence_s = ns, self._s
            self._quiet_m = self._quiet_s = 0.0

    def _is_echo_of_end(self, track: _Track) -> bool:
        """An END ROAD WORK confirmed again just after the zone ended on it (re-acquired)."""
        return (track.vote_class in _WORKZONE and role_of(track.vote_class) == 'end'
                and self._ended_s is not None
                and track.x < self._ended_s + self._config.track_gap_m)

    def _retire(self, track: _Track) -> None:
        """Forget a sign; its later observations (same key) are ignored for a while."""
        self._open.pop(track.key, None)
        self._retired[track.key] = (track.last_s, track.last_ns)
        if track in self._memory:
            self._memory.remove(track)

    def _close_tracks(self) -> None:
        """Close tracks (and let retired keys go) unseen for track_gap_m or track_gap_s."""
        cfg, s, ns = self._config, self._s, self._ns or 0
        gap_ns = cfg.track_gap_s * 1e9

        def gone(last_s: float, last_ns: int) -> bool:
            return s - last_s > cfg.track_gap_m or ns - last_ns > gap_ns
        for key in [k for k, t in self._open.items() if gone(t.last_s, t.last_ns)]:
            del self._open[key]
        for key in [k for k, v in self._retired.items() if gone(*v)]:
            del self._retired[key]

    # --- channelizers ---------------------------------------------------------------------

    def _channel_density(self) -> float:
        """Median devices per frame over the last channelizer_window_m (0 when off).

        The median, not the mean: a line of drums along a closure is in view frame after
        frame, a roadside cluster of cones only for a second or two.  Windows shorter than
        ``_MIN_CHANNEL_FRAMES`` frames are padded with zeros.
        """
        cfg = self._config
        if not cfg.use_channelizers:
            return 0.0
        while self._channel and self._s - self._channel[0][0] > cfg.channelizer_window_m:
            self._channel.popleft()
        counts = sorted([n for _, n in self._channel]
                        + [0] * max(0, _MIN_CHANNEL_FRAMES - len(self._channel)))
        mid = len(counts) // 2
        return float(counts[mid]) if len(counts) % 2 else (counts[mid - 1] + counts[mid]) / 2

    # --- the state machine ----------------------------------------------------------------

    def _evidence_tracks(self) -> list[_Track]:
        return [t for t in self._memory if t.evidence_class is not None]

    def _step(self, stale: bool) -> None:
        """Apply at most one transition of the phase machine (module docstring, item 5)."""
        s = self._s
        live = self._evidence_tracks()
        by_role: dict[str, list[_Track]] = {'advance': [], 'begin': [], 'end': []}
        for t in live:
            by_role[role_of(t.evidence_class)].append(t)
        by_role['end'] = [t for t in by_role['end'] if not self._colocated(t, live)]
        ends_ahead = [t for t in by_role['end'] if s < t.x]
        ends_passed = [t for t in by_role['end'] if s >= t.x]
        begins_reached = [t for t in by_role['begin'] if s >= t.x]
        begins_ahead = [t for t in by_role['begin'] if s < t.x]
        density = self._channel_density()
        channel = density >= self._config.channelizer_inside_density and density > 0
        if channel and self._phase in ('approaching', 'inside', 'leaving'):
            self._channel_ns, self._channel_s = self._ns, s
            self._evidence_ns, self._evidence_s = self._ns, s
            self._quiet_m = self._quiet_s = 0.0
        phase = self._phase
        if ends_passed and not ends_ahead:
            if stale:
                return
            t = max(ends_passed, key=lambda t: t.x)
            self._end_zone(f'passed {_name(t)}', t.x)
            return
        if phase in ('approaching', 'inside') and ends_ahead:
            t = min(ends_ahead, key=lambda t: t.x)
            self._go('leaving', [t], f'{_name(t)} {t.x - s:.0f} m ahead')
        elif phase in ('unknown', 'none', 'approaching') and begins_reached:
            t = max(begins_reached, key=lambda t: t.x)
            self._go('inside', [t], f'reached {_name(t)}')
        elif phase in ('unknown', 'none') and (by_role['advance'] or begins_ahead):
            t = max(by_role['advance'] + begins_ahead, key=lambda t: t.last_ns)
            self._go('approaching', [t], f'{_name(t)} {t.x - s:.0f} m ahead')
        elif phase == 'approaching' and channel and not begins_ahead:
            self._go('inside', [], f'channelizers: {density:.1f} per frame over the last '
                     f'{self._config.channelizer_window_m:.0f} m and no begin sign ahead')
        elif phase in ('approaching', 'inside', 'leaving') and self._timed_out():
            if not stale:
                self._end_zone(self._timeout_reason(), None)
        elif phase == 'unknown' and self._hold_none and not stale and self._timed_out():
            self._hold_none = ''
            self._go('none', [], f'after a restart: {self._timeout_reason()}')
        elif phase == 'unknown' and not live and not stale and self._ns is not None \
                and not self._hold_none \
                and (self._ns - self._first_ns) * 1e-9 >= self._config.warmup_s:
            self._go('none', [], 'no work-zone evidence')

    def _colocated(self, end: _Track, live: list[_Track]) -> bool:
        """Whether an END ROAD WORK stands where another confirmed sign does."""
        d = self._config.colocated_m
        return d > 0 and any(u is not end and role_of(u.evidence_class) != 'end'
                             and abs(u.x - end.x) < d for u in live)

    def _timed_out(self) -> bool:
        cfg = self._config
        return self._quiet_m >= cfg.timeout_m if self._odom_mode \
            else self._quiet_s >= cfg.timeout_s

    def _timeout_reason(self) -> str:
        cfg = self._config
        if self._odom_mode:
            return f'timeout: no evidence for {self._quiet_m:.0f} m (timeout_m {cfg.timeout_m:g})'
        return f'timeout: no evidence for {self._quiet_s:.1f} s (timeout_s {cfg.timeout_s:g})'

    def _go(self, phase: str, cause: list[_Track], reason: str) -> None:
        self._hold_none = ''
        self._phase, self._cause = phase, cause
        self._reason = f'{phase}: {reason}'

    def _end_zone(self, reason: str, end_x: Optional[float]) -> None:
        """The zone is over: phase none, its signs retired, its fields cleared.

        Signs standing beyond the END ROAD WORK that ended it (the next zone's) are kept.
        """
        keep = [t for t in self._memory if end_x is not None and t.x > end_x + 1.0]
        for t in [t for t in self._memory if t not in keep]:
            self._retire(t)
        self._memory = keep
        if end_x is not None:
            self._ended_s = end_x
        self._go('none', [], reason)
        self._evidence_ns = None
        self._channel_ns = None
        self._channel.clear()

    # --- output -----------------------------------------------------------------------------

    def likelihood(self) -> float:
        """Seo et al., eq. 3 (causal, over the path) as a noisy-or, with the channelizers."""
        cfg, s = self._config, self._s
        keep = 1.0
        for t in self._evidence_tracks():
            g = math.exp(-0.5 * ((s - t.last_s) / cfg.sigma_m) ** 2)
            keep *= 1.0 - t.evidence_conf * g
        density = self._channel_density()
        if density > 0:
            keep *= 1.0 - cfg.channelizer_weight * min(1.0,
                                                       density / cfg.channelizer_saturation)
        return min(1.0, max(0.0, 1.0 - keep))

    def _latest(self, classes: Sequence[str]) -> Optional[_Track]:
        found = [t for t in self._evidence_tracks() if t.evidence_class in classes]
        return max(found, key=lambda t: (t.x, t.last_ns)) if found else None

    def _fields(self) -> tuple[dict[str, Any], list[Evidence]]:
        """speed_limit_mph, lane_shift, lanes_closed, unknowns and their evidence."""
        out: dict[str, Any] = {'speed_limit_mph': None, 'lane_shift': 'none',
                               'lanes_closed': [], 'unknowns': []}
        ev: list[Evidence] = []
        speed = self._latest(('work_zone_speed_limit',))
        if speed is not None:
            out['speed_limit_mph'] = speed.speed_value()
            if out['speed_limit_mph'] is None:
                out['unknowns'].append('speed_limit_value')
            ev.append(self._evidence(speed, 'speed_limit_mph'))
        shift = self._latest(('lane_shift', 'lane_shift_left', 'lane_shift_right'))
        if shift is not None:
            effect = catalogue.get(shift.evidence_class).effect
            out['lane_shift'] = {'lane_shift_left': 'left',
                                 'lane_shift_right': 'right'}.get(effect, 'unknown')
            if out['lane_shift'] == 'unknown':
                out['unknowns'].append('lane_shift_direction')
            ev.append(self._evidence(shift, 'lane_shift'))
        sides = set()
        for t in self._evidence_tracks():
            effect = catalogue.get(t.evidence_class).effect
            if effect.startswith('lane_closed_'):
                sides.add(effect.rsplit('_', 1)[1])
                ev.append(self._evidence(t, 'lanes_closed'))
        out['lanes_closed'] = sorted(sides)
        return out, ev

    def _evidence(self, t: _Track, field_name: str) -> Evidence:
        return Evidence(class_key=t.evidence_class or t.vote_class,
                        weight=round(t.evidence_conf, 4), stamp=Time.from_ns(t.last_ns),
                        track_id=t.track_id, field=field_name,
                        distance_m=None if t.distance is None else round(t.distance, 2),
                        ahead_m=round(t.x - self._s, 2))

    def _phase_evidence(self) -> list[Evidence]:
        """The transition's cause first, then the zone's other signs, newest first."""
        cause = [t for t in self._cause if t in self._memory]
        rest = sorted((t for t in self._evidence_tracks() if t not in cause),
                      key=lambda t: -t.last_ns)
        out = [self._evidence(t, 'phase') for t in (cause + rest)[:_MAX_PHASE_EVIDENCE]]
        density = self._channel_density()
        if density > 0 and self._channel_ns is not None:
            cfg = self._config
            out.append(Evidence(class_key='channelizers', weight=round(
                cfg.channelizer_weight * min(1.0, density / cfg.channelizer_saturation), 4),
                stamp=Time.from_ns(self._channel_ns), field='phase'))
        return out

    def _state(self, header: Header, stale_inputs: Sequence[str]) -> WorkzoneState:
        phase = self._phase
        reason = self._reason
        if stale_inputs and phase == 'none':
            phase = 'unknown'
            reason = f'unknown: stale inputs ({", ".join(stale_inputs)}); was {self._reason}'
        values, field_ev = self._fields()
        age = dist = None
        if self._evidence_ns is not None and self._ns is not None:
            age = max(0.0, (self._ns - self._evidence_ns) * 1e-9)
            dist = max(0.0, self._s - self._evidence_s)
        return WorkzoneState(
            header=header, active=phase in ACTIVE_PHASES,
            likelihood=round(self.likelihood(), 6), phase=phase,
            speed_limit_mph=values['speed_limit_mph'], lane_shift=values['lane_shift'],
            lanes_closed=values['lanes_closed'], unknowns=values['unknowns'],
            stale_inputs=sorted(set(stale_inputs)),
            evidence=self._phase_evidence() + field_ev,
            evidence_age_s=None if age is None else round(age, 3),
            distance_since_evidence_m=None if dist is None else round(dist, 2),
            reason=reason)


def _name(t: _Track) -> str:
    """``road_work_ahead (track 3)`` for reasons."""
    who = f'track {t.track_id}' if t.track_id is not None else 'untracked'
    return f'{t.evidence_class} ({who})'
