"""Helpers shared by the evaluation and training tools: JSON, contact sheets, seed lists."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

import cv2
import numpy as np

__all__ = ['json_default', 'print_json', 'tile_grid', 'write_contact_sheet', 'seed_list']


def json_default(o):
    """``json.dumps(..., default=json_default)``: numpy arrays as lists, numpy scalars as
    Python numbers.

    Raises:
        TypeError: any other type (as ``json.dumps`` expects of ``default``).
    """
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(type(o).__name__)



def print_json(report: Any, path: Optional[str] = None,
               default: Callable[[Any], Any] = json_default) -> str:
    """Prints ``report`` as indented JSON, also writes it to ``path`` when one is given, and
    returns the text (a tool's ``--json OUT``)."""
    text = json.dumps(report, indent=2, default=default)
    print(text)
    if path:
        Path(path).write_text(text)
    return text

def tile_grid(tiles: Sequence[np.ndarray], cols: int, fill: int = 0) -> np.ndarray:
    """Equal-sized tiles in rows of ``cols``, the last row padded with ``fill`` tiles.

    Args:
        tiles: at least one image, all of the same shape.
        cols: tiles per row.
        fill: value of the padding tiles.

    Returns:
        The grid as one image.
    """
    tiles = list(tiles) + [np.full_like(tiles[0], fill)] * (-len(tiles) % cols)
    rows = [np.hstack(tiles[i:i + cols]) for i in range(0, len(tiles), cols)]
    return np.vstack(rows)


def write_contact_sheet(tiles: Sequence[np.ndarray], path: str | Path, cols: int = 3,
                        width: Optional[int] = None, scale: float = 1.0) -> bool:
    """Write frames as a grid image (a contact sheet), creating the folder.

    Args:
        tiles: BGR frames; each is resized to the first one's aspect ratio.
        path: the image file to write (PNG, JPEG, ... by its suffix).
        cols: frames per row.
        width: width of each tile in pixels (default: the first frame's).
        scale: the whole sheet is resized by this factor (area interpolation) before writing.

    Returns:
        Whether a sheet was written (nothing is written for no tiles).
    """
    if not tiles:
        return False
    h0, w0 = tiles[0].shape[:2]
    w = w0 if width is None else int(width)
    h = int(w * h0 / w0)
    sheet = tile_grid([cv2.resize(t, (w, h)) for t in tiles], cols)
    if scale != 1.0:
        sheet = cv2.resize(sheet, (int(sheet.shape[1] * scale), int(sheet.shape[0] * scale)),
                           interpolation=cv2.INTER_AREA)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), sheet)
    return True


def seed_list(text: str) -> list[int]:
    """A command line's seeds: ``'300-319'`` or ``'1,2,5'`` (or both, comma-separated)."""
    out: list[int] = []
    for part in text.split(','):
        lo, _, hi = part.partition('-')
        out += list(range(int(lo), int(hi) + 1)) if hi else [int(lo)]
    return out
