"""Identities for the colour proposals, published only once repeated.

The recall-first colour proposals (:mod:`workzone_ros.core.proposals`, ``Detection.proposal``)
are many per frame and most are not signs.  Mean-shift tracking them would multiply the false
ones (a one-frame blob on a brick wall would coast for seconds) and cost a histogram and a
search per blob.  Instead they are followed by box overlap alone:

* a proposal overlapping one of the previous frame's proposal tracks (IoU >= ``iou``) continues
  it, the best overlaps first;
* any other proposal starts a track;
* a track is published (as a ``detection`` track, with its own id) only while it has been
  proposed in at least ``min_hits`` of its last ``window`` frames, so a one-frame false blob
  never reaches the classifier as a track, and a real sign keeps one id for the fusion's vote;
* a track not proposed for ``max_misses`` frames ends, and so does one whose box grew to more
  than ``max_growth`` times its first size (a blob that merged with its surroundings).

The work is an IoU matrix of proposals x tracks per frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

__all__ = ['ProposalTrackConfig', 'ProposalTracks']

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class ProposalTrackConfig:
    """Parameters of :class:`ProposalTracks` (module docstring)."""

    iou: float = 0.3
    min_hits: int = 2
    window: int = 3
    max_misses: int = 2
    max_growth: float = 2.0

    def __post_init__(self) -> None:
        if not 0.0 < self.iou <= 1.0:
            raise ValueError(f'proposal track iou={self.iou} must lie in (0, 1]')
        if not 1 <= self.min_hits <= self.window:
            raise ValueError(f'proposal track min_hits={self.min_hits} must lie in '
                             f'[1, window={self.window}]')
        if self.max_misses < 0 or self.max_growth <= 1.0:
            raise ValueError('proposal track max_misses must be >= 0 and max_growth > 1')


@dataclass
class _PTrack:
    track_id: int
    box: Box
    first_side: float
    confidence: float
    age: int = 1
    hits: int = 1
    misses: int = 0
    recent: list[bool] = field(default_factory=lambda: [True])


def _iou_matrix(a: Sequence[Box], b: Sequence[Box]) -> np.ndarray:
    if not a or not b:
        return np.zeros((len(a), len(b)))
    A, B = np.asarray(a, float)[:, None, :], np.asarray(b, float)[None, :, :]
    x0 = np.maximum(A[..., 0], B[..., 0])
    y0 = np.maximum(A[..., 1], B[..., 1])
    x1 = np.minimum(A[..., 0] + A[..., 2], B[..., 0] + B[..., 2])
    y1 = np.minimum(A[..., 1] + A[..., 3], B[..., 1] + B[..., 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    union = A[..., 2] * A[..., 3] + B[..., 2] * B[..., 3] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-9), 0.0)


class ProposalTracks:
    """Box-overlap identities for proposals (module docstring)."""

    def __init__(self, config: ProposalTrackConfig = ProposalTrackConfig(),
                 new_id: Callable[[], int] | None = None) -> None:
        self.config = config
        self._tracks: list[_PTrack] = []
        self._count = 0
        self._new_id = new_id or self._own_id

    def _own_id(self) -> int:
        self._count += 1
        return self._count

    def reset(self) -> None:
        """Forget every track (a time jump)."""
        self._tracks = []

    def __len__(self) -> int:
        return len(self._tracks)

    def step(self, boxes: Sequence[Box], confidences: Sequence[float]
             ) -> list[tuple[int, Box, float, int, int]]:
        """One frame's proposals -> the published ones as
        (track_id, box, confidence, age, hits)."""
        cfg = self.config
        iou = _iou_matrix([t.box for t in self._tracks], list(boxes))
        matched_t: dict[int, int] = {}
        used: set[int] = set()
        for flat in np.argsort(-iou, axis=None):
            ti, di = np.unravel_index(flat, iou.shape)
            if iou[ti, di] < cfg.iou:
                break
            if ti in matched_t or di in used:
                continue
            matched_t[int(ti)] = int(di)
            used.add(int(di))
        kept: list[_PTrack] = []
        for ti, tr in enumerate(self._tracks):
            tr.age += 1
            di = matched_t.get(ti)
            tr.recent = (tr.recent + [di is not None])[-cfg.window:]
            if di is None:
                tr.misses += 1
                if tr.misses <= cfg.max_misses:
                    kept.append(tr)
                continue
            tr.box, tr.confidence = tuple(map(float, boxes[di])), float(confidences[di])
            tr.hits += 1
            tr.misses = 0
            if max(tr.box[2], tr.box[3]) <= cfg.max_growth * tr.first_side:
                kept.append(tr)
        for di, b in enumerate(boxes):
            if di not in used:
                b = tuple(map(float, b))
                kept.append(_PTrack(self._new_id(), b, max(b[2], b[3], 1.0),
                                    float(confidences[di])))
        self._tracks = kept
        return [(t.track_id, t.box, t.confidence, t.age, t.hits) for t in kept
                if t.misses == 0 and sum(t.recent) >= cfg.min_hits]
