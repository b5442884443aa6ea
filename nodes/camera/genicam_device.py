"""One GenICam camera through harvesters: open, configure, fetch frames, software trigger, close.

Every call must come from one thread (the camera node's acquisition thread). Errors a reconnect can
cure (no producer, no device, device lost) raise :class:`CameraUnavailable`; a frame that does not come
in time returns None from :meth:`GenICamDevice.fetch`.

Features are set by their SFNC names when the device has them: ``Width``, ``Height``, ``PixelFormat``,
``ExposureTime`` (or ``ExposureTimeAbs``), ``TriggerSelector`` (``FrameStart``), ``TriggerMode``,
``TriggerSource``, ``TriggerActivation``, ``AcquisitionFrameRateEnable``, ``AcquisitionFrameRate``. A
feature that is asked for but missing is reported in :attr:`GenICamDevice.notes` (and logged by the node),
except for triggering, which a mode cannot do without (``software`` needs ``TriggerSoftware`` and a
``Software`` trigger source; ``hardware`` needs ``TriggerMode`` and the configured source).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from genicam.genapi import EAccessMode
from genicam.gentl import TimeoutException
from harvesters.core import Harvester

__all__ = ["TRIGGER_MODES", "PIXEL_FORMATS", "CameraUnavailable", "CameraSettings", "GenICamDevice",
           "list_devices", "buffer_to_array"]

TRIGGER_MODES = ("hardware", "software", "free-running")
#: Pixel formats the node publishes: ``{GenICam name: (numpy dtype, ROS encoding)}``. Mono10/12 travel as
#: mono16 holding the camera's digital numbers (not scaled to 16 bits).
PIXEL_FORMATS = {"Mono8": (np.uint8, "mono8"), "Mono10": (np.uint16, "mono16"), "Mono12": (np.uint16, "mono16"),
                 "Mono16": (np.uint16, "mono16")}


class CameraUnavailable(Exception):
    """The producer, the device or its stream cannot be used now; the message says what to check."""


@dataclass(frozen=True)
class CameraSettings:
    """What the node asks of the camera (parameters of ``dptpu.nodes.camera``)."""

    cti_paths: tuple
    serial: str = ""
    device_index: int = 0
    pixel_format: str = "Mono8"
    width: int = 0                 # 0: leave as the device has it
    height: int = 0
    exposure_us: float = 0.0       # 0: leave as the device has it
    trigger_mode: str = "hardware"
    trigger_source: str = "Line1"
    frame_rate_hz: float = 0.0     # free-running only; 0: leave as the device has it

    def with_run_time_setting(self, name: str, value: float) -> CameraSettings:
        """A copy with ``exposure_us`` or ``frame_rate_hz`` (the settings written while acquiring) changed."""
        if name == "exposure_us":
            return dataclasses.replace(self, exposure_us=float(value))
        if name == "frame_rate_hz":
            return dataclasses.replace(self, frame_rate_hz=float(value))
        raise ValueError(f"{name} is not a setting written while acquiring (exposure_us, frame_rate_hz)")

    def __post_init__(self):
        if self.trigger_mode not in TRIGGER_MODES:
            raise ValueError(f"trigger_mode must be one of {', '.join(TRIGGER_MODES)}; got {self.trigger_mode!r}")
        if self.pixel_format not in PIXEL_FORMATS:
            raise ValueError(f"pixel_format must be one of {', '.join(PIXEL_FORMATS)}; got {self.pixel_format!r}")
        for name in ("width", "height", "device_index"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0; got {getattr(self, name)}")
        if self.exposure_us < 0 or self.frame_rate_hz < 0:
            raise ValueError("exposure_us and frame_rate_hz must be >= 0 (0 keeps the device's value)")


def _harvester(cti_paths) -> Harvester:
    if not cti_paths:
        raise CameraUnavailable("no GenTL producer: set the cti parameter (the genicam wheel's viky.cti was not found)")
    harvester = Harvester()
    for path in cti_paths:
        if not Path(path).is_file():
            harvester.reset()
            raise CameraUnavailable(f"GenTL producer {path} does not exist (is the camera vendor's SDK installed?)")
        harvester.add_file(str(path))
    harvester.update()
    return harvester


def list_devices(cti_paths) -> list[dict]:
    """``[{"serial", "model", "vendor", "id"}, ...]`` of the devices the producers see (nothing is opened)."""
    harvester = _harvester(cti_paths)
    try:
        return [{"serial": str(info.serial_number), "model": str(info.model), "vendor": str(info.vendor),
                 "id": str(info.id_)} for info in harvester.device_info_list]
    finally:
        harvester.reset()


def buffer_to_array(data: np.ndarray, width: int, height: int, pixel_format: str, *,
                    allocate: Callable[[tuple[int, int], np.dtype], np.ndarray] | None = None) -> np.ndarray:
    """A copy of a frame's payload as ``(height, width)`` of the format's dtype.

    Parameters
    ----------
    data : ndarray (N,)
        The buffer component's 1-D view (harvesters gives uint8 or uint16 by format); reused by the
        producer once the buffer is queued again, hence the copy.
    width, height : int
        Pixels.
    pixel_format : str
        A key of :data:`PIXEL_FORMATS`.
    allocate : callable(shape, dtype) -> ndarray, optional
        Where the copy goes (e.g. an array loaned by the frames' publisher, so that the copy out of the producer's
        buffer is the only one); default a new array.
    """
    dtype, _ = PIXEL_FORMATS[pixel_format]
    flat = np.asarray(data)
    if flat.dtype != dtype:
        flat = flat.view(dtype) if flat.dtype.itemsize < np.dtype(dtype).itemsize else flat.astype(dtype)
    if flat.size != width * height:
        raise CameraUnavailable(f"a {pixel_format} frame of {width}x{height} has {flat.size} pixels; expected "
                                f"{width * height} (packed or padded format?)")
    if allocate is None:
        return np.array(flat.reshape(height, width), dtype=dtype)
    frame = allocate((height, width), np.dtype(dtype))
    np.copyto(frame, flat.reshape(height, width))
    return frame


class GenICamDevice:
    """An opened, configured and acquiring camera. Use :meth:`open`; close with :meth:`close`."""

    def __init__(self, harvester, acquirer, settings: CameraSettings, info: dict, notes: list[str]):
        self._harvester = harvester
        self._acquirer = acquirer
        self.settings = settings
        self.info = info
        self.notes = notes
        node_map = acquirer.remote_device.node_map
        self.width = int(node_map.Width.value)
        self.height = int(node_map.Height.value)
        self.frames = 0

    @classmethod
    def open(cls, settings: CameraSettings) -> GenICamDevice:
        """Find the device, configure it and start acquisition; :class:`CameraUnavailable` if it cannot."""
        harvester = _harvester(settings.cti_paths)
        try:
            infos = harvester.device_info_list
            names = ", ".join(str(info.serial_number) for info in infos)
            producers = ", ".join(Path(p).name for p in settings.cti_paths)
            if not infos:
                raise CameraUnavailable(f"no camera found by {producers} (is it plugged in and powered?)")
            if settings.serial:
                matches = [i for i, info in enumerate(infos) if str(info.serial_number) == settings.serial]
                if not matches:
                    raise CameraUnavailable(f"no camera with serial {settings.serial!r} among the {len(infos)} "
                                            f"found by {producers}: {names}")
                index = matches[0]
            elif settings.device_index < len(infos):
                index = settings.device_index
            else:
                raise CameraUnavailable(f"device_index {settings.device_index} but {producers} found only "
                                        f"{len(infos)} camera(s): {names}")
            info = infos[index]
            described = {"serial": str(info.serial_number), "model": str(info.model), "vendor": str(info.vendor)}
            try:
                acquirer = harvester.create(index)
            except Exception as exc:  # noqa: BLE001 -- the GenTL exceptions have no common base we can name
                raise CameraUnavailable(f"cannot open camera {described['serial']} ({exc}); is another "
                                        "program using it?") from None
            try:
                notes = _configure(acquirer.remote_device.node_map, settings)
                acquirer.start()
            except CameraUnavailable:
                acquirer.destroy()
                raise
            except Exception as exc:  # noqa: BLE001 -- GenICam node-map errors have no common base either
                acquirer.destroy()
                raise CameraUnavailable(f"cannot configure camera {described['serial']}: {exc}") from None
            return cls(harvester, acquirer, settings, described, notes)
        except BaseException:
            harvester.reset()
            raise

    def write_setting(self, name: str, value: float) -> str:
        """Write ``exposure_us`` or ``frame_rate_hz`` now (while acquiring); a note when the camera has no such
        feature ("" when written)."""
        node_map = self._acquirer.remote_device.node_map
        features = _RUN_TIME_FEATURES[name]
        feature = _first_feature(node_map, features)
        if feature is None:
            return f"the camera has no {features[0]} feature: {name} {value} ignored"
        if name == "frame_rate_hz" and node_map.has_node("AcquisitionFrameRateEnable"):
            _set(node_map, "AcquisitionFrameRateEnable", True)
        _set(node_map, feature, float(value))
        self.settings = self.settings.with_run_time_setting(name, value)
        return ""

    def software_trigger(self) -> None:
        """Fire ``TriggerSoftware`` (software mode)."""
        try:
            self._acquirer.remote_device.node_map.TriggerSoftware.execute()
        except Exception as exc:  # noqa: BLE001 -- any GenTL error here means the camera is gone
            raise CameraUnavailable(f"software trigger failed ({exc}); camera lost?") from None

    def fetch(self, timeout_s: float, *, allocate=None) -> tuple[np.ndarray, int] | None:
        """The next frame ``((H, W) array, host receive time ns)``, or None after ``timeout_s`` seconds; the frame
        is copied out of the producer's buffer into ``allocate(shape, dtype)`` (:func:`buffer_to_array`)."""
        try:
            buffer = self._acquirer.fetch(timeout=timeout_s)
        except TimeoutException:
            return None
        except Exception as exc:  # noqa: BLE001 -- any GenTL error but the timeout means the camera is gone
            raise CameraUnavailable(f"acquisition failed ({type(exc).__name__}: {exc}); camera unplugged?") from None
        stamp_ns = time.time_ns()
        with buffer:
            component = buffer.payload.components[0]
            fmt = str(component.data_format)
            if fmt != self.settings.pixel_format:
                raise CameraUnavailable(f"camera sent {fmt} frames; pixel_format is {self.settings.pixel_format}")
            frame = buffer_to_array(component.data, int(component.width), int(component.height), fmt,
                                    allocate=allocate)
        self.frames += 1
        return frame, stamp_ns

    def close(self) -> None:
        for action in (self._acquirer.stop, self._acquirer.destroy, self._harvester.reset):
            try:
                action()
            except Exception:  # noqa: BLE001 -- closing a lost device may fail in any way; nothing to do
                pass


def _configure(node_map, settings: CameraSettings) -> list[str]:
    """Apply ``settings`` to the device's features; returns notes about features it does not have."""
    notes = []
    if settings.width or settings.height:
        for name, value in (("Width", settings.width), ("Height", settings.height)):
            if value:
                node = getattr(node_map, name)
                if not node.min <= value <= node.max or (value - node.min) % max(node.inc, 1):
                    raise CameraUnavailable(f"{name.lower()} {value} is not possible: the camera takes "
                                            f"{node.min}..{node.max} in steps of {node.inc}")
                _set(node_map, name, value)
    formats = tuple(node_map.PixelFormat.symbolics)
    if settings.pixel_format not in formats:
        raise CameraUnavailable(f"the camera has no {settings.pixel_format} pixel format; it offers "
                                f"{', '.join(formats)}")
    _set(node_map, "PixelFormat", settings.pixel_format)
    if settings.exposure_us:
        exposure_feature = _first_feature(node_map, ("ExposureTime", "ExposureTimeAbs"))
        if exposure_feature is None:
            notes.append(f"the camera has no ExposureTime feature: exposure_us {settings.exposure_us} ignored")
        else:
            _set(node_map, exposure_feature, float(settings.exposure_us))
    has_trigger = node_map.has_node("TriggerMode")
    if node_map.has_node("TriggerSelector") and "FrameStart" in node_map.TriggerSelector.symbolics:
        _set(node_map, "TriggerSelector", "FrameStart")
    if settings.trigger_mode == "free-running":
        if has_trigger:
            _set(node_map, "TriggerMode", "Off")
        if settings.frame_rate_hz:
            if node_map.has_node("AcquisitionFrameRateEnable"):
                _set(node_map, "AcquisitionFrameRateEnable", True)
            if node_map.has_node("AcquisitionFrameRate"):
                _set(node_map, "AcquisitionFrameRate", float(settings.frame_rate_hz))
            else:
                notes.append(f"the camera has no AcquisitionFrameRate: frame_rate_hz {settings.frame_rate_hz} ignored")
        return notes
    source = "Software" if settings.trigger_mode == "software" else settings.trigger_source
    if not has_trigger or not node_map.has_node("TriggerSource"):
        raise CameraUnavailable(f"trigger_mode {settings.trigger_mode} needs the TriggerMode and TriggerSource "
                                "features, which this camera lacks (use free-running)")
    sources = tuple(node_map.TriggerSource.symbolics)
    if source not in sources:
        raise CameraUnavailable(f"trigger_mode {settings.trigger_mode} needs TriggerSource {source}; the camera "
                                f"offers {', '.join(sources)}")
    if settings.trigger_mode == "software" and not node_map.has_node("TriggerSoftware"):
        raise CameraUnavailable("trigger_mode software needs the TriggerSoftware command, which this camera lacks")
    _set(node_map, "TriggerMode", "On")
    _set(node_map, "TriggerSource", source)
    if settings.trigger_mode == "hardware" and node_map.has_node("TriggerActivation"):
        _set(node_map, "TriggerActivation", "RisingEdge")
    return notes


def _set(node_map, name: str, value) -> None:
    """Write feature ``name`` unless it already holds ``value``; a read-only feature holding another value fails."""
    node = getattr(node_map, name)
    if node.value == value:
        return
    if node.get_access_mode() not in (EAccessMode.RW, EAccessMode.WO):
        raise CameraUnavailable(f"the camera's {name} is read-only at {node.value}; cannot set {value}")
    node.value = value


#: The settings written while acquiring, and the GenICam features (SFNC names first) that hold them.
_RUN_TIME_FEATURES = {"exposure_us": ("ExposureTime", "ExposureTimeAbs"), "frame_rate_hz": ("AcquisitionFrameRate",)}


def _first_feature(node_map, names) -> str | None:
    for name in names:
        if node_map.has_node(name):
            return name
    return None
