"""The camera node's parameters at run time, as a real process on the shipped viky.cti GenTL producer.

``exposure_us`` and ``frame_rate_hz`` go to the acquisition thread, which writes them to the device before the next
frame: viky has no ExposureTime feature, so the node says the value was ignored (a camera with the feature is
written instead); its AcquisitionFrameRate is written.
A negative exposure is refused by the same check as at start-up; a device setting is read-only. A ``frame_id`` set at
run time reaches the next frames and the latched CameraInfo, published again. The parameters are
set through the node's parameter services (what ``dptpu param set`` calls), from the test's probe node.
"""
from __future__ import annotations

from dptpu.graph import DurabilityPolicy, Parameter, QoSProfile
from dptpu.graph.parameter_client import AsyncParameterClient
from dptpu.messages import CameraInfo, FringeFrame
from tests.nodes.camera.test_camera_node import FAST, NODE, SMALL, write_rig


def _set(client: AsyncParameterClient, name: str, value):
    future = client.set_parameters([Parameter(name, value=value)])
    assert future.wait(timeout_sec=20), f"no answer to set_parameters {name}"
    return future.result().results[0]


def test_exposure_and_frame_rate_are_written_at_run_time_and_a_bad_value_or_a_device_setting_refused(spawn_node, probe,
                                                                                                       tmp_path):
    rig_path, _ = write_rig(tmp_path / "rig.yaml")
    node = spawn_node(NODE, "--ros-args", "-p", "trigger_mode:=free-running", "-p", "frame_rate_hz:=50.0",
                      "-p", "publish_unpaired:=true", "-p", f"rig:={rig_path}", *SMALL, *FAST)
    assert node.wait_for_stderr("trigger mode free-running", timeout=20)
    client = AsyncParameterClient(probe.node, "/camera")
    assert client.wait_for_services(timeout_sec=20)
    assert _set(client, "exposure_us", 4000.0).successful
    assert node.wait_for_stderr("camera: the camera has no ExposureTime feature: exposure_us 4000.0 ignored",
                                timeout=10)
    assert _set(client, "frame_rate_hz", 25.0).successful  # viky has AcquisitionFrameRate (read-write): written
    assert node.wait_for_stderr("camera: frame_rate_hz 25", timeout=10)
    refused = _set(client, "exposure_us", -1.0)
    assert (refused.successful, refused.reason) == (False, "exposure_us must be >= 0; got -1.0")
    refused = _set(client, "width", 320)
    assert (refused.successful, refused.reason) == (False, "Trying to set a read-only parameter: width")

    # a frame id: the latched CameraInfo was published once, at start-up, and kept the old frame (issue 18)
    assert _set(client, "frame_id", "left_camera_optical_frame").successful
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    (info,) = probe.subscribe(CameraInfo, "/camera/camera_info", latched).wait(1)  # subscribed after the set
    assert (info.header.frame_id, info.width) == ("left_camera_optical_frame", 160)
    frames = probe.subscribe(FringeFrame, "/camera/image_raw")  # free-running, unpaired frames published too
    assert frames.wait(1, timeout=10)[0].image.header.frame_id == "left_camera_optical_frame"
