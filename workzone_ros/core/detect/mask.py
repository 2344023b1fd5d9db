"""The colour mask: table lookup, posterior threshold, hysteresis.

One pass over a region of the frame at the mask's resolution: the colour table's likelihood
(brightness-gated, the frame's saturation normalised), smoothed, compared with the per-pixel
threshold tau / P(sign) of the spatial prior, dim fragments rejoined (:func:`_hysteresis`),
then handed to the blob stage.  Also the colour-balanced windows of the frame the later
stages measure on (value, luma, chroma).
"""
from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from workzone_ros.core.blob_kernels import clipped_outside, gated_likelihood
from workzone_ros.core.color_model import HSV_RANGES, apply_gains
from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.kernels import components_with_stats, flat_take, label_at_first_pixel

__all__ = ['MaskMixin']

#: the identity of uint8 values (the saturation table of a frame that needs none)
_SAME = np.arange(256, dtype=np.uint8)


def _clipped_growth(bgr: np.ndarray, weak: np.ndarray, strong: np.ndarray, bound: float,
                    near: Optional[np.ndarray] = None) -> np.ndarray:
    """The pixels that join a blob's face (uint8 mask) because the camera clipped their red:
    pixels of ``weak`` likelihood whose red channel in ``bgr`` (as the camera gave it) is 250
    or more and above the green, connected to the ``strong`` core through such pixels.  A
    clipped red hides how red the pixel was: its true hue is lower (more orange) and its
    saturation higher than the image shows, so a sunlit plaque's face reads yellowish and
    the table rates it weak.  A connected part more than ``1 + bound`` times the core's
    width or height (plus 2 px) is left out (a surface of that colour, not the face).
    ``near``: pixels the face has already (nothing to do when they hold every clipped one)."""
    out = np.zeros(weak.shape, np.uint8)
    if not clipped_outside(bgr, weak, np.zeros_like(weak) if near is None else near):
        return out                  # (compiled: most blobs have no such pixel)
    clip = (weak > 0) & (bgr[..., 2] >= 250) & (bgr[..., 1] < bgr[..., 2])
    joined = (clip | (strong > 0)).astype(np.uint8)
    n, lab, st = components_with_stats(joined)
    keep = np.zeros(n, bool)
    keep[np.unique(lab[strong > 0])] = True
    keep[0] = False
    _, _, cw, ch = cv2.boundingRect(strong)
    keep &= (st[:, 2] <= (1 + bound) * cw + 2) & (st[:, 3] <= (1 + bound) * ch + 2)
    out[keep[lab]] = 1
    return out


def _hysteresis(mask: np.ndarray, prob_lo: np.ndarray, thr: np.ndarray, smooth_px: int
                ) -> np.ndarray:
    """``mask`` filled in from the mask of ``prob_lo`` (the likelihood with a lower
    brightness gate, smoothed and thresholded like it): each blob of the latter that holds
    two or more blobs of ``mask`` is added within their box.  A small dim plaque whose
    legend darkens half its pixels below the gate is left in fragments, which its dim
    pixels join again; dim pixels never make a blob, nor grow a single one (real cones and
    brick came out as more false detections), nor grow past the bright pixels' box (a dusk
    sign's dim white part, a sky of its colour)."""
    # only around the bright pixels (the box of them all, and the blur's reach)
    bx, by, bw, bh = cv2.boundingRect(mask)
    pad = max(1, smooth_px)
    H, W = mask.shape
    wx0, wy0 = max(0, bx - 2 * pad), max(0, by - 2 * pad)
    wx1, wy1 = min(W, bx + bw + 2 * pad), min(H, by + bh + 2 * pad)
    win = (slice(wy0, wy1), slice(wx0, wx1))
    part = prob_lo[win]
    if smooth_px > 1:
        part = cv2.blur(part, (smooth_px, smooth_px))
    lo = cv2.compare(part, thr[win], cv2.CMP_GE)
    hi = mask[win]
    # the lower gate passes a superset and the blur keeps the order: lo holds hi
    if cv2.countNonZero(lo) == cv2.countNonZero(hi):
        return mask
    n_hi, lab_hi, stats = components_with_stats(hi)
    _, lab_lo = cv2.connectedComponents(lo, connectivity=8)
    boxes: dict = {}                 # dim blob -> its bright pixels' box (x0, y0, x1, y1)
    count: dict = {}
    # the dim blob of each bright blob: the one at its first pixel (compiled: one pass)
    keys = label_at_first_pixel(lab_hi, n_hi, lab_lo).tolist()
    for key, (x, y, w, h, _) in zip(keys[1:], stats.tolist()[1:]):
        b = boxes.get(key)
        count[key] = count.get(key, 0) + 1
        boxes[key] = (x, y, x + w, y + h) if b is None else (
            min(b[0], x), min(b[1], y), max(b[2], x + w), max(b[3], y + h))
    out = mask.copy()
    sub_out = out[win]
    for key, (x0, y0, x1, y1) in boxes.items():
        if key == 0 or count[key] < 2:
            continue
        sl = (slice(y0, y1), slice(x0, x1))
        sub_out[sl][lab_lo[sl] == key] = 255
    return out


class MaskMixin:
    """The detector's colour-mask pass and its colour-balanced windows."""

    def _pass(self, small: np.ndarray, bgr: np.ndarray, region: tuple, thr_full: np.ndarray,
              s: int, thr_base: np.ndarray, lboxes: list,
              limit: Optional[list] = None) -> list[Candidate]:
        """One detection pass over ``region`` (mask coordinates) with thresholds ``thr_full``.

        ``limit``: only pixels inside these mask-coordinate boxes may form blobs.
        """
        cfg = self.config
        cx0, cy0, cx1, cy1 = region
        crop = small[cy0:cy1, cx0:cx1]
        if crop.size == 0:
            return []
        if self._gains is not None:
            crop = apply_gains(crop, self._gains)
        keep = None
        if limit:
            keep = np.zeros(crop.shape[:2], np.uint8)
            for x0, y0, x1, y1 in limit:
                keep[max(0, y0 - cy0):max(0, y1 - cy0), max(0, x0 - cx0):max(0, x1 - cx0)] = 255
        thr = thr_full[cy0:cy1, cx0:cx1]
        hsv = cv2.cvtColor(crop, cv2.COLOR_BGR2HSV)
        if limit is None and crop.shape[:2] == small.shape[:2]:
            self.frame_view = (small, hsv)          # the whole frame: others may reuse it
        cands: list[Candidate] = []
        if cfg.method == 'learned':
            h, sat, v = cv2.split(hsv)
            idx = cv2.merge([sat, h]).view(np.uint16)[..., 0]      # h * 256 + s
            for color in self.colors:
                if color == 'orange' and self._sat_tab is not None:
                    idx_c = cv2.merge([cv2.LUT(sat, self._sat_tab), h]).view(np.uint16)[..., 0]
                else:
                    idx_c = idx
                prob = full = flat_take(self._lut_u8[color], idx_c)
                if self._vmin[color] > 0:
                    # brightness gate outside the table: too dark for a reliable hue
                    prob = full & cv2.threshold(v, self._vmin[color] - 1, 255,
                                                cv2.THRESH_BINARY)[1]
                if cfg.smooth_px > 1:
                    # denoise at the mask's resolution before thresholding: isolated
                    # orange-hued pixels (dusk sky, sensor noise) are averaged away
                    prob = cv2.blur(prob, (cfg.smooth_px, cfg.smooth_px))
                mask = cv2.compare(prob, thr, cv2.CMP_GE)
                if self._vmin[color] > 0 and cfg.v_hysteresis > 0 and cv2.countNonZero(mask):
                    # (the lower gate only when there is a blob to rejoin)
                    prob_lo = full & cv2.threshold(
                        v, int(cfg.v_hysteresis * self._vmin[color]) - 1, 255,
                        cv2.THRESH_BINARY)[1]
                    mask = _hysteresis(mask, prob_lo, thr, cfg.smooth_px)
                if keep is not None:
                    mask &= keep
                grow = (prob, thr, keep) if color == 'orange' and cfg.grow_level > 0 \
                    else None
                cands += self._blobs(mask, bgr, color, (cx0, cy0), s, thr_base, lboxes,
                                     grow=grow)
        elif cfg.method == 'hsv':
            for color in self.colors:
                mask = np.zeros(hsv.shape[:2], np.uint8)
                for h_lo, h_hi, s_lo, v_lo in HSV_RANGES[color]:
                    mask |= cv2.inRange(hsv, (h_lo, s_lo, v_lo), (h_hi, 255, 255))
                if keep is not None:
                    mask &= keep
                cands += self._blobs(mask, bgr, color, (cx0, cy0), s, thr_base, lboxes)
        else:
            count = self.rgb_lp.mask(crop)
            if keep is not None:
                count = np.where(keep > 0, count, 0).astype(count.dtype)
            cands += self._mser_blobs(count, bgr, (cx0, cy0), s)
        return cands

    def _window(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int
                ) -> tuple[np.ndarray, int, int]:
        """``bgr[y0:y1, x0:x1]`` clipped to the frame and colour-balanced, and the clipped
        window's origin."""
        H, W = bgr.shape[:2]
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(W, x1), min(H, y1)
        win = bgr[y0:y1, x0:x1]
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        return win, x0, y0

    def _value(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int,
               luma: bool = False) -> tuple[np.ndarray, int, int]:
        """The HSV value (max of the colour-balanced B, G, R), or with ``luma`` the luma
        (a weighted sum: linear in a blend of two colours, as the edge model is), of
        ``bgr[y0:y1, x0:x1]`` clipped to the frame, and the clipped window's origin."""
        win, x0, y0 = self._window(bgr, x0, y0, x1, y1)
        if luma:
            return cv2.cvtColor(np.ascontiguousarray(win), cv2.COLOR_BGR2GRAY), x0, y0
        return cv2.max(cv2.max(win[..., 0], win[..., 1]), win[..., 2]), x0, y0

    def _orange_like(self, hsv: np.ndarray) -> np.ndarray:
        """The orange table's likelihood of each pixel of ``hsv`` (0 below its brightness
        floor)."""
        i = self._idx['orange']
        return gated_likelihood(self.model.luts[i], hsv,
                                _SAME if self._sat_tab is None else self._sat_tab,
                                int(self.model.v_min[i]))

    def _sat(self, hsv: np.ndarray) -> np.ndarray:
        """The saturation channel as the orange table sees it (frame-normalised)."""
        s = hsv[..., 1]
        return s if self._sat_tab is None else cv2.LUT(s, self._sat_tab)

    def _chroma(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int
                ) -> tuple[np.ndarray, int, int]:
        """The chroma R - B (float32, colour-balanced; linear in a blend of two colours) of
        ``bgr[y0:y1, x0:x1]`` clipped to the frame, and the clipped window's origin."""
        win, x0, y0 = self._window(bgr, x0, y0, x1, y1)
        return win[..., 2].astype(np.float32) - win[..., 0].astype(np.float32), x0, y0
