"""The colour sign detector: the stages of :mod:`workzone_ros.core.detect` composed.

:class:`ColorDetector` holds the model, the configuration and the per-frame state (the
frame's colour-balance gains and saturation table, the mounting-height reference row, the
faces measured on sharp edges) and runs a frame through the stages, one
mixin per module, in this order: the colour mask (:class:`~.mask.MaskMixin`), its blobs
(:class:`~.blobs.BlobMixin`) and their recovery (:class:`~.recovery.RecoveryMixin`), the
sign measurement (:class:`~.measure.MeasureMixin`) with its filters
(:class:`~.filters.FilterMixin`), diamond (:class:`~.warning.WarningMixin`), rectangle
(:class:`~.rectangle.RectangleMixin`) and two-colour (:class:`~.plaque.PlaqueMixin`) steps,
then non-maximum suppression and the LiDAR fusion (:class:`~.lidar.LidarMixin`).  The RGB-LP
baseline groups its mask with MSER (:class:`~.baselines.MserMixin`).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.color_model import (
    ColorModel,
    ModelError,
    SpatialPrior,
    apply_gains,
    saturation_gain,
    saturation_table,
)
from workzone_ros.core.detect.baselines import MserMixin, RgbLpModel
from workzone_ros.core.detect.blobs import BlobMixin
from workzone_ros.core.detect.candidates import Candidate, _iou, nms
from workzone_ros.core.detect.common import _P_SCALE
from workzone_ros.core.detect.config import DetectorConfig
from workzone_ros.core.detect.filters import FilterMixin
from workzone_ros.core.detect.lidar import LidarMixin
from workzone_ros.core.detect.mask import MaskMixin
from workzone_ros.core.detect.measure import MeasureMixin
from workzone_ros.core.detect.plaque import PlaqueMixin
from workzone_ros.core.detect.recovery import RecoveryMixin
from workzone_ros.core.detect.rectangle import RectangleMixin
from workzone_ros.core.detect.warning import WarningMixin
from workzone_ros.interfaces import Detection, Roi

__all__ = ['ColorDetector']


class ColorDetector(MaskMixin, BlobMixin, RecoveryMixin, MeasureMixin, FilterMixin,
                    WarningMixin, RectangleMixin, PlaqueMixin, LidarMixin, MserMixin):
    """Colour sign detector over a :class:`ColorModel` (and optional RGB thresholds of Balali
    and Golparvar-Fard).

    Args:
        model: the colour model (tables and prior).
        config: detector parameters.
        rgb_lp: thresholds for ``method='rgb_lp'``.

    Raises:
        ModelError: the model lacks a configured colour, or ``rgb_lp`` is missing.
    """

    def __init__(self, model: ColorModel, config: DetectorConfig = DetectorConfig(),
                 rgb_lp: Optional[RgbLpModel] = None) -> None:
        self.model = model
        self.config = config
        self.rgb_lp = rgb_lp
        #: places (16 px cells) of the last frame's blobs rejected as drums or cones
        self.channelizers: set = set()
        #: the costly measurements whose per-frame budget ran out on the last frame
        #: (``blur_fit``: ``max_blur_fits``, ``grown``: ``max_grown``, ``shifted``:
        #: ``max_shifted``)
        self.budget_spent: set[str] = set()
        self._budget = self._frame_budget()
        #: the last frame was measured lean (:meth:`detect`)
        self.lean = False
        #: the last frame shrunk to the mask's scale and its white-balanced HSV, when its
        #: colour pass covered the whole frame (the proposals reuse them), else None
        self.frame_view: Optional[tuple[np.ndarray, np.ndarray]] = None
        if config.method == 'rgb_lp' and rgb_lp is None:
            raise ModelError("method 'rgb_lp' needs the RGB thresholds of Balali and "
                             'Golparvar-Fard (train them with workzone-ros train color '
                             '--rgb-lp)')
        colors = config.colors if config.method != 'rgb_lp' else ('orange',)
        self.colors = tuple(colors)
        self._idx = {c: model.index(c) for c in self.colors} if config.method == 'learned' \
            else {}
        self._lut_u8 = {c: np.ascontiguousarray(
            np.round(model.luts[i] * _P_SCALE).astype(np.uint8).reshape(-1))
            for c, i in self._idx.items()}
        self._vmin = {c: model.v_min[i] for c, i in self._idx.items()}
        self._cache: dict[tuple, Any] = {}
        self.debug: Optional[list] = None      # a list: rejected / measured blobs land here
        self._gains: Optional[tuple] = None
        self._sat_norm = model.sat_norm if config.method == 'learned' else None
        self._sat_tab: Optional[np.ndarray] = None
        g = model.extras.get('geometry')
        self._geometry = ((float(g[0]), float(g[1]), float(g[2] if len(g) >= 3 else g[1]))
                          if g is not None and len(g) >= 2 else None)
        self._ref_row: Optional[float] = None             # this frame's reference row
        # half-diagonals (a, b) of this frame's faces measured on sharp edges: their box
        # takes ``diamond_box_bias`` (a face keeps them when moved to its blob's window)
        self._sharp_faces: set[tuple[float, float]] = set()
        self._intrinsics: Optional[tuple[float, float, float, float]] = None

    def set_camera(self, intrinsics: Optional[Sequence[float]]) -> None:
        """The frames' intrinsics (fx, fy, cx, cy in pixels, e.g. from CameraInfo; None:
        unknown), compared with the model's training camera (``camera_match``)."""
        new = None if intrinsics is None else tuple(float(v) for v in intrinsics)
        if new is not None and len(new) != 4:
            raise ValueError('intrinsics are (fx, fy, cx, cy)')
        if new != self._intrinsics:
            self._intrinsics = new
            self._cache.clear()

    def foreign_prior(self) -> float:
        """The location-free prior used on another camera's frames (``foreign_prior``).

        0 in the config: the model prior's mean over its ROI divided by the orange table's
        peak.  The seed's posterior multiplies two factors each scaled to a peak of 1 (the
        heat map by construction; the table is scaled here), so the posterior threshold
        on another camera is the one the model applies at an average place of its own
        ROI, relative to its most sign-like colour.
        """
        if self.config.foreign_prior > 0.0:
            return float(self.config.foreign_prior)
        peak = 1.0
        if 'orange' in self._idx:
            peak = max(float(self.model.luts[self._idx['orange']].max()), 1e-3)
        return float(min(1.0, self.model.prior.expected() / peak))

    def same_camera(self, width: int, height: int) -> bool:
        """Whether the model's fixed-camera prior and mounting row apply to these frames."""
        if not self.config.camera_match:
            return True
        return self.model.same_camera(width, height, self._intrinsics,
                                      self.config.camera_tolerance)

    def _frame_budget(self) -> dict:
        """A frame's costly measurements, by kind (:meth:`_spend`)."""
        cfg = self.config
        return {'blur_fit': cfg.max_blur_fits, 'grown': cfg.max_grown,
                'shifted': cfg.max_shifted}

    def reset(self) -> None:
        """A new camera or clip (the detector keeps no state between frames today)."""

    def with_config(self, **changes) -> 'ColorDetector':
        """A detector sharing the model with some parameters changed."""
        det = ColorDetector(self.model, replace(self.config, **changes), self.rgb_lp)
        det.set_camera(self._intrinsics)
        return det

    def _frame_setup(self, width: int, height: int) -> tuple:
        key = (width, height)
        if key not in self._cache:
            cfg = self.config
            s = int(cfg.scale)
            sw, sh = -(-width // s), -(-height // s)
            own = self.same_camera(width, height)
            if not cfg.use_prior:
                prior = SpatialPrior.uniform(width, height)
            elif own:
                prior = self.model.prior
            else:
                # another camera: the heat map's rows and columns are other directions
                # there, so only its location-free content is kept (Seo et al.'s prior is a
                # property of the training camera, not of the signs)
                prior = SpatialPrior.flat(self.foreign_prior(), width, height)
            p = prior.prior_image(sw, sh)
            thr = np.clip(np.ceil(cfg.threshold / p * _P_SCALE), 0, 255).astype(np.uint8)
            p_full = prior.prior_image(width, height)
            rx, ry, rw, rh = prior.roi_for(width, height) if cfg.use_prior else (
                0, 0, width, height)
            roi = (max(0, rx // s), max(0, ry // s), min(sw, -(-(rx + rw) // s)),
                   min(sh, -(-(ry + rh) // s)))
            self._cache[key] = (s, sw, sh, thr, p_full, roi, own)
        return self._cache[key]

    def detect(self, bgr: np.ndarray, rois: Sequence[Roi] = (), lean: bool = False
               ) -> list[Detection]:
        """Detect colour signs in one BGR frame.

        Args:
            bgr: (H, W, 3) uint8 image.
            rois: LiDAR ROIs of this frame (empty when there is no LiDAR).
            lean: measure without the costly second attempts on a blob that the first
                measurement did not box (the chroma fit, the grown blob, the moved
                refinement starts): about half the time on busy real frames, for a caller
                that has fallen behind its camera.

        Returns:
            Every detected sign, largest first.
        """
        return [c.detection() for c in self.candidates(bgr, rois, lean)]

    def candidates(self, bgr: np.ndarray, rois: Sequence[Roi] = (), lean: bool = False
                   ) -> list[Candidate]:
        """As :meth:`detect`, returning :class:`Candidate` objects (with shape features)."""
        if bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.dtype != np.uint8:
            raise ValueError(f'expected an (H, W, 3) uint8 BGR image, got {bgr.shape} '
                             f'{bgr.dtype}')
        height, width = bgr.shape[:2]
        s, sw, sh, thr_base, p_full, roi, own = self._frame_setup(width, height)
        cfg = self.config
        self.channelizers = set()   # blobs rejected as banded drums / cones this frame
        # this frame's costly measurements left; the kinds whose budget ran out
        self._budget = self._frame_budget()
        self.budget_spent = set()
        self.lean = lean
        self._ref_row = None
        self._sharp_faces = set()
        if self._geometry is not None and cfg.use_geometry and own:
            # the training camera's horizon row; on another camera the row is unknown
            self._ref_row = self._geometry[0] * height
        # LiDAR ROIs in mask coordinates, expanded by roi_margin.
        lboxes = []
        for r in rois:
            mx, my = r.box.w * cfg.roi_margin, r.box.h * cfg.roi_margin
            x0 = int(max(0, (r.box.x - mx) // s))
            y0 = int(max(0, (r.box.y - my) // s))
            x1 = int(min(sw, math.ceil((r.box.x2 + mx) / s)))
            y1 = int(min(sh, math.ceil((r.box.y2 + my) / s)))
            if x1 > x0 and y1 > y0:
                lboxes.append((x0, y0, x1, y1))
        small = cv2.resize(bgr, (sw, sh), interpolation=cv2.INTER_AREA) if s > 1 else bgr
        self.frame_view = None
        self._gains = None
        if cfg.method == 'learned' and small.size:
            # colour constancy outside the table (as the model was trained; None: none)
            self._gains = self.model.balance_gains(small)
        self._sat_tab = None
        if self._sat_norm is not None and 'orange' in self._idx and small.size:
            # frame saturation normalisation (the model was trained this way), measured on
            # a quarter of the mask's pixels
            sub = small[::2, ::2]
            if self._gains is not None:
                sub = apply_gains(sub, self._gains)
            g = saturation_gain(cv2.cvtColor(sub, cv2.COLOR_BGR2HSV), self._sat_norm,
                                self._vmin['orange'])
            if g > 1.0:
                self._sat_tab = saturation_table(g)
        # 1. the colour-only pass over the prior's ROI, exactly as without LiDAR
        cands = self._pass(small, bgr, roi, thr_base, s, thr_base, [])
        cands = nms(cands, cfg.nms_iou, cfg.nms_contain,
                    'area' if cfg.method == 'rgb_lp' else 'confidence')
        # 2. a separate pass, with the ROI threshold, over the LiDAR ROIs that no colour
        # detection explains (its centre in the ROI); it never changes a colour detection
        todo = [b for b in lboxes if not any(
            b[0] <= (c.x + c.w / 2) / s < b[2] and b[1] <= (c.y + c.h / 2) / s < b[3]
            for c in cands)]
        if todo:
            thr = thr_base
            if cfg.method == 'learned':
                thr = thr_base.copy()
                t_roi = np.uint8(min(255, math.ceil(cfg.roi_threshold / cfg.roi_prior
                                                    * _P_SCALE)))
                for x0, y0, x1, y1 in todo:
                    np.minimum(thr[y0:y1, x0:x1], t_roi, out=thr[y0:y1, x0:x1])
            region = (min(b[0] for b in todo), min(b[1] for b in todo),
                      max(b[2] for b in todo), max(b[3] for b in todo))
            extra = self._pass(small, bgr, region, thr, s, thr_base, todo, limit=todo)
            extra = nms(extra, cfg.nms_iou, cfg.nms_contain,
                        'area' if cfg.method == 'rgb_lp' else 'confidence')
            for c in extra:
                if self._in_roi((c.x, c.y, c.w, c.h), s, todo) is not None and all(
                        _iou((c.x, c.y, c.w, c.h), (k.x, k.y, k.w, k.h))[1] <= cfg.nms_contain
                        for k in cands):
                    cands.append(c)
        out = self._fuse(cands, rois, bgr, thr_base)
        for c in out:
            # a sign's box ends at the frame's edge (a two-colour extension or a border
            # growth of a sign the edge cuts reached past it)
            x1, y1 = min(c.x + c.w, float(width)), min(c.y + c.h, float(height))
            c.x, c.y = max(c.x, 0.0), max(c.y, 0.0)
            c.w, c.h = max(x1 - c.x, 1.0), max(y1 - c.y, 1.0)
        return out
