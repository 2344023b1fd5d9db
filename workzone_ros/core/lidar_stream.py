"""The LiDAR candidate stage over a stream of scans, as the ``lidar_cluster`` node runs it.

One object holds what lives across scans: the intensity scale learned over the first scans
(:class:`~workzone_ros.core.lidar_intensity.IntensityScale`), the last plausible ground plane
(the fallback when a scan's road is hidden), the sensor's beam spacing (from the first
scans), persistence with stable ids
(:class:`~workzone_ros.core.lidar_persistence.CandidateTracker`), and the watch that warns
when nothing is bright enough.  Each scan returns its candidates and the lines to log, and
:meth:`LidarStream.status` says where the points of the last scan went and why nothing was
published (intensity, region, height, each check-to-add filter, or persistence), for
``/diagnostics`` and the evaluation tool.  The evaluation tool runs this same class, so its
figures are the node's.

No rclpy here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from workzone_ros.core.lidar_clustering import (
    REJECT_REASONS,
    Candidates,
    ClusterParams,
    ClusterResult,
    _column,
    cluster_cloud,
)
from workzone_ros.core.lidar_geometry import GroundPlane
from workzone_ros.core.lidar_intensity import IntensityScale, SilenceWatch
from workzone_ros.core.lidar_persistence import CandidateTracker

__all__ = ['LidarStream', 'ScanOutput']


@dataclass
class ScanOutput:
    """One scan through the stage.

    Attributes:
        result: the clustering of this scan (funnel, per-cluster reasons).
        candidates: this scan's candidates with track ids; ``confirmed`` rows are published.
        info: lines to log at info level (the intensity scale chosen, the first hold for
            persistence).
        warnings: lines to log at warning level (nothing bright for a while, a revised
            intensity encoding).
    """

    result: ClusterResult
    candidates: Candidates
    info: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def published(self) -> Candidates:
        """The rows persistence confirmed (what the node publishes)."""
        return self.candidates.subset(self.candidates.confirmed)


class LidarStream:
    """Clustering + persistence over scans, with the state a node keeps.

    Args:
        params: thresholds (``intensity_scale`` 0 learns the scale).
        k, n: persistence, seen in ``k`` of the last ``n`` scans.
        gate, gate_k, gate_no_odom: persistence match distances (see
            :class:`CandidateTracker`).
        silent_scans: warn after this many non-empty scans in a row with no bright point.
    """

    def __init__(self, params: ClusterParams = ClusterParams(), k: int = 2, n: int = 3,
                 gate: float = 1.0, gate_k: float = 0.01, gate_no_odom: float = 3.5,
                 silent_scans: int = 20) -> None:
        self.params = params
        self.tracker = CandidateTracker(k, n, gate, gate_k, gate_no_odom)
        self.scale = IntensityScale(params.intensity_scale)
        self.silence = SilenceWatch(silent_scans)
        self.ground: Optional[GroundPlane] = None
        self._spacings: list[float] = []      # the sensor's beam spacing, first scans
        self.top: Optional[float] = None        # highest elevation seen: top of the FOV
        self.scans = 0
        self.totals = {'scans': 0, 'candidates': 0, 'published': 0, 'held': 0, 'bright': 0,
                       'region': 0, 'height': 0, 'clusters': 0}
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.last: Optional[ScanOutput] = None
        self._told_hold = False

    def process(self, points: np.ndarray, pose: Optional[np.ndarray] = None) -> ScanOutput:
        """Run one scan.

        Args:
            points: structured cloud (x, y, z, intensity; more fields allowed).
            pose: 4x4 odom <- lidar at the scan time, or None (persistence in the lidar frame).

        Raises:
            LidarClusterError: a cloud without the fields the stage needs.
        """
        raw = _column(points, 'intensity')
        scale = self.scale.update(raw)
        beam = float(np.median(self._spacings)) if len(self._spacings) >= 3 else None
        res = cluster_cloud(points, self.params, intensity_scale=scale,
                            ground_prior=self.ground, beam=beam, top_elevation=self.top)
        if np.isfinite(res.top_elevation):
            self.top = res.top_elevation
        if res.ground.source == 'fit':
            self.ground = res.ground
        if beam is None and res.funnel.get('points'):
            self._spacings.append(res.beam_spacing)
        cands = self.tracker.update(res.candidates, pose)
        out = ScanOutput(res, cands)
        for line in self.scale.pop_messages():
            (out.warnings if 'revised' in line else out.info).append(line)
        warn = self.silence.update(res.funnel.get('points', 0), res.funnel.get('bright', 0),
                                   raw, scale, self.params.min_intensity)
        if warn:
            out.warnings.append(warn)
        held = int((~cands.confirmed).sum())
        if held and not cands.confirmed.any() and not self._told_hold:
            self._told_hold = True
            out.info.append(
                f'{held} candidate(s) held for persistence: a candidate is published once seen '
                f'in persistence_k={self.tracker.k} of the last persistence_n={self.tracker.n} '
                f'scans (persistence_k 1 publishes a single scan at once)')
        self.scans += 1
        t = self.totals
        t['scans'] += 1
        t['candidates'] += len(cands)
        t['published'] += int(cands.confirmed.sum())
        t['held'] += held
        for key in ('bright', 'region', 'height'):
            t[key] += res.funnel.get(key, 0)
        t['clusters'] += res.n_clusters
        for key, v in res.rejected.items():
            self.rejected[key] += v
        self.last = out
        return out

    def status(self) -> list[tuple[str, str]]:
        """``(key, value)`` lines for ``/diagnostics``: the last scan's funnel and reasons."""
        out = [('intensity scale', f'x{self.scale.scale:.6g}'
                + (f' ({self.scale.encoding})' if self.scale.encoding else ''))]
        if self.last is None:
            return out + [('last scan', 'none yet')]
        res, cands = self.last.result, self.last.candidates
        f = res.funnel
        held = int((~cands.confirmed).sum())
        out += [
            ('mounting', res.mount.describe() if res.mount else ''),
            ('road', res.ground.describe()),
            ('last scan points', str(f.get('points', 0))),
            ('last scan bright (>= min_intensity)', str(f.get('bright', 0))),
            ('last scan bright in region', str(f.get('region', 0))),
            ('last scan bright in height band', str(f.get('height', 0))),
            ('last scan clusters', str(res.n_clusters)),
            ('last scan rejected', ', '.join(f'{k} {v}' for k, v in res.rejected.items()
                                             if v) or 'none'),
            ('last scan candidates', str(len(cands))),
            ('last scan held for persistence', f'{held} (k={self.tracker.k} of '
                                               f'n={self.tracker.n})'),
            ('last scan published', str(int(cands.confirmed.sum()))),
            ('why nothing published', self.why_nothing()),
            ('scans', str(self.totals['scans'])),
            ('candidates published total', str(self.totals['published'])),
        ]
        return out

    def summary(self) -> str:
        """One line over all scans so far: where the bright points went, why clusters were
        rejected, how many candidates persistence held (for an evaluation report)."""
        t = self.totals
        rej = ', '.join(f'{k} {v}' for k, v in self.rejected.items() if v) or 'none'
        return (f'{t["scans"]} scans: bright points {t["bright"]}, in region {t["region"]}, in '
                f'height band {t["height"]}; {t["clusters"]} clusters, rejected: {rej}; '
                f'{t["candidates"]} candidates, {t["held"]} held for persistence, '
                f'{t["published"]} published')

    def why_nothing(self) -> str:
        """One line: why the last scan published nothing ('' when it published)."""
        if self.last is None:
            return 'no scan yet'
        cands = self.last.candidates
        if cands.confirmed.any():
            return ''
        if len(cands):
            return (f'{len(cands)} candidate(s) held for persistence (seen in fewer than '
                    f'{self.tracker.k} of the last {self.tracker.n} scans)')
        return self.last.result.why_empty()

