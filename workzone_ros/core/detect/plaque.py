"""The two-colour plaque extension (orange top, white bottom).

A wide orange rectangle with white rows under it (R22-1, R2-1 + G20-5aP) is extended down
over its white part: the white rows (across a black legend's rows) decide how far, its black
bottom border ends it, the catalogue's height / width chooses among several dark rows.
"""
from __future__ import annotations

import cv2
import numpy as np

from workzone_ros.core.color_model import apply_gains
from workzone_ros.core.detect.candidates import Candidate
from workzone_ros.core.signs import CATALOGUE

__all__ = ['PlaqueMixin']


# height / width of the catalogue's orange-top, white-bottom signs (R22-1, R2-1 + G20-5aP)
_TWO_COLOUR_RATIOS = tuple(sorted({c.height_m / c.width_m for c in CATALOGUE
                                   if c.regulatory_two_color}))


def _ratio_error(heights: np.ndarray, width: float) -> np.ndarray:
    """Per height: the relative difference of ``height / width`` to the nearest two-colour
    sign's height / width in the catalogue."""
    return np.min(np.abs(np.asarray(heights, float)[:, None] / width
                         / np.array(_TWO_COLOUR_RATIOS)[None, :] - 1.0), axis=1)


def _dark_share(value: np.ndarray, rel: float) -> np.ndarray:
    """Per row of the brightness ``value`` of a strip under a two-colour sign's orange part:
    the share of its middle columns (its outer tenth on each side left out: the strip may
    reach past the sign) darker than ``rel`` x the strip's 90th percentile (the white
    sheeting's level)."""
    w = value.shape[1]
    m = max(1, w // 10)
    ref = float(np.percentile(value, 90))
    return (value[:, m:w - m] < rel * ref).mean(axis=1)


def _bands(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first and last row of each run of consecutive rows in the sorted ``rows``."""
    brk = np.diff(rows) > 1
    return rows[np.insert(brk, 0, True)], rows[np.append(brk, True)]


class PlaqueMixin:
    """The detector's two-colour extension."""

    def _extend(self, bgr: np.ndarray, cand: Candidate, orange_hsv: np.ndarray) -> None:
        """Seo et al.'s regulatory two-colour extension: grow the box over a white bottom."""
        cfg = self.config
        H = bgr.shape[0]
        x0, x1 = int(cand.x), int(cand.x + cand.w)
        y_top = int(cand.y + cand.h)
        # reach: ``ext_max_ratio`` x the orange height, or (a thin plaque over a tall white
        # sign, R2-1 + G20-5aP) up to ``ext_max_wratio`` x the width
        y_max = min(H, int(y_top + max(cfg.ext_max_ratio * cand.h, cfg.ext_max_wratio * cand.w)))
        if y_max - y_top < 2:
            return
        strip = bgr[y_top:y_max, max(0, x0):x1]
        if strip.size == 0:
            return
        raw_s = None
        if self._gains is not None:
            # white is judged both as the camera balanced it and after the grey-world gains:
            # the gains remove a dusk cast from white sheeting, but under a blue sky they
            # tint white sheeting yellow (S ~ 40..60) and the white part would be lost
            raw_s = cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)[..., 1]
            strip = apply_gains(strip, self._gains)
        strip = cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)
        sat = strip[..., 1] if raw_s is None else np.minimum(strip[..., 1], raw_s)
        v_ref = float(np.median(orange_hsv[:, 2])) if orange_hsv.size else 200.0
        white = (sat <= cfg.white_s_max) & (strip[..., 2] >= cfg.white_v_rel * v_ref)
        # black legend rows inside the white part: judge rows on a short running window
        frac = white.mean(axis=1)
        k = max(1, int(round(cand.h * 0.25)))
        gap = max(k, int(round(cfg.ext_gap_w * cand.w)))
        run = self._white_run(frac, strip, sat, v_ref, k, gap)
        if cfg.white_own_rel > 0 and y_top + run >= y_max - 1:
            # white to the end of the reach: the sign's own white part (bright sheeting)
            # may be followed by a duller grey background that passed for white by the
            # orange's level (under a grey sky a dull orange is little brighter than the
            # road, verge or snow): judged again against the white part's own level, the
            # part ends at the sign's bottom, and the rest of the reach (a few rows at
            # least) is not white (a background as bright as the sheeting, snow, is left to
            # the bottom border)
            white2, frac2 = self._own_white(white, frac, strip[..., 2], k)
            run2 = self._white_run(frac2, strip, sat, v_ref, k, gap)
            if run2 >= 0.3 * cand.h and y_max - y_top - run2 >= max(3, 2 * k) \
                    and frac2[run2:].mean() < 0.3:
                white, frac, run = white2, frac2, run2
        if cfg.ext_frame and y_top + run >= y_max - 1:
            # white (or what the legend-gap rule bridged) to the end of the reach: snow, a
            # pale sky or wall behind the sign.  The white part ends with its black bottom
            # border
            end = self._bottom_border(white[:run], strip[:run, :, 2], cand.h, cand.w)
            if end:
                run = end
        if cfg.ext_overlong > 0 and y_top + run < y_max - 1 and cand.h + run > max(
                _TWO_COLOUR_RATIOS) * (1.0 + cfg.ext_overlong) * cand.w:
            # white far past any two-colour sign's height for the width, ending before the
            # reach: a pale wall right behind the sign (in rain as bright as white by the
            # orange's level) continued the white part past its black bottom border, which
            # the legend-gap rule bridged.  The part ends after the bridged row (under 45 %
            # white) that gives the height nearest a two-colour sign's, within
            # ``ext_overlong`` (the box is still grown by the blur here)
            low = np.flatnonzero(frac[:run] < 0.45)
            low = low[low + 1 >= 0.3 * cand.h]
            done = False
            if low.size:
                err = _ratio_error(cand.h + low + 1, cand.w)
                if err.min() <= cfg.ext_overlong:
                    run = int(low[int(np.argmin(err))]) + 1
                    done = True
            if not done and cfg.ext_overlong_border > 0:
                share = _dark_share(strip[:run, :, 2], cfg.ext_border_rel)
                rows = np.flatnonzero(share >= cfg.ext_overlong_border)
                rows = rows[rows + 1 >= 0.3 * cand.h]
                if rows.size:
                    cut = _bands(rows)[1] + 1            # the row after each dark band
                    err = _ratio_error(cand.h + cut, cand.w)
                    if err.min() <= cfg.ext_overlong:
                        run = int(cut[int(np.argmin(err))])
        if self.debug is not None:
            self.debug.append(dict(ext_run=run, ext_rows=y_max - y_top,
                                   ext_frac=np.round(frac, 2).tolist()))
        if run < 0.3 * cand.h or y_top + run >= y_max - 1:
            return              # too short, or no bottom edge found (sky, a white wall)
        # a sign's white part carries a black legend and border; sky and walls do not
        # (dark relative to the white part itself: under overcast light the legend is grey)
        part = strip[:run]
        v_white = float(np.median(part[..., 2][white[:run]])) if white[:run].any() else v_ref
        dark = part[..., 2] < cfg.dark_rel * v_white
        if dark.mean() < cfg.ext_min_dark:
            return
        cand.h = float(run + cand.h)
        cand.extended = True

    def _white_run(self, frac: np.ndarray, strip: np.ndarray, sat: np.ndarray, v_ref: float,
                   k: int, gap: int) -> int:
        """How many rows of the HSV ``strip`` under the orange part the white part runs
        (:meth:`_extend`): rows at least 45 % white (``frac``) on a running window of
        ``k`` rows, across rows of a black legend up to ``gap`` rows when they are
        achromatic (:meth:`_achromatic_rows`; ``sat``: the saturation as judged for white,
        ``v_ref``: the orange's brightness), less the rows at its end that are not white."""
        smooth = np.convolve(frac, np.ones(k) / k, mode='full')[:len(frac)]
        # rows of a large black legend (speed-limit numerals) are not white, but they are
        # achromatic like the sheeting around them: such rows may separate white rows by up
        # to ``ext_gap_w`` x the width (background rows, foliage or sky, are coloured)
        # (judged on the row's bright pixels: a dark legend stroke's saturation is noise, a
        # row of large numerals would otherwise look coloured)
        achrom = self._achromatic_rows(strip, sat, v_ref)
        run = 0
        for j, f in enumerate(smooth):
            if f >= 0.45 or (j < k and frac[: j + 1].mean() >= 0.45):
                run = j + 1
            elif j - run > k and (j - run > gap or not achrom[run:j + 1].all()):
                break
        # trim rows at the bottom that are not white themselves
        while run > 0 and frac[run - 1] < 0.3:
            run -= 1
        return run

    def _own_white(self, white: np.ndarray, frac: np.ndarray, value: np.ndarray, k: int
                   ) -> tuple[np.ndarray, np.ndarray]:
        """``white`` and its row shares ``frac`` with the pixels darker than
        ``white_own_rel`` x the white part's own level removed.  The level: the median
        brightness ``value`` of the white pixels in the strip's first white rows (from the
        first row at least 45 % white to the first after it that is not, at most ``k`` + 2
        rows: the part right under the orange one).  Unchanged when no row is white."""
        rows = np.flatnonzero(frac >= 0.45)
        if rows.size == 0:
            return white, frac
        r0 = int(rows[0])
        r1 = r0 + 1
        while r1 < len(frac) and r1 - r0 < k + 2 and frac[r1] >= 0.45:
            r1 += 1
        # (row r0 is at least 45 % white: the level has pixels to be taken from)
        level = float(np.median(value[r0:r1][white[r0:r1]]))
        white = white & (value >= self.config.white_own_rel * level)
        return white, white.mean(axis=1)

    def _achromatic_rows(self, strip: np.ndarray, sat: np.ndarray, v_ref: float
                         ) -> np.ndarray:
        """Per row of an HSV ``strip`` (``sat``: its saturation as judged for white): an
        achromatic row, like a large black legend's inside the white part; background rows
        (foliage, sky) are coloured.  Judged on the row's bright pixels (a dark legend
        stroke's saturation is noise: a row of large numerals would otherwise look
        coloured): their median saturation at most ``ext_gap_s``; or a bold legend row of a
        small sign ("BEGINS"), ink nearly across: too few bright pixels to judge by, but
        black (below ``dark_rel`` of the face's brightness ``v_ref``)."""
        cfg = self.config
        bright = strip[..., 2] >= 0.5 * v_ref
        n = np.count_nonzero(bright, axis=1)
        # the median of each row's bright pixels' saturation (numpy's nanmedian, sorted)
        srt = np.sort(np.where(bright, sat.astype(np.int32), 256), axis=1)
        rows = np.arange(len(n))
        med_b = 0.5 * (srt[rows, np.maximum(n - 1, 0) // 2] + srt[rows, n // 2])
        return ((n >= 3) & (med_b <= cfg.ext_gap_s)) | ((n < 3) & (
            np.median(strip[..., 2], axis=1) < cfg.dark_rel * v_ref))

    def _bottom_border(self, white: np.ndarray, value: np.ndarray, orange_h: float,
                       width: float = 0.0) -> int:
        """The row just after the white part's black bottom border (0: none seen).

        ``white``, ``value``: the white mask and brightness of the strip below the orange
        part.  A border row is dark (below ``dark_rel`` x the white sheeting's level, the
        strip's 90th percentile of brightness) across at least ``ext_border_share`` of
        the width (its outer tenth on each side left out: the strip may reach past the
        sign); a legend's strokes, however bold, leave gaps, but on a small blurred sign a
        bold legend row can look like a border too.  Of the border rows at least ``0.3``
        orange heights down, the one that makes the sign's height / ``width`` nearest a
        two-colour sign's in the catalogue (within ``ext_ratio_tol``) ends the white part,
        else the first.  The candidates: each dark band's last row and, for a band at least
        ``ext_band_long`` orange heights (and 3 rows) long, its first (the border line
        merged with a darker background below the sign).
        """
        cfg = self.config
        w = white.shape[1]
        if w < 4 or white.shape[0] < 2:
            return 0
        share = _dark_share(value, cfg.ext_border_rel)
        if self.debug is not None:
            self.debug.append(dict(border_share=np.round(share, 2).tolist()))
        rows = np.nonzero(share >= cfg.ext_border_share)[0]
        rows = rows[rows + 1 >= 0.3 * orange_h]
        if not rows.size:
            return 0
        if width > 0 and cfg.ext_ratio_tol > 0:
            # the row after each dark band (a border or a legend row is several rows) and,
            # for a long band (a background darker than the sheeting continuing the
            # bottom border), the row after its first
            starts, ends = _bands(rows)
            long = ends - starts + 1 >= max(3.0, cfg.ext_band_long * orange_h)
            cut = np.concatenate([ends + 1, starts[long] + 1])
            err = _ratio_error(orange_h + cut, width)
            if err.min() <= cfg.ext_ratio_tol:
                return int(cut[int(np.argmin(err))])
        return int(rows[0] + 1)
