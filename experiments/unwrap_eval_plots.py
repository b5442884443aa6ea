"""The figures of ``dptpu eval unwrap``, drawn with OpenCV (no matplotlib): an accuracy heatmap like the paper's
Fig. 4b and error-rate-versus-frequency curves like its Fig. 6.

Both take the evaluator's rows (:class:`dptpu.models.evaluate.Row`) and return a BGR ``uint8`` image; the sizes
follow from the number of frequencies, method/noise rows and solvers (:func:`heatmap_size`, :func:`error_plot_size`).
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

__all__ = [
    "SOLVER_COLOURS",
    "accuracy_heatmap",
    "error_plot_size",
    "error_versus_frequency",
    "heatmap_size",
    "write_png",
]

# Heatmap layout, pixels.
_LABEL_W, _CELL_W, _CELL_H, _TITLE_H, _HEADER_H, _BAR_H, _MARGIN = 130, 46, 24, 28, 22, 44, 10
# Accuracy range of the heatmap's colour scale (below: the darkest colour).
_ACCURACY_FLOOR = 0.5
# Error plot layout, pixels: one panel per (method, noise); panels in a grid of methods x noise levels.
_PANEL_W, _PANEL_H, _AXIS_L, _AXIS_B, _AXIS_T, _AXIS_R, _LEGEND_H = 380, 260, 56, 40, 30, 14, 34
# Error-rate axis: log10 of percent from 0.01 % to 100 % (0 errors are drawn at the bottom).
_LOG_ERR_MIN, _LOG_ERR_MAX = -2.0, 2.0
#: Line colours (BGR) of the solvers, in legend order; other solvers cycle through _EXTRA.
SOLVER_COLOURS = {"classical": (40, 40, 220), "classical+median": (0, 150, 255), "dptpu": (170, 90, 0),
                  "unet": (60, 160, 60)}
_EXTRA = ((160, 60, 160), (120, 120, 0), (0, 90, 160))
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _noise_label(noise: float, levels: list[float]) -> str:
    """``1 sigma`` / ``2 sigma`` for the levels in ascending order when they are the paper's 1:2 pair."""
    levels = sorted(levels)
    if len(levels) == 2 and abs(levels[1] - 2 * levels[0]) < 1e-3 * levels[1]:
        return "1 sigma" if noise == levels[0] else "2 sigma"
    return f"sigma {noise:g}"


def _axes(rows):
    """Sorted frequencies, (method, noise) row keys in paper order, solvers in row order, accuracy lookup."""
    frequencies = sorted({r.frequency for r in rows})
    methods = [m for m in ("mf", "mw", "nt") if any(r.method == m for r in rows)]
    noises = sorted({r.noise for r in rows})
    keys = [(m, n) for m in methods for n in noises]
    solvers = list(dict.fromkeys(r.solver for r in rows))
    accuracy = {(r.method, r.noise, r.solver, r.frequency): r.accuracy for r in rows}
    return frequencies, keys, noises, solvers, accuracy


def heatmap_size(n_frequencies: int, n_rows: int, n_solvers: int) -> tuple[int, int]:
    """``(width, height)`` in pixels of :func:`accuracy_heatmap`'s image."""
    width = _LABEL_W + n_frequencies * _CELL_W + _MARGIN
    height = n_solvers * (_TITLE_H + _HEADER_H + n_rows * _CELL_H) + _BAR_H
    return width, height


def _colour(accuracy: float) -> tuple[int, int, int]:
    level = np.clip((accuracy - _ACCURACY_FLOOR) / (1.0 - _ACCURACY_FLOOR), 0.0, 1.0)
    pixel = cv2.applyColorMap(np.array([[round(255 * float(level))]], np.uint8), cv2.COLORMAP_VIRIDIS)[0, 0]
    blue, green, red = (int(v) for v in pixel)  # BGR
    return blue, green, red


def _text(image, text, origin, scale=0.4, colour=(0, 0, 0), thickness=1):
    cv2.putText(image, text, (int(origin[0]), int(origin[1])), _FONT, scale, colour, thickness, cv2.LINE_AA)


def accuracy_heatmap(rows, *, title_prefix: str = "") -> np.ndarray:
    """Accuracy per (method, noise) row and frequency column, one panel per solver (like Fig. 4b).

    Parameters
    ----------
    rows : list of dptpu.models.evaluate.Row
    title_prefix : str
        Text before each panel's solver name.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        BGR image of :func:`heatmap_size`; cells show the accuracy in percent (``n/t``: the solver was not
        trained for the method), colour from 50 % (dark) to 100 % (bright, viridis).
    """
    frequencies, keys, noises, solvers, accuracy = _axes(rows)
    width, height = heatmap_size(len(frequencies), len(keys), len(solvers))
    image = np.full((height, width, 3), 255, np.uint8)
    y = 0
    for solver in solvers:
        _text(image, f"{title_prefix}{solver}", (_MARGIN, y + 19), 0.55, thickness=1)
        y += _TITLE_H
        for j, f in enumerate(frequencies):
            _text(image, f"{f:g}", (_LABEL_W + j * _CELL_W + 12, y + 16), 0.4)
        _text(image, "f_h", (_MARGIN, y + 16), 0.4)
        y += _HEADER_H
        for method, noise in keys:
            _text(image, f"{method.upper()} {_noise_label(noise, noises)}", (_MARGIN, y + 16), 0.4)
            for j, f in enumerate(frequencies):
                x0 = _LABEL_W + j * _CELL_W
                value = accuracy.get((method, noise, solver, f))
                fill = (215, 215, 215) if value is None else _colour(value)
                cv2.rectangle(image, (x0, y), (x0 + _CELL_W - 2, y + _CELL_H - 2), fill, -1)
                if value is None:
                    label, ink = "n/t", (90, 90, 90)
                else:
                    label = f"{100 * value:.1f}" if value < 0.9995 else "100"
                    ink = (0, 0, 0) if value > _ACCURACY_FLOOR + 0.6 * (1 - _ACCURACY_FLOOR) else (255, 255, 255)
                _text(image, label, (x0 + 5, y + 16), 0.38, ink)
            y += _CELL_H
    _colour_bar(image, y)
    return image


def _colour_bar(image, y):
    x0, x1 = _LABEL_W, image.shape[1] - _MARGIN
    for x in range(x0, x1):
        accuracy = _ACCURACY_FLOOR + (1 - _ACCURACY_FLOOR) * (x - x0) / max(x1 - x0 - 1, 1)
        cv2.line(image, (x, y + 8), (x, y + 22), _colour(accuracy), 1)
    _text(image, "accuracy", (_MARGIN, y + 20), 0.4)
    _text(image, f"<={100 * _ACCURACY_FLOOR:.0f}%", (x0, y + 38), 0.38)
    _text(image, "100%", (x1 - 36, y + 38), 0.38)


def error_plot_size(n_methods: int, n_noises: int) -> tuple[int, int]:
    """``(width, height)`` in pixels of :func:`error_versus_frequency`'s image."""
    return n_methods * _PANEL_W, _LEGEND_H + n_noises * _PANEL_H


def _solver_colour(solver: str, solvers: list[str]) -> tuple[int, int, int]:
    if solver in SOLVER_COLOURS:
        return SOLVER_COLOURS[solver]
    others = [s for s in solvers if s not in SOLVER_COLOURS]
    return _EXTRA[others.index(solver) % len(_EXTRA)]


def error_versus_frequency(rows) -> np.ndarray:
    """Error rate (1 - accuracy, log scale, percent) versus f_h per solver; one panel per method and noise (Fig. 6).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        BGR image of :func:`error_plot_size` (methods across, noise levels down); a legend on top.
    """
    frequencies, keys, noises, solvers, accuracy = _axes(rows)
    methods = list(dict.fromkeys(m for m, _ in keys))
    width, height = error_plot_size(len(methods), len(noises))
    image = np.full((height, width, 3), 255, np.uint8)
    x = 10
    for solver in solvers:
        colour = _solver_colour(solver, solvers)
        cv2.line(image, (x, 17), (x + 26, 17), colour, 2, cv2.LINE_AA)
        _text(image, solver, (x + 32, 22), 0.45)
        x += 44 + 10 * len(solver)
    _text(image, "error rate (1 - accuracy), log scale", (width - 300, 22), 0.45)
    f_lo, f_hi = frequencies[0], frequencies[-1]
    span = max(f_hi - f_lo, 1e-9)
    for col, method in enumerate(methods):
        for row, noise in enumerate(noises):
            left, top = col * _PANEL_W + _AXIS_L, _LEGEND_H + row * _PANEL_H + _AXIS_T
            right, bottom = (col + 1) * _PANEL_W - _AXIS_R, _LEGEND_H + (row + 1) * _PANEL_H - _AXIS_B

            box = (left, top, right, bottom)

            def to_px(f, error, box=box):
                x0, y0, x1, y1 = box
                log = np.log10(max(100.0 * error, 10 ** _LOG_ERR_MIN))
                u = x0 + (x1 - x0) * ((f - f_lo) / span if len(frequencies) > 1 else 0.5)
                v = y1 - (y1 - y0) * (log - _LOG_ERR_MIN) / (_LOG_ERR_MAX - _LOG_ERR_MIN)
                return round(float(u)), round(float(v))

            _text(image, f"{method.upper()}, {_noise_label(noise, noises)}", (left, top - 10), 0.45)
            for k in range(int(_LOG_ERR_MIN), int(_LOG_ERR_MAX) + 1):
                _, v = to_px(f_lo, 10.0 ** k / 100.0)
                cv2.line(image, (left, v), (right, v), (225, 225, 225), 1)
                _text(image, f"{10.0 ** k:g}%", (left - 50, v + 4), 0.35)
            for f in frequencies:
                u, _ = to_px(f, 1.0)
                cv2.line(image, (u, bottom), (u, bottom + 4), (0, 0, 0), 1)
                if len(frequencies) <= 6 or (f - f_lo) % 16 == 0:
                    _text(image, f"{f:g}", (u - 8, bottom + 18), 0.35)
            cv2.rectangle(image, (left, top), (right, bottom), (0, 0, 0), 1)
            _text(image, "f_h", (right - 22, bottom + 34), 0.38)
            for solver in solvers:
                points = [to_px(f, 1.0 - accuracy[(method, noise, solver, f)]) for f in frequencies
                          if (method, noise, solver, f) in accuracy]
                colour = _solver_colour(solver, solvers)
                if len(points) > 1:
                    cv2.polylines(image, [np.array(points, np.int32)], False, colour, 2, cv2.LINE_AA)
                for p in points:
                    cv2.circle(image, p, 3, colour, -1, cv2.LINE_AA)
    return image


def write_png(image: np.ndarray, path) -> Path:
    """Write a BGR image as PNG; OSError naming the file if OpenCV cannot."""
    path = Path(path)
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: OpenCV could not write the PNG")
    return path
