"""Timestamp synchronisation and an odometry pose buffer (no rclpy).

* :class:`ApproximateTimeSync` -- the ``message_filters`` ApproximateTime policy (ROS
  ``approximate_time.h``, the "pivot" algorithm), in pure Python: one deque per topic, a
  queue size per topic, a maximum interval duration (the ``slop``), the age penalty and the
  optional inter-message lower bounds.  A set is emitted only once it is *provably optimal*:
  its interval ``[start, end]`` is the smallest among the sets that could still be formed,
  every message is used at most once, and sets come out in time order.  Cahail et al. s2.4.1 / s6.2
  projected "using the last point cloud received" under a mutex; this is what replaces it.
* :class:`LatestSync` -- that seed baseline: each image is paired with the latest cloud.
* :class:`NearestSync` -- each image is paired with the candidate set nearest in time within
  the slop; a set may serve several images (15 Hz camera, 10 Hz LiDAR: every frame gets one),
  and an image waits a bounded time for a later set only when that set could be nearer.
* :class:`ExactStampPairs` -- each image with the boxes (detections, tracks) computed on it:
  the same stamp, whichever comes first; what cannot be paired is reported, not lost.
* :class:`PoseBuffer` -- odometry poses with interpolation (linear for the position, slerp
  for the orientation) and short extrapolation, used for ego-motion compensation between
  scan time and image time (the seed's 5 m error at 60 mph without it).

Stamps are integer nanoseconds everywhere.
"""
from __future__ import annotations

import bisect
from collections import OrderedDict, deque
from typing import Any, Callable, Optional, Sequence

import numpy as np

__all__ = ['SyncError', 'ApproximateTimeSync', 'LatestSync', 'NearestSync', 'ExactStampPairs',
           'PoseBuffer', 'FrameGaps', 'quat_to_matrix', 'matrix_to_quat', 'slerp', 'pose_matrix']


class SyncError(ValueError):
    """Invalid synchroniser settings or input."""


class ApproximateTimeSync:
    """message_filters' ApproximateTime policy for ``n`` topics (ROS approximate_time.h).

    Args:
        n_topics: number of input topics (>= 2).
        queue_size: messages kept per topic (deque + messages set aside during the search).
        slop_ns: maximum interval duration of an emitted set (``setMaxIntervalDuration`` in
            C++, ``slop`` in the Python ``ApproximateTimeSynchronizer``); None = unlimited.
        age_penalty: weight of the candidate's age when comparing sets (C++ default 0.1).
        lower_bounds_ns: optional minimum spacing between messages of each topic; helps
            prove optimality earlier (C++ ``setInterMessageLowerBound``).
        callback: optional ``callback(*messages)`` per emitted set.

    :meth:`add` returns the sets emitted by that call, each a tuple ``(stamps, messages)``.
    """

    def __init__(self, n_topics: int, queue_size: int = 10, slop_ns: Optional[int] = None,
                 age_penalty: float = 0.1, lower_bounds_ns: Optional[Sequence[int]] = None,
                 callback: Optional[Callable[..., Any]] = None) -> None:
        if n_topics < 2:
            raise SyncError('ApproximateTimeSync needs at least 2 topics')
        if queue_size < 1:
            raise SyncError('queue_size must be at least 1')
        if age_penalty < 0:
            raise SyncError('age_penalty must be >= 0')
        self.n = int(n_topics)
        self.queue_size = int(queue_size)
        self.slop_ns = None if slop_ns is None else int(slop_ns)
        self.age_penalty = float(age_penalty)
        self.lower = [0] * self.n if lower_bounds_ns is None else [int(b) for b in
                                                                   lower_bounds_ns]
        if len(self.lower) != self.n:
            raise SyncError('lower_bounds_ns needs one value per topic')
        self.callback = callback
        self._deques: list[deque] = [deque() for _ in range(self.n)]
        self._past: list[list] = [[] for _ in range(self.n)]
        self._dropped = [False] * self.n
        self._non_empty = 0
        self._pivot: Optional[int] = None
        self._pivot_time = 0
        self._cand: Optional[list] = None
        self._cand_start = 0
        self._cand_end = 0
        self._out: list = []
        self.dropped_count = [0] * self.n
        self.out_of_order = [0] * self.n

    # -- public -------------------------------------------------------------------------
    def add(self, topic: int, stamp_ns: int, msg: Any = None) -> list:
        """Add one message of topic ``topic``; return the sets this emitted."""
        if not 0 <= topic < self.n:
            raise SyncError(f'topic index {topic} outside 0..{self.n - 1}')
        self._out = []
        q = self._deques[topic]
        q.append((int(stamp_ns), msg))
        if len(q) == 1:
            self._non_empty += 1
            if self._non_empty == self.n:
                self._process()
        else:
            self._check_inter_message_bound(topic)
        if len(q) + len(self._past[topic]) > self.queue_size:
            # Cancel the ongoing candidate search, drop the oldest message of this topic.
            self._non_empty = 0
            for i in range(self.n):
                self._recover(i)
            q.popleft()
            self.dropped_count[topic] += 1
            self._dropped[topic] = True
            if self._pivot is not None:
                self._cand = None
                self._pivot = None
                self._process()
        return self._out

    def pending(self) -> list[int]:
        """Messages waiting per topic (deque + set aside)."""
        return [len(q) + len(p) for q, p in zip(self._deques, self._past)]

    # -- the algorithm (names follow approximate_time.h) ---------------------------------
    def _check_inter_message_bound(self, i: int) -> None:
        # approximate_time.h only warns about out-of-order stamps; count them.
        q = self._deques[i]
        if len(q) >= 2 and q[-1][0] < q[-2][0]:
            self.out_of_order[i] += 1

    def _recover(self, i: int) -> None:
        q, v = self._deques[i], self._past[i]
        while v:
            q.appendleft(v.pop())
        if q:
            self._non_empty += 1

    def _recover_and_delete(self, i: int) -> None:
        q, v = self._deques[i], self._past[i]
        while v:
            q.appendleft(v.pop())
        q.popleft()
        if q:
            self._non_empty += 1

    def _delete_front(self, i: int) -> None:
        q = self._deques[i]
        q.popleft()
        if not q:
            self._non_empty -= 1

    def _move_front_to_past(self, i: int) -> None:
        q = self._deques[i]
        self._past[i].append(q.popleft())
        if not q:
            self._non_empty -= 1

    def _make_candidate(self) -> None:
        self._cand = [q[0] for q in self._deques]
        for v in self._past:
            v.clear()

    def _publish_candidate(self) -> None:
        cand = self._cand
        stamps = tuple(s for s, _ in cand)
        msgs = tuple(m for _, m in cand)
        self._out.append((stamps, msgs))
        if self.callback is not None:
            self.callback(*msgs)
        self._cand = None
        self._pivot = None
        self._non_empty = 0
        for i in range(self.n):
            self._recover_and_delete(i)

    def _candidate_bounds(self) -> tuple[int, int, int, int]:
        """(start_index, start_time, end_index, end_time) over the deque fronts."""
        return self._bounds([q[0][0] for q in self._deques])

    def _bounds(self, times: list[int]) -> tuple[int, int, int, int]:
        # Ties as getCandidateBoundary: the start is the lowest index, the end the highest.
        si = min(range(self.n), key=lambda i: (times[i], i))
        ei = max(range(self.n), key=lambda i: (times[i], i))
        return si, times[si], ei, times[ei]

    def _virtual_time(self, i: int) -> int:
        q = self._deques[i]
        if not q:
            last = self._past[i][-1][0]
            bound = last + self.lower[i]
            return bound if bound > self._pivot_time else self._pivot_time
        return q[0][0]

    def _virtual_bounds(self) -> tuple[int, int, int, int]:
        return self._bounds([self._virtual_time(i) for i in range(self.n)])

    def _worse(self, end_time: int, start_time: int) -> bool:
        """(end - cand_end) * (1 + age_penalty) >= (start - cand_start)."""
        return (end_time - self._cand_end) * (1.0 + self.age_penalty) >= \
            (start_time - self._cand_start)

    def _process(self) -> None:
        while self._non_empty == self.n:
            si, start_time, ei, end_time = self._candidate_bounds()
            for i in range(self.n):
                if i != ei:
                    self._dropped[i] = False
            if self._pivot is None:
                if self.slop_ns is not None and end_time - start_time > self.slop_ns:
                    self._delete_front(si)       # interval too big: move to the next
                    continue
                if self._dropped[ei]:
                    self._delete_front(si)       # the end topic dropped messages
                    continue
                self._make_candidate()
                self._cand_start, self._cand_end = start_time, end_time
                self._pivot, self._pivot_time = ei, end_time
                self._move_front_to_past(si)
            else:
                if self._worse(end_time, start_time):
                    self._move_front_to_past(si)     # not a better candidate
                else:
                    self._make_candidate()           # a better candidate, same pivot
                    self._cand_start, self._cand_end = start_time, end_time
                    self._move_front_to_past(si)
            if si == self._pivot:
                self._publish_candidate()            # every candidate for this pivot seen
            elif self._worse(end_time, self._pivot_time):
                self._publish_candidate()            # provably optimal already
            elif self._non_empty < self.n:
                before = self._non_empty
                virtual_moves = [0] * self.n
                while True:
                    vsi, vstart, vei, vend = self._virtual_bounds()
                    if self._worse(vend, self._pivot_time):
                        self._publish_candidate()    # optimality proved
                        break
                    if not self._worse(vend, vstart):
                        # A virtual (optimistic) candidate could still be better: undo.
                        self._non_empty = 0
                        for i in range(self.n):
                            for _ in range(virtual_moves[i]):
                                self._deques[i].appendleft(self._past[i].pop())
                            if self._deques[i]:
                                self._non_empty += 1
                        assert self._non_empty == before
                        break
                    self._move_front_to_past(vsi)
                    virtual_moves[vsi] += 1


class LatestSync:
    """Cahail et al. s2.4.1 baseline: each image is paired with the last cloud received.

    ``add_cloud`` stores the cloud; ``add_image`` returns ``(cloud_stamp, cloud)`` or None
    when no cloud arrived yet (the seed's mutex-protected "last point cloud").
    """

    def __init__(self) -> None:
        self._cloud: Optional[tuple[int, Any]] = None

    def add_cloud(self, stamp_ns: int, cloud: Any) -> None:
        """Remember the latest cloud."""
        self._cloud = (int(stamp_ns), cloud)

    def add_image(self, stamp_ns: int) -> Optional[tuple[int, Any]]:
        """The cloud to project onto this image (the latest), or None."""
        return self._cloud


class ExactStampPairs:
    """Each image paired with the boxes computed on it (the same stamp), in either order.

    A node downstream of a detector gets the camera image and the boxes of that image on two
    topics; the boxes come later (the detector's processing time), or earlier when the image
    is late.  Up to ``size`` images wait for their boxes and ``size`` boxes for their image.
    Boxes that cannot be paired are reported with the reason (for ``/diagnostics``): their
    image left the ring before they came (they are more than ``size`` frames late), their
    image never came (a frame the node did not receive), or too many boxes waited.

    Args:
        size: images (and boxes) kept waiting.
    """

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f'size must be at least 1, got {size}')
        self.size = int(size)
        self._images: OrderedDict[int, Any] = OrderedDict()
        self._boxes: OrderedDict[int, Any] = OrderedDict()
        self._evicted: OrderedDict[int, None] = OrderedDict()   # images that left unpaired

    def add_image(self, stamp_ns: int, image: Any) -> Optional[tuple[Any, Any]]:
        """``(image, boxes)`` when this image's boxes were waiting, else None (it waits)."""
        if stamp_ns in self._boxes:
            return image, self._boxes.pop(stamp_ns)
        self._images[stamp_ns] = image
        while len(self._images) > self.size:
            old, _ = self._images.popitem(last=False)
            self._evicted[old] = None
            while len(self._evicted) > self.size:
                self._evicted.popitem(last=False)
        return None

    def add_boxes(self, stamp_ns: int, boxes: Any) -> tuple[Optional[tuple[Any, Any]], list[str]]:
        """``((image, boxes) or None, reasons)``: the pair when the image is here; else the
        boxes wait for it, and ``reasons`` lists each boxes dropped (these, when their image
        already left the ring; the oldest waiting, when too many wait)."""
        image = self._images.pop(stamp_ns, None)
        if image is not None:
            return (image, boxes), []
        if self._evicted.pop(stamp_ns, 0) is None:
            return None, [f'their image had left the buffer ({self.size} frames): they came '
                          'that many frames late']
        self._boxes[stamp_ns] = boxes
        reasons = []
        while len(self._boxes) > self.size:
            self._boxes.popitem(last=False)
            reasons.append('no image with their stamp arrived')
        return None, reasons

    def processed(self, stamp_ns: int) -> list[str]:
        """Frame ``stamp_ns`` was processed: older images are forgotten (their boxes never
        came: the detector skipped them), and so are older waiting boxes, whose image never
        came; returns a reason per boxes dropped."""
        for old in [k for k in self._images if k <= stamp_ns]:
            del self._images[old]
        self._boxes.pop(stamp_ns, None)
        late = [k for k in self._boxes if k < stamp_ns]
        for old in late:
            del self._boxes[old]
        return ['no image with their stamp arrived'] * len(late)

    def clear(self) -> None:
        """Forget everything (the time jumped back: a looping bag)."""
        self._images.clear()
        self._boxes.clear()
        self._evicted.clear()


class NearestSync:
    """Pair every image with the candidate set nearest in time, within the slop.

    Unlike :class:`ApproximateTimeSync` a candidate set is not consumed by its pair: with a
    15 Hz camera and a 10 Hz LiDAR every image gets a set (about a third of them share one).
    Unlike :class:`LatestSync` the pairing looks at stamps, not at arrival order, and may wait
    for a later set.

    Rules, for an image stamped ``t`` (a set's *time* is its stamp plus ``time_offset_ns``):

    1. The best set is the one with the smallest ``|time - t|``; ties go to the earlier set.
       Sets farther than ``slop_ns`` never qualify.
    2. The decision is final when no later set can be nearer: the newest set seen has a time
       ``>= t``, or the earliest possible next set (newest time + ``min_period_ns``) would be
       at least as far as the best one (or beyond the slop).  Sets are assumed to arrive in
       stamp order (a late out-of-order set is still used by images not yet decided).
    3. Otherwise the image waits, at most until an image stamped ``>= t + max_wait_ns``
       arrives (the image stream is the clock: deterministic, no timers) or ``max_pending``
       images are waiting; then it takes the best set it has, or none.

    :meth:`add_image` and :meth:`add_candidates` return the decisions they made, in image
    stamp order, each ``(image_stamp, image, set_stamp, set)`` where ``set_stamp`` and
    ``set`` are None when no set lies within the slop.

    Args:
        slop_ns: maximum ``|image stamp - set time|``.
        min_period_ns: lower bound of the spacing of set stamps (one scan period; 0 = no
            bound, so an image older than the newest set always waits for the next one).
        max_wait_ns: how long an image may wait for a nearer set, on the image clock.
        time_offset_ns: added to set stamps before matching (e.g. half a spin when the stamp
            is the start of the spin and the camera looks forward).
        history: candidate sets kept.
        max_pending: images kept waiting at most.
    """

    def __init__(self, slop_ns: int, min_period_ns: int = 0, max_wait_ns: int = 0,
                 time_offset_ns: int = 0, history: int = 10, max_pending: int = 10) -> None:
        if slop_ns < 0 or min_period_ns < 0 or max_wait_ns < 0:
            raise SyncError('slop, min_period and max_wait must be >= 0')
        if history < 1 or max_pending < 1:
            raise SyncError('history and max_pending must be at least 1')
        self.slop_ns = int(slop_ns)
        self.min_period_ns = int(min_period_ns)
        self.max_wait_ns = int(max_wait_ns)
        self.time_offset_ns = int(time_offset_ns)
        self.history = int(history)
        self.max_pending = int(max_pending)
        self._sets: list[tuple[int, int, Any]] = []      # (time, stamp, set), time-sorted
        self._newest: Optional[int] = None               # newest set time seen
        self._pending: list[tuple[int, Any]] = []        # (image stamp, image), sorted
        self._clock: Optional[int] = None                # newest image stamp seen

    def pending(self) -> int:
        """Images waiting for a decision."""
        return len(self._pending)

    def add_candidates(self, stamp_ns: int, cands: Any) -> list:
        """Store a candidate set; return the images it decided."""
        stamp = int(stamp_ns)
        t = stamp + self.time_offset_ns
        bisect.insort(self._sets, (t, stamp, cands), key=lambda e: e[0])
        if len(self._sets) > self.history:
            del self._sets[0]
        self._newest = t if self._newest is None else max(self._newest, t)
        return self._decide(force=())

    def add_image(self, stamp_ns: int, image: Any = None) -> list:
        """Queue an image; return the images decided now (this one if no wait is needed)."""
        stamp = int(stamp_ns)
        bisect.insort(self._pending, (stamp, image), key=lambda e: e[0])
        self._clock = stamp if self._clock is None else max(self._clock, stamp)
        force = {id(e) for e in self._pending[:max(len(self._pending) - self.max_pending, 0)]}
        return self._decide(force=force)

    def best(self, t_ns: int) -> Optional[tuple[int, int, Any]]:
        """The stored ``(time, stamp, set)`` nearest to ``t_ns`` within the slop, or None."""
        best, best_d = None, None
        for entry in self._sets:                     # time order: ties keep the earlier
            d = abs(entry[0] - t_ns)
            if d <= self.slop_ns and (best_d is None or d < best_d):
                best, best_d = entry, d
        return best

    def _final(self, t: int, best: Optional[tuple[int, int, Any]]) -> bool:
        if self._newest is not None and self._newest >= t:
            return True
        if self._newest is None:
            return False                             # no set yet: the first may be near
        nxt = self._newest + self.min_period_ns      # earliest possible next set time
        if nxt - t > self.slop_ns:
            return True
        return best is not None and nxt - t >= abs(best[0] - t)

    def _decide(self, force) -> list:
        out, keep = [], []
        for entry in self._pending:
            t, image = entry
            best = self.best(t)
            expired = self._clock is not None and self._clock - t >= self.max_wait_ns
            if id(entry) in force or expired or self._final(t, best):
                out.append((t, image, None if best is None else best[1],
                            None if best is None else best[2]))
            else:
                keep.append(entry)
        self._pending = keep
        return out


# --- poses ------------------------------------------------------------------------------

def quat_to_matrix(q: Sequence[float]) -> np.ndarray:
    """Unit quaternion (x, y, z, w) -> 3x3 rotation matrix."""
    x, y, z, w = (float(v) for v in q)
    n = x * x + y * y + z * z + w * w
    if n < 1e-12:
        raise SyncError('zero quaternion')
    s = 2.0 / n
    return np.array([
        [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
        [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
        [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)]])


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """3x3 rotation -> unit quaternion (x, y, z, w) with w >= 0."""
    m = np.asarray(r, float)
    t = np.trace(m)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i] = s / 4
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def slerp(q0: np.ndarray, q1: np.ndarray, f: float) -> np.ndarray:
    """Spherical linear interpolation between unit quaternions (x, y, z, w); any real f."""
    q0 = np.asarray(q0, float) / np.linalg.norm(q0)
    q1 = np.asarray(q1, float) / np.linalg.norm(q1)
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + f * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = np.arccos(min(d, 1.0))
    s = np.sin(theta)
    return (np.sin((1 - f) * theta) * q0 + np.sin(f * theta) * q1) / s


def pose_matrix(position: Sequence[float], quat: Sequence[float]) -> np.ndarray:
    """4x4 transform from a position and a quaternion (x, y, z, w)."""
    t = np.eye(4)
    t[:3, :3] = quat_to_matrix(quat)
    t[:3, 3] = np.asarray(position, float)
    return t


class PoseBuffer:
    """Time-ordered odometry poses (odom <- base) with interpolation.

    Args:
        max_age_ns: poses older than the newest by more than this are forgotten.
        max_extrapolation_ns: how far past the newest (or before the oldest) pose
            :meth:`at` extrapolates with the last (first) two poses' motion.
        max_gap_ns: refuse to interpolate across a gap in the odometry larger than this.
    """

    def __init__(self, max_age_ns: int = 5_000_000_000, max_extrapolation_ns: int = 100_000_000,
                 max_gap_ns: int = 500_000_000) -> None:
        self.max_age_ns = int(max_age_ns)
        self.max_extrapolation_ns = int(max_extrapolation_ns)
        self.max_gap_ns = int(max_gap_ns)
        self._t: list[int] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._t)

    def add(self, stamp_ns: int, position: Sequence[float], quat: Sequence[float]) -> None:
        """Insert a pose (out-of-order stamps are placed in order; duplicates replace)."""
        t = int(stamp_ns)
        p = np.asarray(position, float).reshape(3)
        q = np.asarray(quat, float).reshape(4)
        nq = np.linalg.norm(q)
        if not np.isfinite(p).all() or not np.isfinite(q).all() or nq < 1e-9:
            raise SyncError('pose with a non-finite position or an invalid quaternion')
        q = q / nq
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            self._p[i], self._q[i] = p, q
        else:
            self._t.insert(i, t)
            self._p.insert(i, p)
            self._q.insert(i, q)
        cut = bisect.bisect_left(self._t, self._t[-1] - self.max_age_ns)
        if cut:
            del self._t[:cut], self._p[:cut], self._q[:cut]

    def span(self) -> Optional[tuple[int, int]]:
        """(oldest, newest) stamps, or None when empty."""
        return (self._t[0], self._t[-1]) if self._t else None

    def at(self, stamp_ns: int) -> Optional[np.ndarray]:
        """4x4 odom <- base at ``stamp_ns``, or None when it cannot be had reliably."""
        t = int(stamp_ns)
        n = len(self._t)
        if n == 0:
            return None
        if n == 1:
            return pose_matrix(self._p[0], self._q[0]) if t == self._t[0] else None
        i = bisect.bisect_left(self._t, t)
        if i < n and self._t[i] == t:
            return pose_matrix(self._p[i], self._q[i])
        if i == 0:
            if self._t[0] - t > self.max_extrapolation_ns:
                return None
            a, b = 0, 1
        elif i == n:
            if t - self._t[-1] > self.max_extrapolation_ns:
                return None
            a, b = n - 2, n - 1
        else:
            a, b = i - 1, i
            if self._t[b] - self._t[a] > self.max_gap_ns:
                return None
        f = (t - self._t[a]) / (self._t[b] - self._t[a])
        p = self._p[a] + f * (self._p[b] - self._p[a])
        q = slerp(self._q[a], self._q[b], f)
        return pose_matrix(p, q)


class FrameGaps:
    """Camera frames that never reached a node: gaps in the stamps of the frames it got.

    A node that keeps only the newest frame while it is busy (latest-frame-wins, depth 1)
    never sees the frames it skipped; this counts them from the stamps it does see, against
    the camera's period (the median of the recent stamp steps), so ``/diagnostics`` can say
    how many frames went unprocessed.  A stamp that goes backwards (a looping bag) restarts.

    Args:
        window: recent steps the period is taken from.
    """

    def __init__(self, window: int = 30) -> None:
        import collections
        self._steps: collections.deque = collections.deque(maxlen=window)
        self._last: Optional[int] = None
        self.frames = 0
        self.skipped = 0

    def add(self, stamp_ns: int) -> int:
        """Count the frame of ``stamp_ns``; returns the frames skipped just before it."""
        gap = 0
        if self._last is not None and stamp_ns <= self._last:
            self._steps.clear()
        elif self._last is not None:
            step = stamp_ns - self._last
            if len(self._steps) >= 3:
                period = float(np.median(self._steps))
                gap = max(0, int(round(step / period)) - 1) if period > 0 else 0
            self._steps.append(step / (gap + 1))
        self._last = stamp_ns
        self.frames += 1
        self.skipped += gap
        return gap
