"""Highway sign inventory: sightings of signs in camera frames -> one record per physical sign.

Balali and Golparvar-Fard build sign inventories for departments of transportation from
video: every sign along a road, once, with its class and where it stands.  This module
is the algorithm on plain data (no rclpy, no bag reading; ``workzone_ros.tools.inventory``
feeds it):

1. **Positioning** (:func:`locate`): each sighting -- a classified ``interfaces.Sign`` of one
   image -- becomes a point in the odometry frame,
   ``X_odom = T_odom<-base(t) @ T_base<-camera @ X_camera``, with ``X_camera``

   * the LiDAR candidate whose projection falls in the sign's box (``Sighting.lidar_point``,
     camera frame at the image time, chosen by :func:`match_candidate`), ``source = lidar``;
   * else the monocular estimate: the ray through the undistorted box centre, at the sign's
     ``distance_m`` (apparent size: a depth; LiDAR ROI range: a range), ``source = camera``.

   Each position carries a standard deviation: ``lidar_sigma_m`` for LiDAR, else
   ``camera_sigma_m + camera_sigma_rel * distance`` (the size-based distance is proportional
   to the box height, so its error grows with the distance), times ``cut_factor`` when the
   box touches the image edge (its centre and height are then those of the visible part).
2. **Tracklets** (:func:`group_tracklets`): the sightings of one track (bag, ``track_id``)
   are one tracklet; a sighting without a track id is a tracklet of its own.  Its class is
   the vote of its sightings weighted by score x box height (large boxes are read best); its
   position is the robust, inverse-variance weighted mean of its LiDAR positions when it has
   any, else of its camera positions (outliers beyond ``gate_sigmas`` from the median
   dropped).
3. **Physical signs** (:func:`merge_tracklets`): tracklets are merged -- the tracker lost a
   sign and found it again, the sign was seen on another drive (bag) of the same road -- when
   their classes agree and their positions lie within
   ``clamp(gate_sigmas * sqrt(s1^2 + s2^2), min_gate_m, max_gate_m)``.  Two tracklets of one
   bag seen in the same frame with disjoint boxes are two signs, whatever their positions
   (cannot-link); with overlapping boxes (IoU >= ``same_box_iou``) one sign (must-link).
   Merging is greedy, closest pair (in gates) first.

A physical sign keeps its members (indices into the sightings), first and last stamps, frame
count, class and category (vote), position and its source, the mile number read most often
(mile markers) and the sighting with the best crop (:func:`crop_quality`: the largest, most
confident box not cut by the image edge).

The odometry frame is the map: sightings of several bags merge only when their odometry
frames coincide (one drive split into bags, or map-aligned odometry).
"""
from __future__ import annotations

import math
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.interfaces import Box, Sign

__all__ = ['InventoryConfig', 'Sighting', 'Located', 'Tracklet', 'PhysicalSign',
           'camera_in_base', 'camera_ray', 'camera_point', 'locate', 'match_candidate',
           'crop_quality', 'box_cut', 'group_tracklets', 'merge_tracklets', 'build_inventory']


@dataclass(frozen=True)
class InventoryConfig:
    """Uncertainties and gates of the inventory.

    Attributes:
        lidar_sigma_m: standard deviation of a LiDAR-placed sighting (cluster centre vs face
            centre, calibration, synchronisation), m.
        camera_sigma_m, camera_sigma_rel: a monocular sighting's standard deviation is
            ``camera_sigma_m + camera_sigma_rel * distance``.
        cut_factor: sigma multiplier of a camera sighting whose box touches the image edge.
        edge_px: a box within this many pixels of the image border is cut by it.
        gate_sigmas: two positions are one sign within this many combined sigmas ...
        min_gate_m, max_gate_m: ... but never beyond ``max_gate_m`` nor under ``min_gate_m``.
        same_box_iou: two tracks of one bag whose boxes overlap this much in a shared frame
            are one sign (the tracker's duplicate); less overlap in a shared frame: two signs.
        min_frames: physical signs seen in fewer frames are dropped (stray classifications).
        min_height_m: a sighting placed lower than this above the road under the car is no
            sign (a sign stands on the roadside; road markings and reflections do not count).
        lidar_box_pad: a LiDAR candidate belongs to a sign when its projection falls in the
            sign's box grown by this fraction of its size on each side ...
        lidar_range_ratio: ... and its range agrees with the monocular distance within this
            factor (when the sign has one): a candidate behind or before the sign is not it.
    """

    lidar_sigma_m: float = 0.3
    camera_sigma_m: float = 0.5
    camera_sigma_rel: float = 0.1
    cut_factor: float = 4.0
    edge_px: float = 2.0
    gate_sigmas: float = 3.0
    min_gate_m: float = 1.5
    max_gate_m: float = 12.0
    same_box_iou: float = 0.5
    min_frames: int = 2
    min_height_m: float = 0.0
    lidar_box_pad: float = 0.25
    lidar_range_ratio: float = 1.6


@dataclass(frozen=True)
class Sighting:
    """One sign seen in one image.

    Attributes:
        stamp_ns: image stamp.
        sign: the classified sign (box, class, category, track id, distance).
        bag: which bag (drive) it comes from: track ids are unique per bag only.
        lidar_point: the sign's LiDAR candidate in the camera frame at the image time (m),
            or None.
        mile: mile-marker number read on it (default: ``sign.mile`` when the Sign has one).
        image_size: (width, height) of the image, for the edge test.
    """

    stamp_ns: int
    sign: Sign
    bag: str = ''
    lidar_point: Optional[tuple[float, float, float]] = None
    mile: Optional[int] = None
    image_size: tuple[int, int] = (0, 0)

    @property
    def mile_number(self) -> Optional[int]:
        """``mile``, else the Sign's own ``mile`` field when it has one."""
        return self.mile if self.mile is not None else getattr(self.sign, 'mile', None)


@dataclass(frozen=True)
class Located:
    """A sighting's position in the odometry frame."""

    xyz: np.ndarray
    source: str          # 'lidar' | 'camera'
    sigma_m: float
    height_m: float = math.nan    # above base_link (the road under the car) at the stamp


@dataclass
class Tracklet:
    """Sightings of one track (or one untracked sighting) and what they say together."""

    key: tuple
    bag: str
    members: list[int]
    class_key: str
    votes: Counter
    xyz: Optional[np.ndarray]
    sigma_m: float
    source: str                       # 'lidar' | 'camera' | 'none'
    stamps: dict[int, Box] = field(default_factory=dict)


@dataclass
class PhysicalSign:
    """One row of the inventory."""

    sign_id: int
    class_key: str
    category: str
    first_ns: int
    last_ns: int
    frames: int
    xyz: Optional[np.ndarray]
    source: str                       # 'lidar' | 'camera' | 'none'
    sigma_m: float
    mile: Optional[int]
    best: int                         # index of the sighting with the best crop
    members: list[int]
    bags: list[str]                   # in order of first sighting; stamps are the first's


# --- geometry -------------------------------------------------------------------------------

def camera_in_base(lidar_to_camera: np.ndarray, lidar_in_base: np.ndarray) -> np.ndarray:
    """4x4 ``X_base = T @ X_camera`` from the projector's extrinsics.

    Args:
        lidar_to_camera: ``X_cam = T @ X_lidar`` (``projector.lidar_to_camera``).
        lidar_in_base: ``X_base = T @ X_lidar`` (``projector.lidar_in_base`` as a matrix).
    """
    r = lidar_to_camera[:3, :3]
    inv = np.eye(4)
    inv[:3, :3] = r.T
    inv[:3, 3] = -r.T @ lidar_to_camera[:3, 3]
    return np.asarray(lidar_in_base, float) @ inv


def camera_ray(u: float, v: float, camera) -> np.ndarray:
    """Undistorted normalised ray ``(x, y, 1)`` through pixel (u, v) of ``camera``.

    Args:
        camera: :class:`workzone_ros.core.projection.CameraModel` (K, D, model).
    """
    import cv2
    pt = np.array([[[float(u), float(v)]]])
    d = np.asarray(camera.D, float)
    if camera.model == 'equidistant':
        xy = cv2.fisheye.undistortPoints(pt, camera.K, d[:4] if d.size else np.zeros(4))
    else:
        xy = cv2.undistortPoints(pt, camera.K, d if d.size else None)
    x, y = xy.reshape(2)
    return np.array([x, y, 1.0])


def camera_point(sign: Sign, camera) -> Optional[np.ndarray]:
    """The sign's centre in the camera frame from its box and monocular distance (or None).

    A ``size`` distance is a depth (pinhole ``f H / h``); a ``lidar`` distance is a range.
    """
    if sign.distance_m is None or sign.distance_source == 'none' or sign.box.h <= 0:
        return None
    ray = camera_ray(sign.box.x + sign.box.w / 2, sign.box.y + sign.box.h / 2, camera)
    if sign.distance_source == 'lidar':
        return ray / np.linalg.norm(ray) * float(sign.distance_m)
    return ray * float(sign.distance_m)


def box_cut(box: Box, size: tuple[int, int], edge_px: float) -> bool:
    """The box touches the image border (within ``edge_px``); False when the size is unknown."""
    w, h = size
    if w <= 0 or h <= 0:
        return False
    return (box.x <= edge_px or box.y <= edge_px or box.x2 >= w - edge_px
            or box.y2 >= h - edge_px)


def locate(s: Sighting, camera, base_camera: np.ndarray, odom_base: Optional[np.ndarray],
           cfg: InventoryConfig = InventoryConfig()) -> Optional[Located]:
    """Position of one sighting in the odometry frame (module docstring, step 1).

    Args:
        s: the sighting.
        camera: intrinsics (:class:`~workzone_ros.core.projection.CameraModel`).
        base_camera: 4x4 ``X_base = T @ X_camera`` (:func:`camera_in_base`).
        odom_base: 4x4 odom <- base at ``s.stamp_ns``; None: no odometry, no position.

    Returns:
        :class:`Located`, or None (no odometry, or neither LiDAR nor a distance).
    """
    if odom_base is None:
        return None
    if s.lidar_point is not None:
        p, source, sigma = np.asarray(s.lidar_point, float), 'lidar', cfg.lidar_sigma_m
    else:
        p = camera_point(s.sign, camera)
        if p is None:
            return None
        source = 'camera'
        sigma = cfg.camera_sigma_m + cfg.camera_sigma_rel * float(np.linalg.norm(p))
        if box_cut(s.sign.box, s.image_size, cfg.edge_px):
            sigma *= cfg.cut_factor
    base_camera = np.asarray(base_camera, float)
    height = float(base_camera[2, :3] @ p + base_camera[2, 3])
    t = np.asarray(odom_base, float) @ base_camera
    return Located(t[:3, :3] @ p + t[:3, 3], source, float(sigma), height)


def match_candidate(box: Box, uv: np.ndarray, xyz_cam: np.ndarray,
                    distance_m: Optional[float] = None,
                    cfg: InventoryConfig = InventoryConfig()) -> Optional[int]:
    """Index of the LiDAR candidate that is this sign, or None.

    The candidate's projection must fall in the box grown by ``lidar_box_pad`` (nearest to
    the box centre first) and, when the sign has a monocular ``distance_m``, its range must
    agree with it within ``lidar_range_ratio``.

    Args:
        box: the sign's box.
        uv: (N, 2) projected candidate centres (NaN: not projectable).
        xyz_cam: (N, 3) candidate centres in the camera frame.
        distance_m: the sign's monocular distance (None: no range check).
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    if not len(uv):
        return None
    px, py = cfg.lidar_box_pad * box.w, cfg.lidar_box_pad * box.h
    with np.errstate(invalid='ignore'):
        inside = ((uv[:, 0] >= box.x - px) & (uv[:, 0] <= box.x2 + px)
                  & (uv[:, 1] >= box.y - py) & (uv[:, 1] <= box.y2 + py))
    if distance_m:
        rng = np.linalg.norm(np.asarray(xyz_cam, float).reshape(-1, 3), axis=1)
        ratio = rng / float(distance_m)
        inside &= (ratio <= cfg.lidar_range_ratio) & (ratio >= 1.0 / cfg.lidar_range_ratio)
    if not inside.any():
        return None
    c = np.array([box.x + box.w / 2, box.y + box.h / 2])
    d = np.where(inside, np.hypot(*(uv - c).T), np.inf)
    return int(np.argmin(d))


def crop_quality(box: Box, score: float, size: tuple[int, int], edge_px: float = 2.0) -> float:
    """How good a crop of this box is: area x score, a cut box (image edge) 20x worse."""
    q = float(box.area) * max(float(score), 1e-3)
    return q * 0.05 if box_cut(box, size, edge_px) else q


# --- tracklets and merging ------------------------------------------------------------------

def _fuse(points: Sequence[Located], cfg: InventoryConfig) -> tuple[np.ndarray, float]:
    """Robust inverse-variance mean of positions and its sigma (the best member's: the
    monocular errors of one sign are correlated, averaging does not shrink them)."""
    xyz = np.array([p.xyz for p in points], float)
    sig = np.array([p.sigma_m for p in points], float)
    med = np.median(xyz, axis=0)
    keep = np.linalg.norm(xyz - med, axis=1) <= cfg.gate_sigmas * np.maximum(sig, 1e-3) + \
        np.min(sig)
    if not keep.any():
        keep[:] = True
    w = 1.0 / np.maximum(sig[keep], 1e-3) ** 2
    return (xyz[keep] * w[:, None]).sum(0) / w.sum(), float(sig[keep].min())


def _vote_weight(s: Sighting) -> float:
    return max(float(s.sign.score), 1e-3) * max(float(s.sign.box.h), 1.0)


def group_tracklets(sightings: Sequence[Sighting], located: Sequence[Optional[Located]],
                    cfg: InventoryConfig = InventoryConfig()) -> list[Tracklet]:
    """Sightings -> tracklets (module docstring, step 2).

    Unknown-category signs and sightings placed under ``min_height_m`` are left out.
    """
    groups: dict[tuple, list[int]] = defaultdict(list)
    for i, s in enumerate(sightings):
        if s.sign.category == 'unknown' or s.sign.class_key not in catalogue.BY_KEY:
            continue
        if located[i] is not None and located[i].height_m < cfg.min_height_m:
            continue
        tid = s.sign.track_id
        groups[(s.bag, 'track', tid) if tid is not None else (s.bag, 'sighting', i)].append(i)
    out = []
    for key, members in groups.items():
        votes: Counter = Counter()
        stamps: dict[int, Box] = {}
        for i in members:
            votes[sightings[i].sign.class_key] += _vote_weight(sightings[i])
            stamps[sightings[i].stamp_ns] = sightings[i].sign.box
        pts = [located[i] for i in members if located[i] is not None]
        lidar = [p for p in pts if p.source == 'lidar']
        use = lidar or pts
        xyz, sigma = _fuse(use, cfg) if use else (None, math.inf)
        source = use[0].source if use else 'none'
        out.append(Tracklet(key, key[0], members, votes.most_common(1)[0][0], votes, xyz,
                            sigma, source, stamps))
    return out


def _link(a: dict, b: dict, cfg: InventoryConfig) -> Optional[bool]:
    """Frames shared by two clusters (``(bag, stamp) -> boxes``): False when in one of them
    every pair of boxes is disjoint (two signs side by side), True when boxes overlap by
    ``same_box_iou`` (one sign, tracked twice), None when the frames say nothing."""
    shared = a.keys() & b.keys()
    verdict = None
    for key in shared:
        best = max(p.iou(q) for p in a[key] for q in b[key])
        if best < 0.1:
            return False
        if best >= cfg.same_box_iou:
            verdict = True
    return verdict


class _Cluster:
    def __init__(self, t: Tracklet) -> None:
        self.parts = [t]
        self.votes = Counter(t.votes)
        self.xyz, self.sigma, self.source = t.xyz, t.sigma_m, t.source
        self.frames: dict[tuple, list[Box]] = {(t.bag, k): [b] for k, b in t.stamps.items()}

    @property
    def class_key(self) -> str:
        return self.votes.most_common(1)[0][0]

    def absorb(self, other: '_Cluster') -> None:
        self.parts += other.parts
        self.votes.update(other.votes)
        for k, boxes in other.frames.items():
            self.frames.setdefault(k, []).extend(boxes)
        pos = [p for p in (self, other) if p.xyz is not None]
        pos = [p for p in pos if p.source == 'lidar'] or pos
        if pos:
            w = np.array([1.0 / max(p.sigma, 1e-3) ** 2 for p in pos])
            self.xyz = sum(wi * p.xyz for wi, p in zip(w, pos)) / w.sum()
            self.sigma = min(p.sigma for p in pos)
            self.source = pos[0].source


def _cost(a: _Cluster, b: _Cluster, cfg: InventoryConfig) -> float:
    """Distance in gates (< 1: mergeable), inf when they cannot be one sign."""
    link = _link(a.frames, b.frames, cfg)
    if link is not None:
        return 0.0 if link else math.inf
    if a.class_key != b.class_key or a.xyz is None or b.xyz is None:
        return math.inf
    gate = min(max(cfg.gate_sigmas * math.hypot(a.sigma, b.sigma), cfg.min_gate_m),
               cfg.max_gate_m)
    return float(np.linalg.norm(a.xyz - b.xyz)) / gate


def merge_tracklets(tracklets: Sequence[Tracklet], cfg: InventoryConfig = InventoryConfig()
                    ) -> list[list[Tracklet]]:
    """Greedy merging, closest pair first (module docstring, step 3); groups of tracklets.

    Only pairs within ``max_gate_m`` or sharing a frame are ever compared (a heap of their
    costs), so thousands of untracked sightings stay cheap.
    """
    import heapq
    clusters = [_Cluster(t) for t in tracklets]
    n = len(clusters)
    pos = np.array([c.xyz if c.xyz is not None else [np.nan] * 3 for c in clusters],
                   float).reshape(n, 3)
    by_frame: dict[tuple, set[int]] = defaultdict(set)
    for i, c in enumerate(clusters):
        for k in c.frames:
            by_frame[k].add(i)
    alive = np.ones(n, bool)
    version = [0] * n
    heap: list = []

    def push(i: int) -> None:
        near = set()
        if np.isfinite(pos[i]).all():
            with np.errstate(invalid='ignore'):
                d = np.linalg.norm(pos - pos[i], axis=1)
            near.update(np.flatnonzero(alive & (d <= cfg.max_gate_m)).tolist())
        for k in clusters[i].frames:
            near.update(by_frame[k])
        for k in near:
            if k != i and alive[k]:
                c = _cost(clusters[i], clusters[k], cfg)
                if c < 1.0:
                    heapq.heappush(heap, (c, min(i, k), max(i, k), version[i], version[k])
                                   if i < k else (c, k, i, version[k], version[i]))

    for i in range(n):
        push(i)
    while heap:
        _, i, j, vi, vj = heapq.heappop(heap)
        if not (alive[i] and alive[j]) or vi != version[i] or vj != version[j]:
            continue
        clusters[i].absorb(clusters[j])
        alive[j] = False
        version[i] += 1
        for k in clusters[j].frames:
            by_frame[k].discard(j)
            by_frame[k].add(i)
        pos[j] = np.nan
        if clusters[i].xyz is not None:
            pos[i] = clusters[i].xyz
        push(i)
    return [clusters[i].parts for i in np.flatnonzero(alive)]


def build_inventory(sightings: Sequence[Sighting], located: Sequence[Optional[Located]],
                    cfg: InventoryConfig = InventoryConfig(),
                    quality: Optional[Callable[[int], float]] = None) -> list[PhysicalSign]:
    """The inventory of ``sightings`` (positions ``located``, same order).

    Args:
        sightings: every sighting of every bag.
        located: :func:`locate` of each (None: no position).
        cfg: uncertainties and gates.
        quality: crop quality of sighting ``i`` (default :func:`crop_quality` of its box).

    Returns:
        Physical signs seen in at least ``cfg.min_frames`` frames, numbered from 1 in order
        of first sighting (bags in the order of their first sighting); ``first_ns`` and
        ``last_ns`` are stamps of the sign's first bag.
    """
    if quality is None:
        def quality(i: int) -> float:
            s = sightings[i]
            return crop_quality(s.sign.box, s.sign.score, s.image_size, cfg.edge_px)
    groups = merge_tracklets(group_tracklets(sightings, located, cfg), cfg)
    order: dict[str, int] = {}
    for s in sightings:
        order.setdefault(s.bag, len(order))
    rows = []
    for parts in groups:
        members = sorted(i for t in parts for i in t.members)
        frames = len({(sightings[i].bag, sightings[i].stamp_ns) for i in members})
        if frames < cfg.min_frames:
            continue
        votes: Counter = Counter()
        for t in parts:
            votes.update(t.votes)
        key = votes.most_common(1)[0][0]
        pos = [t for t in parts if t.xyz is not None]
        pos = [t for t in pos if t.source == 'lidar'] or pos
        if pos:
            fused = _fuse([Located(t.xyz, t.source, t.sigma_m) for t in pos], cfg)
            xyz, sigma, source = fused[0], fused[1], pos[0].source
        else:
            xyz, sigma, source = None, math.inf, 'none'
        miles = Counter(m for m in (sightings[i].mile_number for i in members) if m is not None)
        bags = sorted({sightings[i].bag for i in members}, key=order.__getitem__)
        stamps = [sightings[i].stamp_ns for i in members if sightings[i].bag == bags[0]]
        rows.append(PhysicalSign(
            0, key, catalogue.BY_KEY[key].category, min(stamps), max(stamps), frames, xyz,
            source, sigma, miles.most_common(1)[0][0] if miles else None,
            max(members, key=quality), members, bags))
    rows.sort(key=lambda r: (order[r.bags[0]], r.first_ns))
    for k, r in enumerate(rows, 1):
        r.sign_id = k
    return rows
