"""Boxplots of a frequency-set study like the paper's Fig. 4c, drawn with OpenCV (no matplotlib needed).

One PNG per classical method; one panel per noise level; in each panel one box per model of the sets
(S1 ... S5) and one for the classical method ("Tra"), each summarizing that model's accuracies at the
test frequencies: the box spans the quartiles, the line is the median, the whiskers reach the minimum and
maximum, the diamond is the mean.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .study_report import accuracy_by_frequency

__all__ = ["draw_boxplot_panels", "write_boxplots"]

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_BLACK, _GREY, _LIGHT = (0, 0, 0), (150, 150, 150), (225, 225, 225)
_BOX = (200, 140, 60)  # BGR: a blue
_TRA = (60, 60, 200)  # BGR: a red for the classical method


def _ticks(low: float, high: float) -> tuple[float, float, float]:
    """Axis range and a round tick step covering ``[low, high]`` (percent)."""
    span = max(high - low, 1.0)
    step = next(s for s in (0.5, 1, 2, 5, 10, 20, 25) if span / s <= 8)
    return np.floor(low / step) * step, np.ceil(high / step) * step, float(step)


def draw_boxplot_panels(panels, title: str, *, panel_height: int = 360) -> np.ndarray:
    """Draw side-by-side boxplot panels into a BGR image.

    Parameters
    ----------
    panels : list of (str, list of (str, array))
        Panel title and its boxes: label and values in percent (any length >= 1).
    title : str
    panel_height : int
        Pixels of the plotting area.

    Returns
    -------
    ndarray (H, W, 3) uint8
    """
    values = np.concatenate([np.asarray(v, float).ravel() for _, boxes in panels for _, v in boxes])
    if values.size == 0:
        raise ValueError("boxplot: no values to draw")
    low, high, step = _ticks(float(values.min()), float(values.max()))
    left, top, bottom, box_px, gap = 64, 56, 44, 34, 22
    widths = [len(boxes) * (box_px + gap) + gap for _, boxes in panels]
    width = max(left + sum(widths) + 16 * len(panels), left + cv2.getTextSize(title, _FONT, 0.6, 1)[0][0] + 16)
    image = np.full((top + panel_height + bottom, width, 3), 255, np.uint8)

    def y_of(v):
        return int(round(top + (high - v) / (high - low) * panel_height))

    cv2.putText(image, title, (left, 24), _FONT, 0.6, _BLACK, 1, cv2.LINE_AA)
    for v in np.arange(low, high + step / 2, step):
        y = y_of(v)
        cv2.line(image, (left - 4, y), (width - 8, y), _LIGHT, 1)
        cv2.putText(image, f"{v:g}", (6, y + 4), _FONT, 0.4, _BLACK, 1, cv2.LINE_AA)
    cv2.putText(image, "acc. %", (6, top - 10), _FONT, 0.4, _BLACK, 1, cv2.LINE_AA)
    x0 = left
    for (panel_title, boxes), panel_width in zip(panels, widths):
        cv2.rectangle(image, (x0, top), (x0 + panel_width, top + panel_height), _GREY, 1)
        cv2.putText(image, panel_title, (x0 + 4, top - 10), _FONT, 0.45, _BLACK, 1, cv2.LINE_AA)
        for i, (label, data) in enumerate(boxes):
            data = np.asarray(data, float).ravel()
            q1, median, q3 = np.percentile(data, [25, 50, 75])
            cx = x0 + gap + i * (box_px + gap) + box_px // 2
            color = _TRA if label == "Tra" else _BOX
            cv2.line(image, (cx, y_of(data.max())), (cx, y_of(data.min())), _BLACK, 1)
            for end in (data.min(), data.max()):
                cv2.line(image, (cx - box_px // 4, y_of(end)), (cx + box_px // 4, y_of(end)), _BLACK, 1)
            cv2.rectangle(image, (cx - box_px // 2, y_of(q3)), (cx + box_px // 2, y_of(q1)), color, -1)
            cv2.rectangle(image, (cx - box_px // 2, y_of(q3)), (cx + box_px // 2, y_of(q1)), _BLACK, 1)
            cv2.line(image, (cx - box_px // 2, y_of(median)), (cx + box_px // 2, y_of(median)), _BLACK, 2)
            ym = y_of(data.mean())
            diamond = np.array([[cx, ym - 4], [cx + 4, ym], [cx, ym + 4], [cx - 4, ym]], np.int32)
            cv2.fillPoly(image, [diamond], (255, 255, 255))
            cv2.polylines(image, [diamond], True, _BLACK, 1)
            size = cv2.getTextSize(label, _FONT, 0.45, 1)[0]
            cv2.putText(image, label, (cx - size[0] // 2, top + panel_height + 18), _FONT, 0.45, _BLACK, 1,
                        cv2.LINE_AA)
        x0 += panel_width + 16
    return image


def write_boxplots(rows, records, out_dir) -> list[Path]:
    """``boxplot-<method>.png`` per method: the set runs and the classical method, one panel per noise level."""
    table = accuracy_by_frequency(rows)
    set_runs = [r["name"] for r in records if r["role"] == "set"]
    paths = []
    for method in sorted({r.method for r in rows}):
        panels = []
        for noise in sorted({r.noise for r in rows if r.method == method}):
            boxes = []
            for run, label in [("classical", "Tra")] + [(n, n) for n in set_runs]:
                values = table.get((run, method, noise))
                if values:
                    boxes.append((label, [100 * v for v in values.values()]))
            if boxes:
                panels.append((f"noise {noise:g} gray levels", boxes))
        if not panels:
            continue
        frequencies = sorted({r.frequency for r in rows if r.method == method})
        image = draw_boxplot_panels(panels, f"{method.upper()}: accuracy over {len(frequencies)} test frequencies "
                                            f"({frequencies[0]:g}-{frequencies[-1]:g})")
        path = Path(out_dir) / f"boxplot-{method}.png"
        if not cv2.imwrite(str(path), image):
            raise OSError(f"{path}: could not write the PNG")
        paths.append(path)
    return paths
