"""PNG figures of the diagnosis, drawn with OpenCV (no plotting library is a dependency).

- :func:`map_figure`: signed maps (NaN = not measured) side by side, a diverging colour scale symmetric about 0
  (blue negative, red positive), each panel titled with its RMS;
- :func:`profile_figure`: curves over a common x range (a profile per panel), with a zero line.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

__all__ = ["map_figure", "profile_figure"]

_FONT_SCALE = 0.4


def _panel(image: np.ndarray, title: str, scale: float, height: int) -> np.ndarray:
    finite = np.isfinite(image)
    normalized = np.clip(np.where(finite, image, 0.0) / max(scale, 1e-12), -1.0, 1.0)  # [-1, 1]
    red = np.clip(1.0 + np.minimum(normalized, 0.0), 0.0, 1.0)
    blue = np.clip(1.0 - np.maximum(normalized, 0.0), 0.0, 1.0)
    green = 1.0 - np.abs(normalized)
    rgb = np.stack([blue, green, red], axis=-1)  # BGR: white at 0, red +, blue -
    rgb[~finite] = 0.5
    panel: np.ndarray = (rgb * 255).astype(np.uint8)
    zoom = max(1, height // image.shape[0])
    panel = cv2.resize(panel, (image.shape[1] * zoom, image.shape[0] * zoom), interpolation=cv2.INTER_NEAREST)
    banner = np.full((18, panel.shape[1], 3), 255, np.uint8)
    cv2.putText(banner, title, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, _FONT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([banner, panel])


def map_figure(path, maps: dict, *, unit: str, scale: float | None = None, height: int = 240) -> Path:
    """Panels of signed maps ``{title: (H, W)}`` in one row; the colour scale is +-``scale`` (default 3x the
    largest RMS)."""
    rms = {k: float(np.sqrt(np.nanmean(v ** 2))) if np.isfinite(v).any() else 0.0 for k, v in maps.items()}
    scale = scale or 3.0 * max(max(rms.values(), default=0.0), 1e-9)
    panels = [_panel(v, f"{k}: {rms[k]:.3g} {unit}", scale, height) for k, v in maps.items()]
    rows = max(p.shape[0] for p in panels)
    panels = [np.vstack([p, np.full((rows - p.shape[0], p.shape[1], 3), 255, np.uint8)]) for p in panels]
    figure = np.hstack([np.hstack([p, np.full((rows, 6, 3), 255, np.uint8)]) for p in panels])
    footer = np.full((18, figure.shape[1], 3), 255, np.uint8)
    cv2.putText(footer, f"colour: -{scale:.3g} (blue) .. +{scale:.3g} (red) {unit}; grey: not measured", (3, 13),
                cv2.FONT_HERSHEY_SIMPLEX, _FONT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
    path = Path(path)
    cv2.imwrite(str(path), np.vstack([figure, footer]))
    return path


def profile_figure(path, profiles: dict, *, x_label: str, unit: str, size=(320, 200)) -> Path:
    """One panel per ``{title: y (M,)}`` profile, x from 0 to 1 over the samples."""
    width, height = size
    panels = []
    for title, values in profiles.items():
        y = np.asarray(values, dtype=np.float64)
        panel = np.full((height, width, 3), 255, np.uint8)
        top = float(np.nanmax(np.abs(y))) if y.size and np.isfinite(y).any() else 1.0
        top = top or 1.0
        margin = 24
        xs = margin + (np.arange(len(y)) + 0.5) / max(len(y), 1) * (width - 2 * margin)
        ys = height / 2 - np.nan_to_num(y) / top * (height / 2 - margin)
        cv2.line(panel, (margin, height // 2), (width - margin, height // 2), (180, 180, 180), 1)
        points = np.stack([xs, ys], axis=1).astype(np.int32)
        cv2.polylines(panel, [points], False, (200, 60, 0), 1, cv2.LINE_AA)
        cv2.putText(panel, title, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, _FONT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(panel, f"+-{top:.3g} {unit}; x: {x_label}", (3, height - 6), cv2.FONT_HERSHEY_SIMPLEX,
                    _FONT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
        panels.append(panel)
    path = Path(path)
    cv2.imwrite(str(path), np.hstack(panels) if panels else np.full((height, width, 3), 255, np.uint8))
    return path
