"""The cloud node's ``~/capture_and_save`` service (std_srvs/Trigger): the last scan's cloud and frames to disk.

Parts the cloud node composes (its own parameters, subscriptions and service on the node it is given):

================================ ================ ===================================================================
name                             kind             meaning
================================ ================ ===================================================================
``~/capture_and_save``           service          std_srvs/Trigger: write the last scan (:func:`.capture_saver.
                                                  save_scan`) to ``save_dir/scan_<sequence_id>/``: ``cloud.ply`` (or
                                                  ``.pcd``; metres; every field of the cloud: intensity = texture,
                                                  modulation, confidence, normals) and ``capture/``
                                                  (``dptpu-capture/1``, with the rig as its calibration); ``message``
                                                  names what was written, or why nothing was (``success`` false)
``/camera/image_raw``            FringeFrame in   best effort, depth 100: the frames of the last scans (only with
                                                  ``save_frames``)
``/camera/frame_bursts``         FringeBurst in   the same, with ``frame_bursts`` (instead of the frames)
``/projector/pattern_sequence``  PatternSequence  transient local: the layout written into the capture
``save_dir``                     "captures"       parameter: where scans are saved (settable)
``save_format``                  "ply"            parameter: ``ply`` or ``pcd`` (settable)
``save_units``                   "m"              parameter: the cloud file's unit, ``m`` or ``mm`` (settable)
``save_frames``                  true             parameter (read-only): keep the last scans' frames for the capture
                                                  folder (the frames' cost: one more subscriber of the camera)
``frame_bursts``                 false            parameter (read-only): take the frames as FringeBursts, as the
                                                  phase node given ``frame_bursts:=true`` does
================================ ================ ===================================================================
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

from dptpu.fpp.calibration import load_rig
from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.graph.parameter_rules import ParameterRules, one_of
from dptpu.graph.qos import QoSProfile, ReliabilityPolicy
from dptpu.messages import FringeBurst, FringeFrame, PatternSequence, PointCloud2
from dptpu.nodes.plumbing import LATCHED_QOS

from .capture_saver import CLOUD_FORMATS, CLOUD_UNITS, RecentScanFrames, save_scan

__all__ = ["CaptureAndSave"]

_FRAME_QUEUE_DEPTH = 100


class CaptureAndSave:
    """The service and what it keeps, on ``node`` (see the module docstring).

    Parameters
    ----------
    node : Node
        The cloud node.
    rules : ParameterRules
        The node's parameter rules (the parameters are declared through them).
    rig_path : str
        The node's rig file, copied into each capture.
    """

    def __init__(self, node, rules: ParameterRules, rig_path: str):
        self._node = node
        self.rig_path = rig_path
        self.save_dir = rules.settable("save_dir", "captures", apply=lambda value: setattr(self, "save_dir", value))
        self.save_format = rules.settable("save_format", "ply", check=one_of(CLOUD_FORMATS),
                                          apply=lambda value: setattr(self, "save_format", value))
        self.save_units = rules.settable("save_units", "m", check=one_of(CLOUD_UNITS),
                                         apply=lambda value: setattr(self, "save_units", value))
        self.save_frames = rules.read_only("save_frames", True, description="sets the frame subscription up")
        frame_bursts = self.frame_bursts = rules.read_only("frame_bursts", False,
                                                           description="sets the frame subscription up")
        self.frames = RecentScanFrames(kept_scans=3)
        self.layout: PatternSequence | None = None
        # (sequence_id, the cloud or what makes it, fringe axis)
        self._last: tuple[int, PointCloud2 | Callable[[], PointCloud2], str] | None = None
        self.saved = 0
        self.subscriptions = []
        if self.save_frames:
            frame_qos = QoSProfile(depth=_FRAME_QUEUE_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
            self.subscriptions = [
                node.create_subscription(FringeBurst, "/camera/frame_bursts", self._on_burst, frame_qos)
                if frame_bursts else node.create_subscription(FringeFrame, "/camera/image_raw", self.frames.add,
                                                              frame_qos),
                node.create_subscription(PatternSequence, "/projector/pattern_sequence", self._on_layout,
                                         LATCHED_QOS)]
        self.service = node.create_service(TriggerService, "~/capture_and_save", self.on_request)

    def keep(self, sequence_id: int, cloud: PointCloud2 | Callable[[], PointCloud2], fringe_axis: str) -> None:
        """The cloud node published scan ``sequence_id``'s ``cloud``: it is the one a request saves (a callable
        makes it when asked: a cloud published from a loaned segment is not kept itself)."""
        self._last = (int(sequence_id), cloud, fringe_axis)

    def on_request(self, request, response):
        """``~/capture_and_save``: write the last scan (its cloud and, with ``save_frames``, its frames)."""
        if self._last is None:
            response.success, response.message = False, "no scan to save yet: no cloud was published"
            return response
        sequence_id, kept, fringe_axis = self._last
        cloud = kept() if callable(kept) else kept
        frames = self.frames.frames(sequence_id)
        folder = Path(self.save_dir) / f"scan_{sequence_id:08d}"
        try:
            # the rig file as the cloud was triangulated with it: its camera the CameraInfo's (size, intrinsics)
            rig = dataclasses.replace(load_rig(self.rig_path), camera=self._node.rig.camera) if self.rig_path \
                else None
            saved = save_scan(folder, cloud, frames, projector_size=tuple(self._node.rig.projector.size),
                              fringe_axis=fringe_axis, cloud_format=self.save_format, layout=self.layout, rig=rig,
                              cloud_unit=self.save_units)
        except (OSError, ImportError, RuntimeError, ValueError) as exc:
            response.success, response.message = False, f"cannot save scan {sequence_id} to {folder}: {exc}"
            self._node.get_logger().warning(response.message)
            return response
        self.saved += 1
        unit = "metres" if self.save_units == "m" else "millimetres"
        written = f"{saved.cloud_path} ({saved.points} points, {unit})"
        if saved.capture_folder is not None:
            written += f" and {saved.capture_folder} ({len(frames)} frames)"
        elif self.save_frames:
            topic = self.subscriptions[0].topic_name
            written += (f"; no frames of it were received on {topic} (frame_bursts:={str(self.frame_bursts).lower()}: "
                        f"the camera side must publish there), so no capture folder")
        response.success, response.message = True, f"saved scan {sequence_id}: {written}"
        self._node.get_logger().info(response.message)
        return response

    def _on_burst(self, burst: FringeBurst) -> None:
        """Keep a burst's frames; one that cannot be read as frames is logged, not kept."""
        try:
            self.frames.add_burst(burst)
        except ValueError as exc:
            self._node.get_logger().warning(f"capture_and_save: a FringeBurst not kept: {exc}",
                                            throttle_duration_sec=1.0)

    def _on_layout(self, msg: PatternSequence) -> None:
        self.layout = msg
