"""The ROS 2 bridge as a real process, heard by a Cyclone DDS subscriber in another process.

The subscriber (``SUBSCRIBER``, run from a file) knows nothing of dptpu: it declares ROS 2's IDL types itself
(``sensor_msgs::msg::dds_::PointCloud2_`` ...), as a ROS 2 node on ``rmw_cyclonedds_cpp`` has them, and prints
what it takes. Cyclone runs on loopback only: ``CYCLONEDDS_URI`` with the ``lo`` interface, multicast off and the
peer 127.0.0.1, on a domain of this test run. The checks are exact: field names, offsets, datatypes, steps, the
header, the point count and every byte of the point data equal those of the graph's message.
"""
from __future__ import annotations

import os
import textwrap
import time

import numpy as np
import pytest

from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import (
    CameraInfo,
    DiagnosticArray,
    DiagnosticStatus,
    Header,
    KeyValue,
    PointCloud2,
    Quaternion,
    TFMessage,
    Time,
    Transform,
    TransformStamped,
    Vector3,
)
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.ros2_bridge import Ros2BridgeNode
from tests.graph.conftest import NodeProcess
from tests.nodes.conftest import REPO_ROOT

#: A DDS domain of this test run (0..232), away from a real ROS 2 graph's usual 0.
DDS_DOMAIN = 100 + os.getpid() % 100
LOOPBACK_URI = ("<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
                "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
                "<MaxAutoParticipantIndex>50</MaxAutoParticipantIndex><Peers><Peer Address=\"127.0.0.1\"/></Peers>"
                "</Discovery></Domain></CycloneDDS>")

SUBSCRIBER = textwrap.dedent('''
    """A ROS 2-side listener: ROS 2's DDS types declared here, nothing of dptpu imported."""
    import json, sys, time
    from dataclasses import dataclass, field
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, byte, float64, int32, int64, sequence, uint8, uint32, uint64
    from cyclonedds.pub import DataWriter
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    @dataclass
    class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
        sec: int32 = 0
        nanosec: uint32 = 0

    @dataclass
    class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
        stamp: Time_ = field(default_factory=Time_)
        frame_id: str = ""

    @dataclass
    class PointField_(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
        name: str = ""
        offset: uint32 = 0
        datatype: uint8 = 0
        count: uint32 = 0

    @dataclass
    class PointCloud2_(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
        header: Header_ = field(default_factory=Header_)
        height: uint32 = 0
        width: uint32 = 0
        fields: sequence[PointField_] = field(default_factory=list)
        is_bigendian: bool = False
        point_step: uint32 = 0
        row_step: uint32 = 0
        data: sequence[uint8] = field(default_factory=list)
        is_dense: bool = False

    @dataclass
    class RegionOfInterest_(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
        x_offset: uint32 = 0
        y_offset: uint32 = 0
        height: uint32 = 0
        width: uint32 = 0
        do_rectify: bool = False

    @dataclass
    class CameraInfo_(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
        header: Header_ = field(default_factory=Header_)
        height: uint32 = 0
        width: uint32 = 0
        distortion_model: str = ""
        d: sequence[float64] = field(default_factory=list)
        k: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
        r: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
        p: array[float64, 12] = field(default_factory=lambda: [0.0] * 12)
        binning_x: uint32 = 0
        binning_y: uint32 = 0
        roi: RegionOfInterest_ = field(default_factory=RegionOfInterest_)

    @dataclass
    class KeyValue_(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
        key: str = ""
        value: str = ""

    @dataclass
    class DiagnosticStatus_(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
        level: byte = 0
        name: str = ""
        message: str = ""
        hardware_id: str = ""
        values: sequence[KeyValue_] = field(default_factory=list)

    @dataclass
    class DiagnosticArray_(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
        header: Header_ = field(default_factory=Header_)
        status: sequence[DiagnosticStatus_] = field(default_factory=list)

    @dataclass
    class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
        x: float64 = 0.0
        y: float64 = 0.0
        z: float64 = 0.0

    @dataclass
    class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
        x: float64 = 0.0
        y: float64 = 0.0
        z: float64 = 0.0
        w: float64 = 1.0

    @dataclass
    class Transform_(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
        translation: Vector3_ = field(default_factory=Vector3_)
        rotation: Quaternion_ = field(default_factory=Quaternion_)

    @dataclass
    class TransformStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
        header: Header_ = field(default_factory=Header_)
        child_frame_id: str = ""
        transform: Transform_ = field(default_factory=Transform_)

    @dataclass
    class TFMessage_(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
        transforms: sequence[TransformStamped_] = field(default_factory=list)

    @dataclass
    class Trigger_Request_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
        client_guid: uint64 = 0
        sequence_number: int64 = 0
        structure_needs_at_least_one_member: uint8 = 0

    @dataclass
    class Trigger_Response_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
        client_guid: uint64 = 0
        sequence_number: int64 = 0
        success: bool = False
        message: str = ""

    def qos(reliable=True, latched=False, depth=10):
        reliability = (Policy.Reliability.Reliable(duration(milliseconds=100)) if reliable
                       else Policy.Reliability.BestEffort)
        return Qos(reliability,
                   Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile,
                   Policy.History.KeepLast(depth), Policy.DataRepresentation(use_cdrv0_representation=True))

    domain, out_dir, clouds_wanted, capture = int(sys.argv[1]), sys.argv[2], int(sys.argv[3]), sys.argv[4] == "1"
    participant = DomainParticipant(domain)
    points = DataReader(participant, Topic(participant, "rt/scanner/points", PointCloud2_, qos=qos()), qos=qos())
    info = DataReader(participant, Topic(participant, "rt/camera/camera_info", CameraInfo_, qos=qos(latched=True,
                      depth=1)), qos=qos(latched=True, depth=1))
    diagnostics = DataReader(participant, Topic(participant, "rt/diagnostics", DiagnosticArray_, qos=qos()), qos=qos())
    tf_static = DataReader(participant, Topic(participant, "rt/tf_static", TFMessage_, qos=qos(latched=True,
                           depth=1)), qos=qos(latched=True, depth=1))
    if capture:
        requests = DataWriter(participant, Topic(participant, "rq/scanner/captureRequest", Trigger_Request_,
                                                 qos=qos()), qos=qos())
        save_requests = DataWriter(participant, Topic(participant, "rq/scanner/capture_and_saveRequest",
                                                      Trigger_Request_, qos=qos()), qos=qos())
        save_replies = DataReader(participant, Topic(participant, "rr/scanner/capture_and_saveReply",
                                                     Trigger_Response_, qos=qos()), qos=qos())
        replies = DataReader(participant, Topic(participant, "rr/scanner/captureReply", Trigger_Response_,
                                                qos=qos()), qos=qos())
    print(json.dumps({"event": "ready"}), flush=True)
    clouds, deadline = 0, time.monotonic() + 90
    while clouds < clouds_wanted and time.monotonic() < deadline:
        for sample in points.take(N=4):
            if not isinstance(sample, PointCloud2_):
                continue
            path = f"{out_dir}/cloud_{clouds}.bin"
            with open(path, "wb") as f:
                f.write(bytes(sample.data))
            print(json.dumps({"event": "cloud", "stamp": [sample.header.stamp.sec, sample.header.stamp.nanosec],
                              "frame_id": sample.header.frame_id, "height": sample.height, "width": sample.width,
                              "fields": [[f.name, f.offset, f.datatype, f.count] for f in sample.fields],
                              "is_bigendian": sample.is_bigendian, "point_step": sample.point_step,
                              "row_step": sample.row_step, "is_dense": sample.is_dense, "path": path}), flush=True)
            clouds += 1
        for sample in diagnostics.take(N=4):
            if isinstance(sample, DiagnosticArray_):
                stamp = [sample.header.stamp.sec, sample.header.stamp.nanosec]
                print(json.dumps({"event": "diagnostics", "stamp": stamp,
                                  "status": [[s.level, s.name, s.message, s.hardware_id,
                                              [[v.key, v.value] for v in s.values]] for s in sample.status]}),
                      flush=True)
        for sample in tf_static.take(N=1):
            if isinstance(sample, TFMessage_):
                print(json.dumps({"event": "tf_static", "transforms": [
                    [t.header.frame_id, t.child_frame_id, [t.header.stamp.sec, t.header.stamp.nanosec],
                     [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                     [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w]]
                    for t in sample.transforms]}), flush=True)
        for sample in info.take(N=1):
            if isinstance(sample, CameraInfo_):
                print(json.dumps({"event": "camera_info", "width": sample.width, "height": sample.height,
                                  "k": list(sample.k), "d": list(sample.d), "model": sample.distortion_model,
                                  "frame_id": sample.header.frame_id}), flush=True)
        time.sleep(0.005)
    if capture:
        time.sleep(1.0)  # discovery of the request reader
        for event, writer, reader, seq in (("reply", requests, replies, 7), ("save_reply", save_requests,
                                                                             save_replies, 8)):
            writer.write(Trigger_Request_(client_guid=0x1234ABCD, sequence_number=seq))
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                got = [s for s in reader.take(N=4) if isinstance(s, Trigger_Response_)]
                if got:
                    print(json.dumps({"event": event, "guid": got[0].client_guid, "seq": got[0].sequence_number,
                                      "success": got[0].success, "message": got[0].message}), flush=True)
                    break
                time.sleep(0.01)
    print(json.dumps({"event": "done", "clouds": clouds}), flush=True)
''')


def dds_env(node_env: dict) -> dict:
    env = dict(os.environ)
    env.update(node_env)
    env["PYTHONPATH"] = str(REPO_ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    env["CYCLONEDDS_URI"] = LOOPBACK_URI
    env.pop("ROS_DOMAIN_ID", None)
    return env


def start_subscriber(tmp_path, env: dict, clouds: int, *, capture: bool = False) -> NodeProcess:
    script = tmp_path / "ros2_listener.py"
    script.write_text(SUBSCRIBER)
    return NodeProcess([str(script), str(DDS_DOMAIN), str(tmp_path), str(clouds), "1" if capture else "0"], env)


def start_bridge(env: dict, *extra: str) -> NodeProcess:
    return NodeProcess(["-m", "dptpu.nodes.ros2_bridge", "--ros-args", "-p", f"domain_id:={DDS_DOMAIN}", *extra], env)


def stop(*processes: NodeProcess) -> None:
    for process in processes:
        process.terminate()
    for process in processes:
        try:
            process.proc.wait(timeout=5)
        except Exception:  # noqa: BLE001 -- killed below
            pass
        process.kill()


def assert_same_cloud(event: dict, cloud: PointCloud2) -> None:
    """Everything a ROS 2 subscriber reads equals the graph's message, byte for byte."""
    assert event["stamp"] == [cloud.header.stamp.sec, cloud.header.stamp.nanosec]
    assert event["frame_id"] == cloud.header.frame_id
    assert (event["height"], event["width"]) == (cloud.height, cloud.width)
    assert event["fields"] == [[f.name, f.offset, f.datatype, f.count] for f in cloud.fields]
    assert (event["point_step"], event["row_step"]) == (cloud.point_step, cloud.row_step)
    assert (event["is_bigendian"], event["is_dense"]) == (cloud.is_bigendian, cloud.is_dense)
    data = np.fromfile(event["path"], dtype=np.uint8)
    assert data.size == cloud.row_step * cloud.height
    assert data.tobytes() == np.asarray(cloud.data).tobytes()
    xyz = PointCloud2(**{**cloud.__dict__, "data": data}).to_array(["x", "y", "z"])  # (H, W, 3) as ROS reads it
    np.testing.assert_array_equal(xyz, cloud.to_array(["x", "y", "z"]))
    assert int(np.isfinite(xyz).all(axis=-1).sum()) == int(np.isfinite(cloud.to_array(["x"])[..., 0]).sum())


def _test_cloud(width: int, height: int, sequence: int) -> PointCloud2:
    """An organized cloud of the cloud node's layout (x y z intensity quality, float32) with NaN holes."""
    rng = np.random.default_rng(sequence)
    points = rng.normal(0.0, 0.2, size=(height, width, 5)).astype(np.float32)  # (H, W, 5)
    points[..., 2] += 0.85  # metres in front of the camera
    points[rng.random((height, width)) < 0.2, :3] = np.nan  # holes: invalid pixels
    header = Header(stamp=Time(sec=1_700_000_000 + sequence, nanosec=1234 * sequence), frame_id="scanner_optical_frame")
    return PointCloud2.from_array(points, ["x", "y", "z", "intensity", "quality"], header=header)


def test_bridge_republishes_points_camera_info_and_answers_capture_requests(node_env, probe, tmp_path):
    """Graph publisher -> bridge process -> a ROS 2-typed Cyclone subscriber process; capture request back."""
    env = dds_env(node_env)
    started = []

    def start_scan(request, response):  # the projector's ~/start_scan, served by the test
        started.append(request)
        response.success, response.message = True, "scan 41 queued"
        return response

    probe.node.create_service(TriggerService, "/projector/start_scan", start_scan)

    def capture_and_save(request, response):  # the cloud node's ~/capture_and_save, served by the test
        response.success, response.message = True, "saved scan 41: captures/scan_00000041/cloud.ply (5 points, metres)"
        return response

    probe.node.create_service(TriggerService, "/cloud/capture_and_save", capture_and_save)
    points = probe.publisher(PointCloud2, "/scanner/points", 10)
    diagnostics = probe.publisher(DiagnosticArray, "/diagnostics", 10)
    array = DiagnosticArray(header=Header(stamp=Time(sec=1_700_000_000, nanosec=5)), status=[
        DiagnosticStatus(level=DiagnosticStatus.WARN, name="dptpu: scan", message="scan 4: UNTRUSTED (1.35 % ...)",
                         hardware_id="rig-7", values=[KeyValue(key="wrong_share", value="0.0135")]),
        DiagnosticStatus(level=DiagnosticStatus.OK, name="dptpu: /cloud", message="done")])
    info = probe.publisher(CameraInfo, "/camera/camera_info",
                           QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    camera_info = CameraInfo.from_intrinsics(np.array([[600.0, 0, 80], [0, 601.0, 60], [0, 0, 1]]),
                                             [0.1, -0.2, 0.001, 0.002, 0.05], 160, 120)
    camera_info.header.frame_id = "scanner_optical_frame"
    info.publish(camera_info)  # latched before the bridge exists
    tf_static = probe.publisher(TFMessage, "/tf_static",
                                QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    mount = TransformStamped(header=Header(stamp=Time(sec=1_700_000_000, nanosec=9), frame_id="tool0"),
                             child_frame_id="scanner_optical_frame", transform=Transform(
                                 translation=Vector3(x=0.01, y=-0.02, z=0.15),
                                 rotation=Quaternion(x=0.5, y=-0.5, z=0.5, w=0.5)))
    projector = TransformStamped(header=Header(stamp=Time(sec=1_700_000_000, nanosec=9),
                                               frame_id="scanner_optical_frame"),
                                 child_frame_id="projector_optical_frame",
                                 transform=Transform(translation=Vector3(x=-0.2, y=0.0, z=0.03)))
    tf_static.publish(TFMessage(transforms=[mount, projector]))  # latched before the bridge exists too

    bridge = start_bridge(env, "-p", "interface:=lo", "-p", "peers:=127.0.0.1")  # its own config, not the URI's
    listener = start_subscriber(tmp_path, env, clouds=3, capture=True)
    try:
        listener.wait_event("ready", timeout=30)
        assert points.wait_for_subscriptions(1, timeout_sec=30), bridge.stderr
        sent = {}
        deadline = time.monotonic() + 60
        events = []
        sequence = 0
        while len(events) < 3 and time.monotonic() < deadline:  # until the DDS reader matched and took 3
            sequence += 1
            cloud = _test_cloud(160, 120, sequence)
            sent[(cloud.header.stamp.sec, cloud.header.stamp.nanosec)] = cloud
            points.publish(cloud)
            diagnostics.publish(array)
            try:
                events.append(listener.wait_event("cloud", timeout=0.5))
            except Exception:  # noqa: BLE001 -- not matched yet: publish again
                pass
        assert len(events) == 3, (bridge.stderr[-2000:], listener.stderr[-2000:])
        for event in events:
            assert_same_cloud(event, sent[tuple(event["stamp"])])
        got_diagnostics = listener.wait_event("diagnostics", timeout=10)  # the scan monitor's, as ROS 2 reads them
        assert {k: v for k, v in got_diagnostics.items() if k in ("stamp", "status")} == {
            "stamp": [1_700_000_000, 5], "status": [
            [1, "dptpu: scan", "scan 4: UNTRUSTED (1.35 % ...)", "rig-7", [["wrong_share", "0.0135"]]],
            [0, "dptpu: /cloud", "done", "", []]]}
        got_tf = listener.wait_event("tf_static", timeout=10)  # latched on both sides: a late ROS 2 reader gets it
        assert got_tf["transforms"] == [
            ["tool0", "scanner_optical_frame", [1_700_000_000, 9], [0.01, -0.02, 0.15], [0.5, -0.5, 0.5, 0.5]],
            ["scanner_optical_frame", "projector_optical_frame", [1_700_000_000, 9], [-0.2, 0.0, 0.03],
             [0.0, 0.0, 0.0, 1.0]]]
        got_info = listener.wait_event("camera_info", timeout=10)
        assert (got_info["width"], got_info["height"], got_info["model"]) == (160, 120, "plumb_bob")
        assert got_info["k"] == [600.0, 0.0, 80.0, 0.0, 601.0, 60.0, 0.0, 0.0, 1.0]
        assert got_info["d"] == [0.1, -0.2, 0.001, 0.002, 0.05]
        reply = listener.wait_event("reply", timeout=30)
        assert (reply["guid"], reply["seq"]) == (0x1234ABCD, 7)  # rmw_cyclonedds' request header, echoed
        assert (reply["success"], reply["message"]) == (True, "scan 41 queued")
        assert len(started) == 1
        saved = listener.wait_event("save_reply", timeout=30)  # /scanner/capture_and_save -> the cloud node's
        assert (saved["guid"], saved["seq"], saved["success"]) == (0x1234ABCD, 8, True)
        assert saved["message"] == "saved scan 41: captures/scan_00000041/cloud.ply (5 points, metres)"
    finally:
        stop(listener, bridge)


def test_bridge_refuses_bad_parameters_naming_them():
    with NodeHarness() as harness:
        with pytest.raises(ValueError, match="parameter qos must be 'default' or 'sensor_data'; got 'fast'"):
            harness.start(Ros2BridgeNode, qos="fast")
        with pytest.raises(ValueError, match="must be absolute, like /scanner/points; got 'scanner/points'"):
            harness.start(Ros2BridgeNode, topics=["scanner/points"])


def test_bridge_process_exits_with_code_2_on_a_bad_parameter(node_env):
    bridge = start_bridge(dds_env(node_env), "-p", "domain_id:=300")
    try:
        assert bridge.proc.wait(timeout=30) == 2
    finally:
        stop(bridge)
    assert "ros2_bridge: error: parameter domain_id must be -1 (ROS_DOMAIN_ID) or 0..232; got 300" in bridge.stderr
