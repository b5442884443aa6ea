"""Camera node: acquires frames through GenICam GenTL (harvesters) and pairs each with its projector Trigger.

Run it as ``python -m dptpu.nodes.camera --ros-args -p cti:=/opt/pylon/lib/gentlproducer/gtl/ProducerU3V.cti
-p serial:=22334455`` or from a launch file (``pkg: dptpu, exec: camera``). Without a ``cti`` it uses
the ``viky.cti`` simulated producer shipped in the genicam wheel (docs/camera.md). How frames are paired
with Triggers in each trigger mode: ``dptpu.nodes.camera.genicam_acquisition``.

Topics (defaults; remappable):

=========================  ======================  ==================================================
name                       type                    what
=========================  ======================  ==================================================
``/projector/trigger``     Trigger (sub)           the pattern on screen; one frame is paired with each
``/camera/image_raw``      FringeFrame (pub)       the frame (``mono8``/``mono16``, DN) + its Trigger
                                                   (with ``frame_bursts``: only while it has subscribers,
                                                   and frames no Trigger claimed)
``/camera/frame_bursts``   FringeBurst (pub)       with ``frame_bursts``: an entry's frames in one
                                                   message, published with its last frame
``/camera/camera_info``    CameraInfo (pub)        from the ``rig`` file; TRANSIENT_LOCAL, depth 1
``/scanner/status``        ScanStatus (pub)        ERROR ``failed`` when a Trigger got no frame (once
                                                   per scan), with the reason
=========================  ======================  ==================================================

Parameters:

=======================  ==========================  ===================================================
name                     default                     meaning
=======================  ==========================  ===================================================
``cti``                  ``""``                      GenTL producer file(s), ``:``-separated; ``""`` =
                                                     the genicam wheel's ``viky.cti`` (simulated)
``serial``               ``""``                      device serial number (text, or an unquoted integer);
                                                     ``""`` = use ``device_index``
``device_index``         0                           index among the devices the producers list
``pixel_format``         ``"Mono8"``                 ``Mono8`` (mono8) or ``Mono10/12/16`` (mono16, DN)
``width``, ``height``    0                           image size, pixels; 0 = as the device is set
``exposure_us``          0.0                         exposure, microseconds; 0 = as the device is set
``trigger_mode``         ``"hardware"``              ``hardware`` (TriggerSource line), ``software``
                                                     (TriggerSoftware per Trigger), ``free-running``
``trigger_source``       ``"Line1"``                 hardware mode's input line
``frame_rate_hz``        0.0                         free-running rate; 0 = as the device is set
``frame_timeout_s``      1.0                         longest wait for a Trigger's frame
``publish_unpaired``     false                       free-running: also publish frames no Trigger claimed
                                                     (with an empty Trigger: sequence_id 0, count 0)
``frame_bursts``         false                       publish each entry's frames as one FringeBurst
                                                     (fewer messages a scan; the phase node needs
                                                     ``frame_bursts:=true`` too): ``burst_writer``
``rig``                  ``""``                      ``dptpu-rig/1`` file for CameraInfo; ``""`` = none
``frame_id``             ``"scanner_optical_frame"``  ``header.frame_id`` of images and CameraInfo
``reconnect_initial_s``  0.5                         first reconnection delay; doubles per failure
``reconnect_max_s``      5.0                         longest reconnection delay
=======================  ==========================  ===================================================

``exposure_us`` and ``frame_rate_hz`` (written to the camera before its next frame) and ``frame_id`` apply at run
time (``dptpu param set``); the others open and configure the device and are read-only.

Convention: an image's stamp is the host time at which its buffer was received (producers such as
``viky.cti`` give no device timestamps); the exposure started up to one exposure plus the transfer
time earlier.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from dptpu.fpp.calibration import load_rig
from dptpu.graph.known_publishers import SOLE_PUBLISHER
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, frame_id
from dptpu.messages import CameraInfo, FringeBurst, FringeFrame, Header, Image, ScanStatus, Time, Trigger
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import DEFAULT_FRAME_ID, LATCHED_QOS, scan_status

from .burst_writer import BurstWriter
from .genicam_acquisition import Acquisition
from .genicam_device import CameraSettings
from .genicam_producers import split_cti_paths

__all__ = ["CameraNode", "main"]


class CameraNode(Node):
    """Opens the camera, pairs frames with Triggers, publishes FringeFrames (or FringeBursts) and the rig's
    CameraInfo.

    Counters: ``frames_published`` (FringeFrames), ``timeouts``; with ``frame_bursts``, ``bursts`` counts
    ``bursts_published`` and ``frames_copied_twice`` (said in the log at shutdown).
    """

    def __init__(self, node_name: str = "camera", **kwargs):
        super().__init__(node_name, **kwargs)
        rules = ParameterRules(self)
        device = "opens and configures the device; restart the node to change it"
        self.settings = CameraSettings(
            cti_paths=tuple(split_cti_paths(rules.read_only("cti", "", description=device))),
            serial=_serial_text(rules.read_only("serial", "", description=device, dynamic_typing=True)),
            device_index=rules.read_only("device_index", 0, description=device),
            pixel_format=rules.read_only("pixel_format", "Mono8", description=device),
            width=rules.read_only("width", 0, description=device),
            height=rules.read_only("height", 0, description=device),
            exposure_us=rules.settable("exposure_us", 0.0, check=at_least(0.0),
                                       apply=self._set_exposure_us,
                                       description="written to the camera before its next frame"),
            trigger_mode=rules.read_only("trigger_mode", "hardware", description=device),
            trigger_source=rules.read_only("trigger_source", "Line1", description=device),
            frame_rate_hz=rules.settable("frame_rate_hz", 0.0, check=at_least(0.0), apply=self._set_frame_rate_hz,
                                         description="free-running: written to the camera before its next frame"))
        frame_timeout_s = rules.read_only("frame_timeout_s", 1.0, description=device)
        publish_unpaired = rules.read_only("publish_unpaired", False, description=device)
        frame_bursts = rules.read_only("frame_bursts", False, description="sets the frames' publisher up")
        rig_path = rules.read_only("rig", "", description="the CameraInfo published at start-up")
        self.frame_id = rules.settable("frame_id", DEFAULT_FRAME_ID, check=frame_id, apply=self._set_frame_id)
        initial_s = rules.read_only("reconnect_initial_s", 0.5, description=device)
        max_s = rules.read_only("reconnect_max_s", 5.0, description=device)
        self.camera_info = self.rig_camera_info(rig_path) if rig_path else None

        self.image_pub = self.create_publisher(FringeFrame, "/camera/image_raw", 30)
        self.bursts = BurstWriter(self.create_publisher(FringeBurst, "/camera/frame_bursts", 10),
                                  lambda: self.frame_id) if frame_bursts else None
        self.info_pub = self.create_publisher(CameraInfo, "/camera/camera_info", LATCHED_QOS)
        self.status_pub = self.create_publisher(ScanStatus, "/scanner/status", 20)
        self.trigger_sub = self.create_subscription(Trigger, "/projector/trigger", self.on_trigger, 100,
                                                    publishers=SOLE_PUBLISHER)  # a stranger's Triggers: refused

        self.frames_published = 0
        self.timeouts = 0
        self._failed_scans: deque = deque(maxlen=64)  # scans already reported failed (one ScanStatus each)
        if self.camera_info is not None:
            self.info_pub.publish(self.camera_info)
        else:
            self.get_logger().info("no rig parameter: no CameraInfo is published")
        self.acquisition = Acquisition(self.settings, logger=self.get_logger(), on_frame=self.on_frame,
                                       on_timeout=self.on_timeout, on_connected=self.on_connected,
                                       frame_timeout_s=frame_timeout_s, publish_unpaired=publish_unpaired,
                                       initial_s=initial_s, max_s=max_s, allocate=self._frame_destination)
        self._image_raw_listened = False  # with frame_bursts: /camera/image_raw has subscribers (the timer asks)
        if self.bursts is not None:
            self.burst_timer = self.create_timer(0.1, self.on_burst_timer)
        self.acquisition.start()

    # --- callbacks ---------------------------------------------------------------------------------

    def _set_exposure_us(self, exposure_us: float) -> None:
        """``param set /camera exposure_us``: the acquisition thread writes it before the next frame."""
        if exposure_us > 0:
            self.acquisition.write_setting("exposure_us", exposure_us)

    def _set_frame_id(self, value: str) -> None:
        """``param set /camera frame_id``: the next frames carry it, and the latched CameraInfo is published again
        with it (a late subscriber would otherwise get the old frame)."""
        self.frame_id = value
        if self.camera_info is not None:
            self.camera_info.header = Header(stamp=self.get_clock().now().to_msg(), frame_id=value)
            self.info_pub.publish(self.camera_info)

    def _set_frame_rate_hz(self, frame_rate_hz: float) -> None:
        """``param set /camera frame_rate_hz`` (free-running): the acquisition thread writes it before the next
        frame."""
        if frame_rate_hz > 0:
            self.acquisition.write_setting("frame_rate_hz", frame_rate_hz)

    def on_trigger(self, trigger: Trigger) -> None:
        """A pattern is on screen: hand it to the acquisition thread to be paired with a frame."""
        self.acquisition.add_trigger(trigger)

    def on_burst_timer(self) -> None:
        """``frame_bursts``, 10 times a second: send a burst whose next frame is ``max_wait_s`` late (a lost Trigger),
        and note whether ``/camera/image_raw`` has subscribers (asked here rather than at each frame)."""
        assert self.bursts is not None
        self._image_raw_listened = self.image_pub.get_subscription_count() > 0
        self.bursts.publish_due()

    def on_frame(self, frame, stamp_ns: int, trigger: Trigger | None) -> None:
        """Acquisition thread: publish ``frame`` (H, W) with the Trigger it belongs to; with ``frame_bursts``, a
        frame with a Trigger joins its burst (and is published alone too, a copy, while ``/camera/image_raw`` has
        subscribers: from at most 0.1 s after the first connects)."""
        if trigger is not None and self.bursts is not None:
            if self._image_raw_listened:
                single = self._loaned_frame(frame.shape, frame.dtype)
                np.copyto(single, frame)
                self._publish_frame(single, stamp_ns, trigger)
            self.bursts.add(trigger, frame, stamp_ns)
        else:
            self._publish_frame(frame, stamp_ns, trigger)

    def _publish_frame(self, frame, stamp_ns: int, trigger: Trigger | None) -> None:
        """A FringeFrame of ``frame`` (an empty Trigger for an unpaired one)."""
        header = Header(stamp=Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000),
                        frame_id=self.frame_id)
        self.image_pub.publish(FringeFrame(image=Image.from_array(frame, header=header),
                                           trigger=trigger if trigger is not None else Trigger()))
        self.frames_published += 1

    def _frame_destination(self, shape: tuple[int, int], dtype: np.dtype, trigger: Trigger | None) -> np.ndarray:
        """Acquisition thread: where a frame is copied out of the producer's buffer, given the Trigger it pairs
        with: its row of its burst (``frame_bursts``), else :meth:`_loaned_frame`."""
        if trigger is not None and self.bursts is not None:
            return self.bursts.row(trigger, shape, dtype)
        return self._loaned_frame(shape, dtype)

    def _loaned_frame(self, shape: tuple[int, int], dtype: np.dtype) -> np.ndarray:
        """Acquisition thread: the array a frame is copied into out of the producer's buffer, loaned by the frames'
        publisher where a loan pays (a shared-memory segment, published without a further copy; a frame no Trigger
        claims goes back to the pool when it is let go), else a new array."""
        if not self.image_pub.can_loan_messages(math.prod(shape) * np.dtype(dtype).itemsize):
            return np.empty(shape, dtype)  # ZeroMQ sends it without a copy
        (frame,) = self.image_pub.borrow_loaned_arrays([(shape, dtype)])
        return frame

    def on_timeout(self, trigger: Trigger, reason: str) -> None:
        """Acquisition thread: ``trigger`` got no frame; log it, and report its scan failed once."""
        self.timeouts += 1
        where = f"pattern {trigger.pattern_index} of scan {trigger.sequence_id}"
        self.get_logger().warning(f"camera timeout: {where}: {reason} ({self.timeouts} so far)",
                                  throttle_duration_sec=1.0)
        if trigger.sequence_id in self._failed_scans:
            return
        self._failed_scans.append(trigger.sequence_id)
        self.status_pub.publish(scan_status(self, trigger.sequence_id, ScanStatus.ERROR, "failed",
                                            f"camera: {where}: {reason}", frames_expected=trigger.pattern_count,
                                            frames_dropped=1))

    def on_connected(self, device) -> None:
        """Acquisition thread: the camera is open and acquiring."""
        info = device.info
        self.get_logger().info(f"camera {info['vendor']} {info['model']} serial {info['serial']}: "
                               f"{device.width}x{device.height} {self.settings.pixel_format}, trigger mode "
                               f"{self.settings.trigger_mode}")
        for note in device.notes:
            self.get_logger().warning(f"camera: {note}")
        if self.camera_info is not None and (self.camera_info.width, self.camera_info.height) != \
                (device.width, device.height):
            self.get_logger().warning(f"camera: images are {device.width}x{device.height} but the rig's camera is "
                                      f"{self.camera_info.width}x{self.camera_info.height}: CameraInfo does not fit")

    # --- helpers -----------------------------------------------------------------------------------

    def rig_camera_info(self, rig_path: str) -> CameraInfo:
        """CameraInfo of the rig file's camera (``K``, ``dist``, ``size``); ValueError naming the file."""
        try:
            camera = load_rig(rig_path).camera
        except FileNotFoundError as exc:
            raise ValueError(f"parameter rig: {exc}") from None
        width, height = camera.size
        return CameraInfo.from_intrinsics(camera.K, camera.dist, width, height,
                                          header=Header(stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id))

    def destroy_node(self):
        self.acquisition.close()
        if self.bursts is not None:
            self.bursts.flush()  # frames of a scan cut short by the shutdown: sent as they stand, not dropped
            self.get_logger().info(f"camera: published {self.bursts.bursts_published} bursts and "
                                   f"{self.frames_published} single frames; {self.bursts.frames_copied_twice} "
                                   f"frame(s) copied twice (not into their burst's row at once)")
        return super().destroy_node()


def _serial_text(value) -> str:
    """A serial number given as text or, unquoted on the command line (``serial:=22334455``), as an integer."""
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise ValueError(f"parameter serial must be a serial number (text or integer); got {value!r}")
    return str(value)


def main(argv=None) -> int:
    """``python -m dptpu.nodes.camera [--ros-args ...]``; returns the exit code (2 for bad parameters)."""
    return run_node("camera", CameraNode, argv)

