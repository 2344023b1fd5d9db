"""LiDAR sign candidates: pre-filter, region growing, check-to-add filters (Cahail et al. s1.3).

Implements Cahail et al. section 1.3 (Velodyne sign detection) with its future work done, for any
sensor on any vehicle:

0. **Where the sensor is** (:mod:`workzone_ros.core.lidar_geometry`): the points are taken
   to the *level frame* with the mounting ``lidar_in_base`` (axes from its rotation, never an
   assumed convention; origin on the road under the sensor), and every height threshold is a
   height above the road: the mounting height, corrected per scan by a robust ground-plane
   fit where the ground is visible (slopes, pitch, a mounting height a few dm off).
   Intensities are brought to 0-255 units (:mod:`workzone_ros.core.lidar_intensity`: from
   the field's datatype and values, or ``intensity_scale``).
1. **Pre-clustering filter** (Cahail et al. s1.3): keep points that are bright enough
   (intensity), above the road paint (``min_point_height``), far enough and not too far
   (range band), ahead, and within ``right_max`` / ``left_max`` of the sensor (left-side
   signs included: medians and left-lane closures carry them).
2. **Clustering** (Cahail et al. s1.3): region growing, two points join when closer than
   ``d(r) = d0 + k * r`` (:mod:`workzone_ros.core.lidar_region_grow`: the connected
   components of that graph on a voxel grid, DBSCAN's partition for ``k = 0``).  On a sensor
   whose rings are further apart than ``d(r)`` (16 or 32 beams) heights are shrunk so the
   rings of one face join (:func:`_rings_closer`, from the ``ring`` field's beam spacing).
3. **Check-to-add filters** (Cahail et al. s1.3): a cluster is added only when it has enough points
   and its bounding box fits the sign sizes.  Beyond the seed (its s1.5 future work): the
   cluster's top must reach sign height (``min_top_height`` above the road); a pole test; a
   sign is *retroreflective*, not just bright: a thin plate (PCA flatness), vertical, facing
   the sensor (``max_incidence``: walls and fences along the road are seen edge-on), whose
   returns are far brighter than their own surroundings (``min_contrast``: the cluster's
   median intensity over the 90th percentile of the dull returns around it -- bright
   foliage, walls, painted poles and window frames sit among returns nearly as bright,
   a sign among a dull post, its own black legend, or nothing); not hollow (a truck's rear
   outlined with tape); no reflectors underneath (plates, tail lights, bumper tape).

   The seed's height band is a per-point pre-filter at sign height.  Temporary signs on
   portable stands start 0.3 m above the ground (MUTCD 6F.03), so a per-point band cuts
   their lower half.  We keep every bright point above the road paint, cluster, and apply
   the seed's height to the *cluster's top* (1.55 m above the road: above drums, cones,
   tubular markers, plates and car tail lights; a 36-in diamond on a stand reaches 1.6 m).

Each accepted cluster also carries its measured size for the camera ROI (``half_w``,
``half_h``: half its width across the line of sight and half its height, each plus one
beam spacing at its range, where the sign may extend unseen; 0 when the cluster lies on a
single ring and its height cannot be measured).  :class:`ClusterResult` says where the points
went (the funnel: bright, in the region, in the height band) and why each cluster was
rejected.  Persistence over scans is :mod:`workzone_ros.core.lidar_persistence`.

No rclpy here; the node ``nodes/lidar_cluster.py`` is a thin wrapper.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Optional

import numpy as np

from workzone_ros.core.knobs import knob
from workzone_ros.core.lidar_geometry import (
    GroundPlane,
    LidarGeometryError,
    Mount,
    beam_spacing,
    fit_ground,
)
from workzone_ros.core.lidar_intensity import ENCODINGS, finite_max, infer_encoding
from workzone_ros.core.lidar_measure import cluster_stats, contrast, rows, widest_row_gap
from workzone_ros.core.lidar_persistence import CandidateTracker, PersistenceError
from workzone_ros.core.lidar_region_grow import region_grow

__all__ = [
    'LidarClusterError', 'ClusterParams', 'Candidates', 'ClusterResult', 'Prefiltered',
    'prefilter', 'region_grow', 'cluster_cloud', 'CandidateTracker', 'PersistenceError',
    'REJECT_REASONS', 'CANDIDATE_DTYPE', 'SIZED_CANDIDATE_DTYPE', 'RENAMED',
    'candidates_to_array', 'scan_geometry', 'auto_scale',
]

REJECT_REASONS = ('few_points', 'too_large', 'too_small', 'too_low', 'too_thin', 'not_flat',
                  'not_vertical', 'not_facing', 'hollow', 'reflectors_below',
                  'not_retroreflective')

#: The candidate fields every consumer reads (x, y, z, radius, intensity, count, id).
CANDIDATE_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('radius', '<f4'),
                            ('intensity', '<f4'), ('count', '<u4'), ('id', '<u4')])
#: What ``lidar_cluster`` publishes: :data:`CANDIDATE_DTYPE` plus ``half_w`` / ``half_h``,
#: the measured half width (across the line of sight) and half height in metres, each with
#: one beam spacing added, and ``dz``, how far above the candidate the ROI's centre lies (a
#: face cut by the top of the sensor's field of view); all 0 when the cluster is too sparse
#: to measure (one ring): then size its ROI from ``radius`` with a minimum.
SIZED_CANDIDATE_DTYPE = np.dtype(CANDIDATE_DTYPE.descr + [('half_w', '<f4'),
                                                          ('half_h', '<f4'), ('dz', '<f4')])

#: Parameters that no longer exist, with what replaced them (one-line errors).
RENAMED = {
    'z_min': 'min_point_height (metres above the road, not lidar z: z_min - ground_z)',
    'z_max': 'max_point_height (metres above the road, not lidar z: z_max - ground_z)',
    'min_top': 'min_top_height (metres above the road, not lidar z: min_top - ground_z)',
    'ground_z': 'lidar_in_base (its z is the sensor height above the road) and ground_fit',
    'include_left': 'left_max (left-side signs are on by default; left_max 4 keeps only '
                    'the ego and next lane)',
    'center_left': 'left_max',
    'hollow_row': 'nothing: the hollow test compares the returns of each ring',
}

# Neighbourhood of the contrast test: the cluster's box grown by this much (plus per metre of
# range: the next ring up or down is further away).
_CONTRAST_MARGIN, _CONTRAST_MARGIN_K = 0.3, 0.01
# The largest work-zone sign face (a 48-in diamond is 1.72 m point to point), m: what may
# hide above the sensor's top ring.
_LARGEST_FACE = 1.8
# Ground-fit subsample of a scan (the fit uses at most this many points).
_GROUND_SAMPLE = 6000


class LidarClusterError(ValueError):
    """A cloud the clustering cannot use (no intensity field, bad parameters)."""


@dataclass(frozen=True)
class ClusterParams:
    """Every threshold of the LiDAR candidate stage.

    Positions are in the level frame (x forward, y left, from the sensor), heights are above
    the road, intensities in 0-255 units.  Each field is a
    :func:`~workzone_ros.core.knobs.knob`: its one-line description and range there are the
    ``lidar_cluster`` node parameter's.

    Attributes:
        min_intensity: pre-filter, intensity at least this, 0-255 units (retroreflective
            sheeting returns ~200-250, paint and car bodies < 100).
        intensity_scale: raw intensity -> 0-255 units; 0 infers it from the field's datatype
            and values (0-1 float x 255, 0-255 x 1, 0-65535 x 255/65535).
        lidar_in_base: the sensor in base_link (on the road): x y z roll pitch yaw, metres
            and radians; z is the mounting height, the rotation gives the axes.
        ground_fit: correct the road under the sensor per scan by a plane fit where the
            ground is visible (else the mounting alone).
        min_point_height, max_point_height: pre-filter height band above the road, per
            point (the default keeps everything above the lane paint, see ``min_top_height``).
        min_top_height: check-to-add, the cluster's top must reach this height above the
            road: sign height, above drums, cones, plates and tail lights.
        thin_height, max_aspect: a cluster taller than ``thin_height`` and more than
            ``max_aspect`` times taller than wide is a pole or post, not a sign face.
        range_min, range_max: pre-filter range band, metres (horizontal, from the sensor).
        x_min: pre-filter, only points at least this far ahead.
        right_max, left_max: pre-filter, how far right / left of the sensor the region
            reaches (``left_max`` 4 keeps only signs over the ego and next lane).
        cluster_d0, cluster_k: region-growing threshold ``d(r) = d0 + k r`` (Cahail et al. s1.3's
            dynamic distance threshold).
        min_points: check-to-add, at least this many points.
        max_width: check-to-add, horizontal bounding-box diagonal at most this (guide boards
            are the widest signs).
        max_height: check-to-add, vertical extent at most this.
        min_size: check-to-add, the largest bbox extent at least this.
        flat_min_points: the plate tests (flatness, vertical, facing) need at least this many
            points and a planar spread (second PCA axis) of ``flat_min_spread``; sparser
            clusters (one ring at long range) pass them untested.
        flat_min_spread: second-axis standard deviation that makes the tests meaningful.
        flat_thickness, flat_thickness_k: the plate thickness (third-axis standard
            deviation) must be at most ``flat_thickness + flat_thickness_k * range``.
        max_normal_z: a sign is a vertical plate: |normal z| at most this.
        max_incidence: a sign faces the sensor: the angle between its normal and the line
            of sight at most this, degrees (retroreflection fades beyond ~60-70 deg).
        min_contrast: retroreflective, not just bright: the cluster's median intensity must
            be at least this many times the 90th percentile of the dull returns around it
            (when there are at least 5 of them); 0 disables.
        hollow_gap, hollow_gap_k, hollow_frac: the hollow test rejects a cluster when one
            ring of returns has an inner horizontal gap wider
            than both ``hollow_gap + hollow_gap_k * range`` and ``hollow_frac`` of the
            cluster's width (a tape outline; a filled face has only beam-spacing gaps).
            ``hollow_frac`` >= 1 disables the test.
        below_clearance: bright returns lower than this above the road (lane paint) are
            ignored by the reflectors-underneath test.
        below_margin: footprint margin of the reflectors-underneath test, metres.
        below_gap: a bright return counts as underneath when it is at least this much lower
            than the cluster's lowest point and not part of the cluster.
        max_bright_below: reject a cluster with more bright returns than this underneath it
            (set < 0 to disable).
        voxel: voxel side for the graph; 0 means ``d0 / sqrt(3)`` (the exactness bound).
    """

    min_intensity: float = knob(
        120.0, 'pre-filter: minimum intensity, 0-255 units (after intensity_scale)', min=0.0,
        max=255.0)
    intensity_scale: float = knob(
        0.0, 'raw intensity -> 0-255 units; 0 = learned from the datatype and values (0-1 float '
        'x255, 0-255 x1, 0-65535 x255/65535)', min=0.0, max=1e6)
    lidar_in_base: tuple = knob(
        (1.0, 0.0, 1.95, 0.0, 0.0, 0.0), 'the sensor in base_link (on the road, x forward, y '
        'left, z up): x y z roll pitch yaw, m and rad; z = height above the road, the rotation '
        'gives the axes (x right / y forward: yaw -1.5708)')
    ground_fit: bool = knob(
        True, 'fit the road plane per scan where it is visible (slopes, pitch)')
    min_point_height: float = knob(
        0.25, 'pre-filter: lowest point height above the road, m', min=-5.0, max=20.0)
    max_point_height: float = knob(
        10.0, 'pre-filter: highest point height above the road, m', min=-5.0, max=50.0)
    min_top_height: float = knob(
        1.55, 'check-to-add: the cluster top must reach this height above the road (sign height), '
        'm', min=-5.0, max=50.0)
    thin_height: float = knob(
        0.4, 'check-to-add: clusters taller than this are tested for poles, m', min=0.0, max=100.0)
    max_aspect: float = knob(
        4.0, 'check-to-add: a pole is taller than max_aspect x its width', min=0.0, max=1000.0)
    range_min: float = knob(3.0, 'pre-filter: nearest horizontal range, m', min=0.0, max=500.0)
    range_max: float = knob(110.0, 'pre-filter: farthest horizontal range, m', min=0.0, max=500.0)
    x_min: float = knob(
        1.0, 'pre-filter: only points at least this far ahead, m', min=-500.0, max=500.0)
    right_max: float = knob(
        25.0, 'pre-filter: reach of the region to the right, m', min=0.0, max=500.0)
    left_max: float = knob(
        25.0, 'pre-filter: reach of the region to the left, m (4 = ego and next lane only)',
        min=0.0, max=500.0)
    cluster_d0: float = knob(
        0.3, 'region growing: distance threshold at range 0, m', min=0.01, max=10.0)
    cluster_k: float = knob(
        0.012, 'region growing: threshold growth per metre of range', min=0.0, max=1.0)
    min_points: int = knob(3, 'check-to-add: minimum points per cluster', min=1, max=100000)
    max_width: float = knob(
        5.0, 'check-to-add: maximum horizontal bbox diagonal, m', min=0.0, max=100.0)
    max_height: float = knob(3.5, 'check-to-add: maximum vertical extent, m', min=0.0, max=100.0)
    min_size: float = knob(
        0.05, 'check-to-add: minimum of the largest extent, m', min=0.0, max=100.0)
    flat_min_points: int = knob(8, 'plate tests: points needed to test', min=3, max=100000)
    flat_min_spread: float = knob(
        0.12, 'plate tests: second PCA axis std needed to test, m', min=0.0, max=10.0)
    flat_thickness: float = knob(
        0.06, 'flatness: max plate thickness (third-axis std) at range 0, m', min=0.0, max=10.0)
    flat_thickness_k: float = knob(
        0.002, 'flatness: thickness allowance per metre of range', min=0.0, max=1.0)
    max_normal_z: float = knob(
        0.6, 'flatness: max |normal z| of a (vertical) sign plate', min=0.0, max=1.0)
    max_incidence: float = knob(
        85.0, 'facing: max angle between the plate normal and the line of sight, deg', min=1.0,
        max=90.0)
    min_contrast: float = knob(
        1.8, 'retroreflective: median intensity / p90 of the dull returns around the cluster at '
        'least this (0 disables)', min=0.0, max=100.0)
    hollow_gap: float = knob(
        0.6, 'hollow test: widest inner gap in a ring at range 0, m', min=0.0, max=100.0)
    hollow_gap_k: float = knob(
        0.01, 'hollow test: gap growth per metre of range', min=0.0, max=1.0)
    hollow_frac: float = knob(
        0.5, 'hollow test: gap must also exceed this fraction of the width (>= 1 disables)',
        min=0.0, max=10.0)
    below_clearance: float = knob(
        0.25, 'reflectors test: ignore bright returns this close to the road, m', min=0.0,
        max=10.0)
    below_margin: float = knob(0.4, 'reflectors test: footprint margin, m', min=0.0, max=10.0)
    below_gap: float = knob(
        0.1, 'reflectors test: counted only this far below the cluster bottom, m', min=0.0,
        max=10.0)
    max_bright_below: int = knob(
        2, 'reflectors test: reject with more bright returns under the cluster (-1 disables)',
        min=-1, max=100000)
    voxel: float = knob(
        0.0, 'voxel side of the clustering graph (0 = d0/sqrt(3))', min=0.0, max=10.0)

    def __post_init__(self) -> None:
        """Reject inconsistent thresholds with a one-line message naming them."""
        try:
            Mount.from_list(self.lidar_in_base)
        except LidarGeometryError as exc:
            raise LidarClusterError(str(exc)) from None
        object.__setattr__(self, 'lidar_in_base', tuple(float(v) for v in self.lidar_in_base))
        if not self.min_point_height < self.max_point_height:
            raise LidarClusterError(f'min_point_height ({self.min_point_height}) must be below '
                                    f'max_point_height ({self.max_point_height})')
        if not 0 <= self.range_min < self.range_max:
            raise LidarClusterError(f'need 0 <= range_min ({self.range_min}) < range_max '
                                    f'({self.range_max})')
        if self.cluster_d0 <= 0 or self.cluster_k < 0:
            raise LidarClusterError('need cluster_d0 > 0 and cluster_k >= 0')
        if self.min_points < 1:
            raise LidarClusterError('min_points must be at least 1')
        if self.intensity_scale < 0 or not math.isfinite(self.intensity_scale):
            raise LidarClusterError(f'intensity_scale must be 0 (auto) or a factor > 0, got '
                                    f'{self.intensity_scale}')
        if not 0 < self.max_incidence <= 90:
            raise LidarClusterError(f'max_incidence must be in (0, 90] degrees, got '
                                    f'{self.max_incidence}')
        if self.min_contrast < 0:
            raise LidarClusterError(f'min_contrast must be >= 0 (0 disables), got '
                                    f'{self.min_contrast}')
        if self.right_max < 0 or self.left_max < 0:
            raise LidarClusterError('right_max and left_max must be >= 0 (distances from the '
                                    'sensor to the right and to the left)')

    @classmethod
    def from_mapping(cls, values: dict) -> 'ClusterParams':
        """Build from a dict, ignoring keys that are not thresholds (e.g. topic names).

        Raises:
            LidarClusterError: a parameter that no longer exists (see :data:`RENAMED`).
        """
        old = [k for k in values if k in RENAMED]
        if old:
            raise LidarClusterError('; '.join(f'{k} no longer exists: use {RENAMED[k]}'
                                              for k in old))
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in values.items() if k in names})

    def with_(self, **changes) -> 'ClusterParams':
        """A copy with some thresholds changed."""
        return replace(self, **changes)

    @property
    def mount(self) -> Mount:
        """The sensor's mounting (``lidar_in_base``)."""
        return Mount.from_list(self.lidar_in_base)


@dataclass
class Candidates:
    """Per-cluster results, one row per accepted cluster (all arrays share the length M).

    Attributes:
        center: (M, 3) bounding-box centres in the lidar frame.
        radius: (M,) half the bounding-box diagonal, metres.
        intensity: (M,) mean intensity, 0-255 units.
        count: (M,) points in the cluster.
        extent: (M, 3) bounding-box size in the level frame (x forward, y left, z up).
        ids: (M,) candidate ids (cluster index before tracking; stable track ids after).
        confirmed: (M,) persistence satisfied (all True before tracking).
        cluster: (M,) index of the cluster in ``ClusterResult.labels``.
        half_size: (M, 3) measured half width (across the line of sight), half height (each
            plus one beam spacing at the cluster's range) and how far the box centre lies above
            the bounding-box centre (a face cut by the top of the sensor's field of view goes
            on above it), metres; 0 when not measurable (a single ring).
        rows: (M,) rings (rows of returns) the cluster spans.
    """

    center: np.ndarray
    radius: np.ndarray
    intensity: np.ndarray
    count: np.ndarray
    extent: np.ndarray
    ids: np.ndarray
    confirmed: np.ndarray
    cluster: np.ndarray
    half_size: Optional[np.ndarray] = None
    rows: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        m = len(self.radius)
        if self.half_size is None:
            self.half_size = np.zeros((m, 3))
        if self.rows is None:
            self.rows = np.zeros(m, np.int64)

    @classmethod
    def empty(cls) -> 'Candidates':
        """No candidates."""
        z = np.zeros(0)
        return cls(np.zeros((0, 3)), z, z.copy(), np.zeros(0, np.int64), np.zeros((0, 3)),
                   np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, np.int64))

    def __len__(self) -> int:
        return int(self.radius.shape[0])

    def subset(self, mask: np.ndarray) -> 'Candidates':
        """The rows where ``mask`` holds."""
        return Candidates(*(getattr(self, f.name)[mask] for f in fields(self)))

    @property
    def range(self) -> np.ndarray:
        """Horizontal range of each centre."""
        return np.hypot(self.center[:, 0], self.center[:, 1])


@dataclass
class ClusterResult:
    """Output of :func:`cluster_cloud`.

    Attributes:
        candidates: the accepted clusters (check-to-add passed).
        points: (N, 3) pre-filtered points in the lidar frame (float64).
        intensity: (N,) their intensities, 0-255 units.
        index: (N,) their indices in the input cloud.
        labels: (N,) cluster label per pre-filtered point (-1 none).
        n_clusters: clusters before the filters.
        rejected: reason -> number of clusters rejected for it.
        reason: (n_clusters,) index into :data:`REJECT_REASONS` of the first filter that
            rejected each cluster, -1 for accepted clusters (for diagnostics and RViz).
        funnel: points in the cloud, bright enough, in the region, in the height band.
        clusters: per cluster (n_clusters rows): 'center' (lidar frame), 'count', 'top'
            (height above the road), 'width', 'height', 'intensity', 'contrast' and
            'incidence' (NaN where not measured) -- what a user reads to see why.
        scale: the intensity factor used (raw -> 0-255 units).
        ground: the road used for the heights.
        mount: the sensor's mounting.
        beam_spacing: the sensor's vertical beam spacing, rad (NaN: no ring field).
        top_elevation: the top of the sensor's field of view as far as seen, rad.
    """

    candidates: Candidates
    points: np.ndarray
    intensity: np.ndarray
    index: np.ndarray
    labels: np.ndarray
    n_clusters: int = 0
    rejected: dict = field(default_factory=dict)
    reason: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    funnel: dict = field(default_factory=dict)
    clusters: dict = field(default_factory=dict)
    scale: float = 1.0
    ground: GroundPlane = field(default_factory=GroundPlane)
    mount: Optional[Mount] = None
    beam_spacing: float = float('nan')
    top_elevation: float = float('nan')

    def clustered_mask(self) -> np.ndarray:
        """Mask over ``points`` of the points of accepted clusters."""
        keep = np.zeros(self.n_clusters + 1, bool)
        keep[self.candidates.cluster] = True
        return keep[np.where(self.labels >= 0, self.labels, self.n_clusters)]

    def why_empty(self) -> str:
        """One line saying where the points went when there is no candidate ('' otherwise)."""
        if len(self.candidates):
            return ''
        f = self.funnel
        if not f.get('points'):
            return 'empty cloud'
        if not f.get('bright'):
            return (f'no point reached min_intensity (of {f["points"]} points; intensity '
                    f'scale x{self.scale:.6g})')
        if not f.get('region'):
            return f'{f["bright"]} bright points, none in the region (ahead, range, left/right)'
        if not f.get('height'):
            return (f'{f["region"]} bright points in the region, none in the height band '
                    f'({self.ground.describe()})')
        why = ', '.join(f'{v} {k}' for k, v in self.rejected.items() if v)
        return f'{self.n_clusters} clusters, all rejected: {why}'


def _column(points: np.ndarray, name: str) -> np.ndarray:
    if points.dtype.names is None or name not in points.dtype.names:
        have = ', '.join(points.dtype.names or ()) or 'none'
        what = 'an intensity' if name == 'intensity' else f'a {name}'
        raise LidarClusterError(f'point cloud has no {name!r} field (fields: {have}); '
                                f'sign candidates need {what} field')
    column = points[name]
    if column.ndim != 1:
        raise LidarClusterError(f'point cloud field {name!r} has {column.shape[1]} values per '
                                f'point; it must have one')
    return column


def scan_geometry(points: np.ndarray, params: ClusterParams,
                  ground_prior: Optional[GroundPlane] = None,
                  spacing: Optional[float] = None) -> tuple[Mount, GroundPlane, float, float]:
    """The mounting, this scan's road (a plane fit on a subsample when ``ground_fit``), the
    sensor's beam spacing in radians (``spacing`` when given, else estimated; NaN without a
    ``ring`` field) and the highest elevation seen in the subsample (the top of the sensor's
    field of view, as far as this scan shows it), radians."""
    mount = params.mount
    if points.shape[0] == 0:
        return mount, ground_prior or GroundPlane(), float('nan'), float('nan')
    step = max(1, points.shape[0] // _GROUND_SAMPLE)
    sub = np.column_stack([_column(points, c)[::step] for c in 'xyz'])
    if spacing is None:
        rings = points['ring'][::step] if 'ring' in (points.dtype.names or ()) else None
        spacing = beam_spacing(sub, rings)
    el = np.arctan2(sub[:, 2], np.hypot(sub[:, 0], sub[:, 1]))
    top = float(np.fmax.reduce(el)) if el.size else float('nan')
    if not params.ground_fit:
        return mount, ground_prior or GroundPlane(), spacing, top
    return mount, fit_ground(mount.to_level(sub), ground_prior), spacing, top


def auto_scale(inten: np.ndarray) -> float:
    """The 0-255 factor of one scan's intensity column, from its datatype and values."""
    return ENCODINGS[infer_encoding(inten.dtype, finite_max(inten))].scale


@dataclass
class Prefiltered:
    """Output of :func:`prefilter`: the bright points in the band, and what the band cut.

    Attributes:
        xyz: (N, 3) lidar frame.  level: (N, 3) level frame.  height: (N,) above the road.
        intensity: (N,) 0-255 units.  index: (N,) indices in the cloud.
        below_level, below_height: bright points of the region under the band (for the
            reflectors-underneath test).
        funnel: counts (points, bright, region, height).
    """

    xyz: np.ndarray
    level: np.ndarray
    height: np.ndarray
    intensity: np.ndarray
    index: np.ndarray
    below_level: np.ndarray
    below_height: np.ndarray
    funnel: dict


def prefilter(points: np.ndarray, params: ClusterParams, scale: float, mount: Mount,
              ground: GroundPlane) -> Prefiltered:
    """Cahail et al. s1.3 pre-clustering filter, vectorised over a structured cloud.

    The intensity test runs first over the whole cloud on the field view (no copy); the
    other tests run on the few bright survivors, in the level frame.

    Args:
        points: structured array with x, y, z and intensity (any float/int types).
        params: thresholds.
        scale: raw intensity -> 0-255 units.
        mount, ground: the sensor's mounting and the road (see :func:`scan_geometry`).

    Raises:
        LidarClusterError: a missing x, y, z or intensity field.
    """
    inten = _column(points, 'intensity')
    xs, ys, zs = (_column(points, c) for c in 'xyz')
    idx = np.flatnonzero(inten >= params.min_intensity / scale)      # NaN compares False
    xyz = np.column_stack([xs[idx], ys[idx], zs[idx]]).astype(np.float64)
    lvl = mount.to_level(xyz)
    hgt = ground.height(lvl)
    rng = np.hypot(lvl[:, 0], lvl[:, 1])
    region = ((lvl[:, 0] >= params.x_min) & (lvl[:, 1] >= -params.right_max)
              & (lvl[:, 1] <= params.left_max) & (rng >= params.range_min)
              & (rng <= params.range_max) & np.isfinite(hgt))
    band = region & (hgt >= params.min_point_height) & (hgt <= params.max_point_height)
    below = region & (hgt < params.min_point_height) & (hgt >= params.below_clearance)
    funnel = {'points': int(points.shape[0]), 'bright': int(idx.size),
              'region': int(region.sum()), 'height': int(band.sum())}
    return Prefiltered(xyz[band], lvl[band], hgt[band],
                       inten[idx[band]].astype(np.float64) * scale, idx[band], lvl[below],
                       hgt[below], funnel)


def _rings_closer(lvl: np.ndarray, params: ClusterParams, spacing: float) -> np.ndarray:
    """Level-frame points with heights shrunk so that adjacent rings of one face join.

    Region growing joins points closer than ``d(r) = d0 + k r``; on a sensor whose rings are
    further apart than that (a VLP-16's 2 deg is 1 m at 30 m), a sign face breaks into one
    cluster per ring, and each ring sees the one below as reflectors underneath.  Vertical
    distances are therefore scaled by ``d(r) / (d0 + kv r)`` with ``kv`` 1.25 beam spacings:
    adjacent rings join, a gap of two rings does not.  A no-op on dense sensors (HDL-64E:
    ``kv`` < ``k``) and when the spacing is unknown.
    """
    kv = 1.25 * spacing
    if not np.isfinite(kv) or kv <= params.cluster_k:
        return lvl
    r = np.hypot(lvl[:, 0], lvl[:, 1])
    out = lvl.copy()
    out[:, 2] *= (params.cluster_d0 + params.cluster_k * r) / (params.cluster_d0 + kv * r)
    return out


class _Rejector:
    """Which clusters are still accepted, the first filter that rejected each, and counts."""

    def __init__(self, n: int, rejected: dict) -> None:
        self.ok = np.ones(n, bool)
        self.why = np.full(n, -1, np.int64)
        self.rejected = rejected

    def __call__(self, mask: np.ndarray, reason: str) -> None:
        hit = self.ok & mask
        self.rejected[reason] = int(hit.sum())
        self.why[hit] = REJECT_REASONS.index(reason)
        self.ok = self.ok & ~mask


@dataclass
class _ClusterGeometry:
    """Per-cluster measurements of one scan's clusters (n rows), level frame."""

    lvl: np.ndarray
    hgt: np.ndarray
    labels: np.ndarray
    n: int
    lo: np.ndarray
    hi: np.ndarray
    mi: np.ndarray
    counts: np.ndarray
    cov: np.ndarray
    order: np.ndarray
    start: np.ndarray
    top: np.ndarray
    bottom: np.ndarray
    ext: np.ndarray
    center: np.ndarray
    rng: np.ndarray
    los: np.ndarray
    row_key: np.ndarray
    n_rows: np.ndarray
    el_hi: np.ndarray
    beam_m: np.ndarray
    width: np.ndarray


def _cluster_geometry(points: np.ndarray, pf: Prefiltered, labels: np.ndarray, n: int,
                      mount: Mount) -> _ClusterGeometry:
    """Bounding boxes, heights, rows and line of sight of the ``n`` clusters in ``labels``."""
    lvl, hgt = pf.level, pf.height
    lo, hi, mean, mi, counts, cov, order, start = cluster_stats(lvl, pf.intensity, labels, n)
    top = np.maximum.reduceat(hgt[order], start)
    bottom = np.minimum.reduceat(hgt[order], start)
    ext = hi - lo
    center = 0.5 * (lo + hi)
    rng = np.hypot(center[:, 0], center[:, 1])
    los = mean - np.array([0.0, 0.0, mount.height])           # sensor -> cluster
    dist = np.linalg.norm(los, axis=1)
    rings = points['ring'] if 'ring' in (points.dtype.names or ()) else None
    row_key, n_rows, spacing, el_hi = rows(pf.xyz, labels, n,
                                           None if rings is None else rings[pf.index])
    # One beam spacing at the cluster's range: how far the face may extend beyond its
    # outermost rows unseen (0 on a single row: unknown).
    beam_m = np.nan_to_num(spacing * dist)
    width = np.hypot(ext[:, 0], ext[:, 1])
    return _ClusterGeometry(lvl, hgt, labels, n, lo, hi, mi, counts, cov, order, start, top,
                            bottom, ext, center, rng, los, row_key, n_rows, el_hi, beam_m,
                            width)


def _reject_by_shape(g: _ClusterGeometry, params: ClusterParams,
                     reject: _Rejector) -> np.ndarray:
    """Check-to-add on size, height, shape and flatness; returns the incidence angles, deg
    (NaN where not measured)."""
    counts, ext, width = g.counts, g.ext, g.width
    # Check-to-add (Cahail et al. s1.3): point count, bounding box within sign sizes.
    reject(counts < params.min_points, 'few_points')
    reject((width > params.max_width) | (ext[:, 2] > params.max_height), 'too_large')
    reject(np.maximum(width, ext[:, 2]) < params.min_size, 'too_small')
    # Height on the cluster: its top must reach sign height (drums, cones, plates do not).
    # The face's top lies between the highest row and the next, on average half a beam
    # spacing above the highest row (at 85 m on a 64-beam sensor, 0.3 m).
    reject(g.top + 0.5 * g.beam_m < params.min_top_height, 'too_low')
    # A pole: tall and narrow over 3+ rings (two rings of a sparse sensor across a diamond's
    # tip are one beam spacing apart, not a measured height).
    reject((ext[:, 2] > params.thin_height) & (ext[:, 2] > params.max_aspect * width)
           & (g.n_rows >= 3), 'too_thin')
    # A thin vertical plate facing the sensor (Cahail et al. s1.5 future work): PCA, ascending.
    evals, evecs = np.linalg.eigh(g.cov)
    evals = np.maximum(evals, 0.0)
    testable = (counts >= params.flat_min_points) & \
        (np.sqrt(evals[:, 1]) >= params.flat_min_spread)
    thick = np.sqrt(evals[:, 0])
    reject(testable & (thick > params.flat_thickness + params.flat_thickness_k * g.rng),
           'not_flat')
    normal = evecs[:, :, 0]
    reject(testable & (np.abs(normal[:, 2]) > params.max_normal_z), 'not_vertical')
    los = g.los
    cos_i = np.abs((normal * los).sum(axis=1)) / np.maximum(np.linalg.norm(los, axis=1), 1e-9)
    incidence = np.where(testable, np.degrees(np.arccos(np.clip(cos_i, 0.0, 1.0))), np.nan)
    reject(testable & (incidence > params.max_incidence), 'not_facing')
    return incidence


def _reject_hollow(g: _ClusterGeometry, params: ClusterParams, reject: _Rejector) -> None:
    """Reject accepted clusters with a gap within a row wider than a sign face has."""
    if params.hollow_frac < 1.0 and reject.ok.any():
        hollow = np.zeros(g.n, bool)
        for c in np.flatnonzero(reject.ok):
            sel = g.order[g.start[c]:g.start[c] + g.counts[c]]
            hollow[c] = widest_row_gap(g.lvl[sel], g.row_key[sel]) > max(
                params.hollow_gap + params.hollow_gap_k * g.rng[c],
                params.hollow_frac * g.width[c])
        reject(hollow, 'hollow')


def _reject_reflectors_below(g: _ClusterGeometry, pf: Prefiltered, params: ClusterParams,
                             reject: _Rejector) -> None:
    """Reflectors underneath (plates, tail reflectors, bumper tape): bright returns below the
    cluster's footprint that are not part of it (under the band, or other clusters)."""
    if params.max_bright_below >= 0 and reject.ok.any():
        lo, hi = g.lo, g.hi
        idx = np.flatnonzero(reject.ok)
        m = params.below_margin
        pool = np.vstack([g.lvl, pf.below_level])
        pool_h = np.concatenate([g.hgt, pf.below_height])
        plab = np.concatenate([g.labels, np.full(pf.below_level.shape[0], -1)])
        inside = ((pool[None, :, 0] >= lo[idx, 0, None] - m)
                  & (pool[None, :, 0] <= hi[idx, 0, None] + m)
                  & (pool[None, :, 1] >= lo[idx, 1, None] - m)
                  & (pool[None, :, 1] <= hi[idx, 1, None] + m)
                  & (pool_h[None, :] <= g.bottom[idx, None] - params.below_gap)
                  & (pool_h[None, :] >= params.below_clearance)
                  & (plab[None, :] != idx[:, None]))
        bad = np.zeros(g.n, bool)
        bad[idx] = inside.sum(axis=1) > params.max_bright_below
        reject(bad, 'reflectors_below')


def _reject_dull(points: np.ndarray, g: _ClusterGeometry, pf: Prefiltered,
                 params: ClusterParams, scale: float, reject: _Rejector) -> np.ndarray:
    """Retroreflective, not just bright: far brighter than the dull returns around it.
    Returns the contrast ratio per cluster (NaN where not measured)."""
    ratio = np.full(g.n, np.nan)
    if params.min_contrast > 0 and reject.ok.any():
        order, start, counts = g.order, g.start, g.counts
        idx = np.flatnonzero(reject.ok)
        sx = pf.xyz[order]
        llo = np.minimum.reduceat(sx, start, axis=0)[idx]
        lhi = np.maximum.reduceat(sx, start, axis=0)[idx]
        sraw = pf.intensity[order] / scale
        med = np.array([np.median(sraw[start[c]:start[c] + counts[c]]) for c in idx])
        ratio[idx] = contrast(points, params.min_intensity / scale, llo, lhi,
                              _CONTRAST_MARGIN + _CONTRAST_MARGIN_K * g.rng[idx], med)
        reject(np.nan_to_num(ratio, nan=np.inf) < params.min_contrast,
               'not_retroreflective')
    return ratio


def _half_sizes(g: _ClusterGeometry, keep: np.ndarray, sensor_spacing: float,
                top_el: float) -> np.ndarray:
    """(len(keep), 3) measured half width, half height and box offset above the bounding-box
    centre of the kept clusters (see :attr:`Candidates.half_size`)."""
    center, ext, beam_m, n_rows = g.center, g.ext, g.beam_m, g.n_rows
    half = np.zeros((keep.size, 3))
    # A face reaching the sensor's top ring may go on above it, unseen (a sign close by,
    # above a 64-beam sensor's +2 deg): the box grows upwards to the largest face.
    edge = max(0.5 * np.nan_to_num(sensor_spacing), math.radians(0.1))
    cut = g.el_hi >= top_el - edge if np.isfinite(top_el) else np.zeros(g.n, bool)
    for j, c in enumerate(keep):
        if n_rows[c] >= 2:
            az = math.atan2(center[c, 1], center[c, 0])
            across = g.lvl[g.order[g.start[c]:g.start[c] + g.counts[c]], :2] @ np.array(
                [-math.sin(az), math.cos(az)])
            hw, hh = 0.5 * np.ptp(across) + beam_m[c], 0.5 * ext[c, 2] + beam_m[c]
            up = max(_LARGEST_FACE - ext[c, 2], beam_m[c]) if cut[c] else 0.0
            if cut[c]:
                hw = max(hw, 0.5 * _LARGEST_FACE)
            half[j] = (hw, hh + 0.5 * up, 0.5 * up)
    return half


def _candidates(g: _ClusterGeometry, keep: np.ndarray, center_lidar: np.ndarray,
                half: np.ndarray) -> Candidates:
    """The kept clusters as :class:`Candidates` (ids are cluster indices)."""
    ext, counts, n_rows = g.ext, g.counts, g.n_rows
    return Candidates(
        center=center_lidar[keep], radius=0.5 * np.linalg.norm(ext[keep], axis=1),
        intensity=g.mi[keep], count=counts[keep].astype(np.int64), extent=ext[keep],
        ids=keep.astype(np.int64), confirmed=np.ones(keep.size, bool),
        cluster=keep.astype(np.int64), half_size=half, rows=n_rows[keep])


def cluster_cloud(points: np.ndarray, params: ClusterParams = ClusterParams(), *,
                  intensity_scale: Optional[float] = None,
                  ground_prior: Optional[GroundPlane] = None,
                  beam: Optional[float] = None,
                  top_elevation: Optional[float] = None) -> ClusterResult:
    """Pre-filter, cluster and check-to-add one scan (Cahail et al. s1.3 steps 1-3).

    Args:
        points: structured cloud with x, y, z, intensity (more fields allowed, NaN allowed; a
            ``ring`` field is used to count rows).
        params: thresholds.
        intensity_scale: raw -> 0-255 factor (a node's learned one); None uses
            ``params.intensity_scale``, or infers it from this scan when that is 0.
        ground_prior: the road to fall back on when this scan's ground fit is not plausible.
        beam: the sensor's vertical beam spacing, rad (a node's from its first scans); None
            estimates it from this scan's ``ring`` field.
        top_elevation: the top of the sensor's vertical field of view, rad (a node's highest
            elevation seen so far); None takes this scan's.

    Returns:
        The candidates (ids are cluster indices; run :class:`CandidateTracker` for
        persistence and stable ids), the per-point labels and why clusters were rejected.

    Raises:
        LidarClusterError: the cloud has no x, y, z or intensity field.
    """
    raw = _column(points, 'intensity')
    scale = float(intensity_scale or params.intensity_scale or auto_scale(raw))
    mount, ground, sensor_spacing, top_el = scan_geometry(points, params, ground_prior, beam)
    if top_elevation is not None and np.isfinite(top_elevation):
        top_el = max(top_el, top_elevation) if np.isfinite(top_el) else top_elevation
    pf = prefilter(points, params, scale, mount, ground)
    rejected = dict.fromkeys(REJECT_REASONS, 0)
    extra = dict(funnel=pf.funnel, scale=scale, ground=ground, mount=mount,
                 beam_spacing=sensor_spacing, top_elevation=top_el)
    if pf.xyz.shape[0] == 0:
        return ClusterResult(Candidates.empty(), pf.xyz, pf.intensity, pf.index,
                             np.zeros(0, np.int64), 0, rejected, **extra)
    labels = region_grow(_rings_closer(pf.level, params, sensor_spacing), params.cluster_d0,
                         params.cluster_k, params.voxel)
    n = int(labels.max()) + 1
    g = _cluster_geometry(points, pf, labels, n, mount)
    reject = _Rejector(n, rejected)
    incidence = _reject_by_shape(g, params, reject)
    _reject_hollow(g, params, reject)
    _reject_reflectors_below(g, pf, params, reject)
    ratio = _reject_dull(points, g, pf, params, scale, reject)
    keep = np.flatnonzero(reject.ok)
    center_lidar = mount.to_lidar(g.center)
    cands = _candidates(g, keep, center_lidar, _half_sizes(g, keep, sensor_spacing, top_el))
    table = {'center': center_lidar, 'count': g.counts, 'rows': g.n_rows, 'top': g.top,
             'width': g.width, 'height': g.ext[:, 2], 'intensity': g.mi, 'contrast': ratio,
             'incidence': incidence}
    return ClusterResult(cands, pf.xyz, pf.intensity, pf.index, labels, n, rejected,
                         reject.why, clusters=table, **extra)

def candidates_to_array(cands: Candidates, only_confirmed: bool = True) -> np.ndarray:
    """Pack candidates into :data:`SIZED_CANDIDATE_DTYPE` rows for a PointCloud2."""
    c = cands.subset(cands.confirmed) if only_confirmed else cands
    out = np.zeros(len(c), SIZED_CANDIDATE_DTYPE)
    if len(c):
        out['x'], out['y'], out['z'] = c.center[:, 0], c.center[:, 1], c.center[:, 2]
        out['radius'] = c.radius
        out['intensity'] = c.intensity
        out['count'] = c.count
        out['id'] = c.ids
        out['half_w'], out['half_h'], out['dz'] = c.half_size.T
    return out
