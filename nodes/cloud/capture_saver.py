"""What the cloud node's ``~/capture_and_save`` service keeps and writes (pure logic and files, no sockets).

The service saves the last scan: its cloud as a point-cloud file (PLY or PCD, metres unless asked for millimetres,
with every field the cloud node publishes: ``intensity`` (the texture, also as grey colours), ``modulation``,
``confidence`` and the normals; :func:`dptpu.fpp.point_cloud_file.write_point_cloud`) and the camera frames it was
made of as a ``dptpu-capture/1`` folder (:func:`dptpu.fpp.capture.write_capture`, with the rig file as its
calibration), so the scan can be triangulated again offline (``dptpu triangulate``), unwrapped by another method or
kept as a test case.

:class:`RecentScanFrames` keeps the fringe frames of the last few scans by ``sequence_id`` (references to the
received frames, no copies); :func:`save_scan` writes one scan.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import Rig, save_rig
from dptpu.fpp.capture import PhaseFrames, write_capture
from dptpu.fpp.point_cloud_file import write_point_cloud
from dptpu.messages import FringeBurst, FringeFrame, Header, Image, PatternSequence, PointCloud2
from dptpu.messages.scanner import REFERENCE_KINDS

from .cloud_fields import NORMAL_FIELDS

__all__ = ["CLOUD_FORMATS", "CLOUD_UNITS", "RecentScanFrames", "SavedScan", "save_scan"]

#: File formats of the saved cloud (the suffix open3d writes).
CLOUD_FORMATS = ("ply", "pcd")
#: Units of the saved cloud's coordinates: metres (ROS's, the default) or millimetres.
CLOUD_UNITS = ("m", "mm")


class RecentScanFrames:
    """The fringe frames of the last ``kept_scans`` scans, by ``sequence_id`` then ``pattern_index``."""

    def __init__(self, kept_scans: int = 2):
        self.kept_scans = int(kept_scans)
        self._scans: OrderedDict[int, dict[int, FringeFrame]] = OrderedDict()

    def add(self, frame: FringeFrame) -> None:
        sequence_id = int(frame.trigger.sequence_id)
        scan = self._scans.get(sequence_id)
        if scan is None:
            scan = self._scans[sequence_id] = {}
            while len(self._scans) > self.kept_scans:
                self._scans.popitem(last=False)
        scan[int(frame.trigger.pattern_index)] = frame

    def add_burst(self, burst: FringeBurst) -> None:
        """Keep a burst's frames, each as the FringeFrame it stands for (views of the burst, no copy)."""
        if not burst.triggers:
            return
        if burst.image.encoding not in ("mono8", "mono16"):  # as the phase node, which refuses the scan
            raise ValueError(f"FringeBurst.image.encoding must be mono8 or mono16; got {burst.image.encoding!r}")
        frames = burst.frames()  # (N, H, W)
        last = len(burst.triggers) - 1
        for index, (trigger, image) in enumerate(zip(burst.triggers, frames)):  # stamps as the phase node takes them
            stamp = burst.image.header.stamp if index == last else trigger.header.stamp
            header = Header(stamp=stamp, frame_id=burst.image.header.frame_id)
            self.add(FringeFrame(image=Image.from_array(image, burst.image.encoding, header=header), trigger=trigger))

    def frames(self, sequence_id: int) -> list[FringeFrame]:
        """The frames of scan ``sequence_id`` in pattern order (empty when none was kept)."""
        scan = self._scans.get(int(sequence_id), {})
        return [scan[index] for index in sorted(scan)]


@dataclass(frozen=True)
class SavedScan:
    """Where one scan went: the cloud file (its point count) and the capture folder (None without frames)."""

    cloud_path: Path
    points: int
    capture_folder: Path | None


def save_scan(folder, cloud: PointCloud2, frames: list[FringeFrame], *, projector_size: tuple[int, int],
              fringe_axis: str = "x", cloud_format: str = "ply", layout: PatternSequence | None = None,
              rig: Rig | None = None, cloud_unit: str = "m") -> SavedScan:
    """Write ``cloud`` as ``folder/cloud.<cloud_format>`` (every field, in ``cloud_unit``) and ``frames`` as a
    capture folder ``folder/capture``.

    Parameters
    ----------
    folder : path-like
        Created if absent.
    cloud : PointCloud2
        The scan's cloud: ``x, y, z`` in metres; ``normal_x/y/z`` written as the file's normals; every other field
        under its name (``intensity`` also as grey colours, when it has a finite value).
    frames : list of FringeFrame
        The scan's fringe frames in pattern order; empty: no capture folder.
    projector_size : (int, int)
        The projector's ``(width, height)`` (the rig's), used without ``layout``.
    fringe_axis : {"x", "y"}
        The scan's (its AbsolutePhase's), used without ``layout``.
    cloud_format : {"ply", "pcd"}
    layout : PatternSequence, optional
        The projector's layout (phase offsets, shift sign, fringe axis, projector size); without it the paper's
        shift sign and no phase offsets. The triggers' frequency, steps and step place the frames either way.
    rig : Rig, optional
        The rig the cloud was triangulated with (the rig file, its camera as the camera's CameraInfo gave it: the
        frames' size and intrinsics), written as ``folder/calibration.yaml`` and copied into the capture as its
        calibration, so the capture replays (``source:=<folder>/capture``) with the frames' own camera; None: none.
    cloud_unit : {"m", "mm"}
        The unit of the cloud file's coordinates.

    Raises
    ------
    ValueError
        An unknown format, frames that do not make whole phase sequences, or a file that cannot be written.
    """
    if cloud_format not in CLOUD_FORMATS:
        raise ValueError(f"cloud format must be one of {', '.join(CLOUD_FORMATS)}; got {cloud_format!r}")
    if cloud_unit not in CLOUD_UNITS:
        raise ValueError(f"cloud unit must be one of {', '.join(CLOUD_UNITS)}; got {cloud_unit!r}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = [field.name for field in cloud.fields]
    points = cloud.to_array(["x", "y", "z"])  # (H, W, 3) metres
    normals = cloud.to_array(list(NORMAL_FIELDS)) if set(NORMAL_FIELDS) <= set(names) else None  # (H, W, 3)
    fields = {name: cloud.to_array([name])[..., 0] for name in names  # (H, W) each
              if name not in ("x", "y", "z") and name not in NORMAL_FIELDS}
    intensity = fields.get("intensity")
    if intensity is not None and not np.isfinite(intensity).any():
        intensity = None
    cloud_path = folder / f"cloud.{cloud_format}"
    count = write_point_cloud(cloud_path, points, unit="m", file_unit=cloud_unit, intensity=intensity,
                              normals=normals, fields=fields)
    capture_folder = None
    if frames:
        capture_folder = folder / "capture"
        if layout is not None:
            projector_size, fringe_axis = layout.projector_size, layout.fringe_axis
        rig_path = str(save_rig(rig, folder / "calibration.yaml")) if rig is not None else ""
        _write_frames(capture_folder, frames, layout, rig_path, projector_size, fringe_axis)
    return SavedScan(cloud_path, count, capture_folder)


def _write_frames(folder: Path, frames: list[FringeFrame], layout: PatternSequence | None, rig_path: str,
                  projector_size: tuple[int, int], fringe_axis: str) -> None:
    """The frames as phase sequences, entry by entry in projection order (the triggers' frequency and steps)."""
    entries: list[tuple[float, int, list]] = []  # (frequency, steps, images by step)
    references = {}  # "white" / "black" -> (H, W)
    for frame in frames:
        trigger = frame.trigger
        if trigger.kind in REFERENCE_KINDS:
            references[trigger.kind] = frame.image.to_array()
            continue
        if not entries or all(image is not None for image in entries[-1][2]):  # the last entry is complete
            if not trigger.steps:
                raise ValueError(f"frame of pattern {trigger.pattern_index} has no steps: cannot lay out the capture")
            entries.append((float(trigger.frequency), int(trigger.steps), [None] * int(trigger.steps)))
        frequency, steps, images = entries[-1]
        if float(trigger.frequency) != frequency or int(trigger.steps) != steps or images[trigger.step] is not None:
            raise ValueError(f"frame of pattern {trigger.pattern_index} (f={trigger.frequency:g}, step "
                             f"{trigger.step} of {trigger.steps}) does not continue the sequence f={frequency:g}")
        images[trigger.step] = frame.image.to_array()
    expected = int(frames[-1].trigger.pattern_count)
    if any(image is None for _, _, images in entries for image in images) or (expected and len(frames) != expected):
        raise ValueError(f"{len(frames)} of the scan's {expected or 'unknown number of'} frames were received: "
                         "not whole phase sequences")
    offsets = [entry.phase_offset for entry in layout.entries if not entry.is_reference] if layout is not None else []
    sequences = [PhaseFrames(images=np.stack(images), frequency=frequency,
                             phase_offset=float(offsets[index]) if index < len(offsets) else 0.0)
                 for index, (frequency, _, images) in enumerate(entries)]
    width, height = projector_size
    write_capture(folder, sequences=sequences, projector_size=(int(width), int(height)), fringe_axis=fringe_axis,
                  phase_shift_sign=int(layout.shift_sign) if layout is not None else -1, calibration=rig_path or None,
                  references=references or None)
