"""A scan callback that raises fails that scan with a status naming the node and the exception (issue 16, item 1).

Before: the exception reached the executor, which logged it and went on; the scan never ended and the scan monitor
called it LOST ("no cloud within 10 s (/projector done, /phase processing, /unwrap processing)"), naming neither
the node nor the exception. Each test feeds a real node a real input it cannot handle (no monkeypatching): a
model file the network cannot run on the scan's size. And a CameraInfo with zero focal lengths (uncalibrated) is not
used: the scan fails naming it instead of going out as an all-NaN cloud.
"""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import AbsolutePhase, CameraInfo, Header, PhaseMaps, ScanStatus, Time
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.scan_monitor import ScanMonitorNode
from dptpu.nodes.unwrap import UnwrapNode
from tests.nodes.test_cloud_scene import plane_scene

STAMP = Time.from_ns(1_700_000_000_000_000_000)


@pytest.fixture(scope="module")
def scene():
    return plane_scene()


def _fixed_size_model(path, height: int, width: int):
    """A real ONNX model with the DP-TPU interface whose inputs are fixed at ``height`` x ``width``: onnxruntime
    refuses any other size with its own exception type (InvalidArgument, not a ValueError)."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    inference = pytest.importorskip("dptpu.models.inference")

    def image(name):
        return helper.make_tensor_value_info(name, TensorProto.FLOAT, [1, 1, height, width])

    graph = helper.make_graph(
        [helper.make_node("Identity", ["coarse_order"], ["fringe_order"])], "fixed_size",
        [image("wrapped_high"), image("wrapped_low"), image("coarse_order"),
         helper.make_tensor_value_info("frequency_high", TensorProto.FLOAT, [1])], [image("fringe_order")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    helper.set_model_props(model, {"dptpu_format": inference.MODEL_FORMAT, "kind": "dptpu", "config": "{}",
                                   "training": "{}"})
    onnx.save(model, str(path))
    return path


def _phase_maps(scene, sequence_id: int) -> PhaseMaps:
    phases = np.stack([np.mod(scene.absolute_phase(f), 2 * np.pi) for f in (16.0, 1.0)]).astype(np.float32)
    phases[phases >= 2 * np.pi] = 0.0
    return PhaseMaps(header=Header(stamp=Time.from_ns(STAMP.to_ns() + sequence_id), frame_id="scanner_optical_frame"),
                     sequence_id=sequence_id, fringe_axis="x", projector_width=912, projector_height=1140,
                     frequencies=np.array([16.0, 1.0]), phases=phases,
                     modulation=np.full(phases.shape, 80.0, np.float32), valid=np.ones(phases.shape[1:], bool))


def test_a_scan_the_unwrap_node_raises_on_is_failed_naming_the_node_and_the_exception(scene, tmp_path):
    model = _fixed_size_model(tmp_path / "fixed_8x8.onnx", 8, 8)
    with NodeHarness() as harness:
        node = harness.start(UnwrapNode, method="mf", model=str(model), min_confidence=0.0)
        monitor = harness.start(ScanMonitorNode, ground_truth=False, trigger_latency=False, scan_timeout_s=60.0)
        source = harness.publisher(PhaseMaps, "/scanner/phase")
        status = harness.collect(ScanStatus, "/scanner/status")
        harness.connect()
        for sequence_id in (1, 2):  # every scan fails; the node goes on
            source.publish(_phase_maps(scene, sequence_id))
        assert harness.spin_until(lambda: monitor.reported >= 2 and len(status.messages) >= 2, timeout_s=30.0)
        failed = [s for s in status.messages if s.state == "failed"]
    assert [s.sequence_id for s in failed] == [1, 2]
    assert all(s.node == "/unwrap" and s.level == ScanStatus.ERROR for s in failed)
    reason = failed[0].reason
    assert reason.startswith("InvalidArgument: ") and "\n" not in reason, reason
    assert "Got: 120 Expected: 8" in reason  # the message's lines joined into one
    assert "(in on_phase_maps; traceback in the node's log)" in reason
    assert node.scan_failures.count == 2
    # the monitor reports what the node said, not LOST
    assert [(r["outcome"], r["reason"]) for r in monitor.records] == [
        ("failed", f"/unwrap: {s.reason}") for s in failed]
    assert monitor.counts["lost"] == 0


def test_an_uncalibrated_camera_info_is_not_used_and_the_scan_fails_naming_it(scene, tmp_path):
    """A CameraInfo with a K of zeros (ROS: an uncalibrated camera) is ignored with a warning: the scan is not
    triangulated with it (that published an all-NaN cloud as done) but fails, after ``camera_info_wait_s``, with the
    reason."""
    rig_path = save_rig(scene.rig, tmp_path / "rig.yaml")
    camera = scene.rig.camera
    k = camera.K.copy()
    k[0, 0] = k[1, 1] = 0.0  # zero focal lengths (cx, cy kept)
    with NodeHarness() as harness:
        node = harness.start(CloudNode, rig=str(rig_path), use_camera_info=True, camera_info_wait_s=1.0)
        info = harness.publisher(CameraInfo, "/camera/camera_info",
                                 QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        source = harness.publisher(AbsolutePhase, "/scanner/absolute_phase")
        status = harness.collect(ScanStatus, "/scanner/status")
        harness.connect()
        info.publish(CameraInfo.from_intrinsics(k, camera.dist, *camera.size))
        psi = scene.absolute_phase(16.0).astype(np.float32)
        source.publish(AbsolutePhase(
            header=Header(stamp=STAMP, frame_id="camera"), sequence_id=5, frequency=16.0, fringe_axis="x",
            projector_width=912, projector_height=1140, absolute_phase=psi,
            fringe_order=np.floor(psi / (2 * np.pi)).astype(np.int32), valid=np.ones(psi.shape, bool),
            reliability=np.full(psi.shape, 0.9, np.float32), method="mf"))
        assert harness.spin_until(lambda: any(s.state == "failed" for s in status.messages), timeout_s=30.0)
        assert node.rig.camera.K[0, 0] == camera.K[0, 0]  # the rig's own intrinsics kept
    assert not any(s.state == "done" for s in status.messages)
    (failed,) = [s for s in status.messages if s.state == "failed"]
    assert (failed.sequence_id, failed.node) == (5, "/cloud")
    assert "no CameraInfo on /camera/camera_info within 1 s" in failed.reason, failed.reason
