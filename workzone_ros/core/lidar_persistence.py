"""Persistence of LiDAR sign candidates over scans, with stable ids (Cahail et al. s1.4).

Cahail et al. s1.4 proposes "requiring an object to be present in 3 or so frames": a candidate is
published when it was seen in ``k`` of the last ``n`` scans.  With odometry the candidates
are matched in the odometry frame, so a static sign keeps its id while the car moves.
:meth:`CandidateTracker.held` says how many of a scan's candidates wait for persistence, so
a node can tell a user testing one scan why nothing was published.

No rclpy here.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Optional

import numpy as np

__all__ = ['PersistenceError', 'CandidateTracker']


class PersistenceError(ValueError):
    """Persistence parameters that cannot work (k > n, k < 1)."""


class CandidateTracker:
    """Persistence k of n with stable ids (Cahail et al. s1.4's proposed object tracking).

    Candidates are matched to tracks by nearest neighbour (greedy, closest pairs first)
    within a gate.  With a pose (4x4 odom <- lidar at the scan time) matching happens in the
    odometry frame, so a static sign keeps its position while the car moves; without one
    the match is in the lidar frame with the wider ``gate_no_odom`` gate.

    Args:
        k: scans with a detection needed among the last ``n``.
        n: window length, scans.
        gate: match distance at range 0, metres.
        gate_k: growth of the gate per metre of range.
        gate_no_odom: gate when no pose is given (car motion between scans).
    """

    def __init__(self, k: int = 2, n: int = 3, gate: float = 1.0, gate_k: float = 0.01,
                 gate_no_odom: float = 3.5) -> None:
        if not 1 <= k <= n:
            raise PersistenceError(f'persistence needs 1 <= persistence_k <= persistence_n, '
                                   f'got k={k}, n={n}')
        self.k, self.n = int(k), int(n)
        self.gate, self.gate_k, self.gate_no_odom = float(gate), float(gate_k), \
            float(gate_no_odom)
        self._pos = np.zeros((0, 3))
        self._hist = np.zeros((0, self.n), bool)
        self._ids = np.zeros(0, np.int64)
        self._framed = np.zeros(0, bool)        # position is in the odometry frame
        self._next_id = 1

    def reset(self) -> None:
        """Forget every track (ids keep increasing)."""
        self._pos = np.zeros((0, 3))
        self._hist = np.zeros((0, self.n), bool)
        self._ids = np.zeros(0, np.int64)
        self._framed = np.zeros(0, bool)

    @property
    def n_tracks(self) -> int:
        """Tracks currently remembered."""
        return int(self._ids.size)

    def update(self, cands, pose: Optional[np.ndarray] = None):
        """Feed one scan's candidates; returns them with stable ids and ``confirmed`` set.

        Args:
            cands: this scan's candidates (lidar frame).
            pose: 4x4 odom <- lidar at the scan time, or None.

        Returns:
            The same rows with ``ids`` replaced by track ids and ``confirmed`` true where the
            track was seen in at least ``k`` of the last ``n`` scans (this one included).
        """
        c = cands.center
        if pose is not None:
            pos = c @ pose[:3, :3].T + pose[:3, 3]
            framed = True
        else:
            pos = c.copy()
            framed = False
        if self._framed.size and np.any(self._framed != framed):
            self.reset()                 # odometry appeared or vanished: frames differ
        gate = (self.gate if framed else self.gate_no_odom) + self.gate_k * cands.range
        t = self._ids.size
        assign = np.full(len(cands), -1, np.int64)
        if t and len(cands):
            d = np.linalg.norm(pos[:, None, :] - self._pos[None, :, :], axis=2)
            d[d > gate[:, None]] = np.inf
            order = np.argsort(d, axis=None)
            used_c, used_t = np.zeros(len(cands), bool), np.zeros(t, bool)
            for flat in order[: int(np.isfinite(d).sum())]:
                i, j = divmod(int(flat), t)
                if used_c[i] or used_t[j]:
                    continue
                assign[i], used_c[i], used_t[j] = j, True, True
        hist = np.zeros((t, self.n), bool)
        hist[:, :-1] = self._hist[:, 1:]
        matched = assign >= 0
        hist[assign[matched], -1] = True
        new_pos = self._pos.copy()
        new_pos[assign[matched]] = pos[matched]
        n_new = int((~matched).sum())
        new_ids = np.arange(self._next_id, self._next_id + n_new)
        self._next_id += n_new
        new_hist = np.zeros((n_new, self.n), bool)
        new_hist[:, -1] = True
        ids = np.empty(len(cands), np.int64)
        ids[matched] = self._ids[assign[matched]]
        ids[~matched] = new_ids
        self._pos = np.vstack([new_pos, pos[~matched]])
        self._hist = np.vstack([hist, new_hist])
        self._ids = np.concatenate([self._ids, new_ids])
        self._framed = np.full(self._ids.size, framed)
        alive = self._hist.any(axis=1)
        self._pos, self._hist, self._ids = self._pos[alive], self._hist[alive], \
            self._ids[alive]
        self._framed = self._framed[alive]
        hits = dict(zip(self._ids.tolist(), self._hist.sum(axis=1).tolist()))
        confirmed = np.array([hits.get(int(i), 0) >= self.k for i in ids], bool)
        out = replace(cands, ids=ids, confirmed=confirmed)
        return out
