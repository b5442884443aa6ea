"""MCAP recordings without the graph: bit-exact round trips of every type, files that mcap-ros2-support
reads on its own, the summary section, and the errors of the writer and the reader."""

from __future__ import annotations

import io

import msgpack
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer as RawMcapWriter
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer

from dptpu.graph import interfaces as graph_interfaces
from dptpu.messages import CameraInfo, EncodeError, Image, PhaseMaps, PointCloud2, Trigger, registered_types
from dptpu.tools.recording import McapReadError, McapRecordWriter, describe_mcap, msgpack_records, read_mcap
from dptpu.tools.recording.ros2_cdr import from_ros2, is_ros2_type, ros2_schema_text, to_ros2_dict

from .sample_messages import sample_messages

T0_NS = 1_700_000_000_000_000_000


@pytest.fixture
def recording(tmp_path):
    """A file with every sample on its own topic, message i logged at T0 + i ms."""
    samples = sample_messages()
    path = tmp_path / "all.mcap"
    with McapRecordWriter(path) as writer:
        for index, (topic, msg) in enumerate(samples.items()):
            writer.write(topic, msg, T0_NS + index * 1_000_000)
    return path, samples


def _ros2_decoded(path, topic):
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(schema, channel, message, decoded)
                for schema, channel, message, decoded in reader.iter_decoded_messages(topics=[topic])]


# --------------------------------------------------------------------------------------------------
# Round trip
# --------------------------------------------------------------------------------------------------

def test_samples_cover_every_type_of_dptpu_messages():
    ours = {cls for cls in registered_types().values() if cls.__module__.startswith("dptpu.messages.")}
    covered = {type(msg) for msg in sample_messages().values()}
    missing = sorted(cls.TYPE_NAME for cls in ours - covered)
    assert missing == [], f"add a sample of {missing} to tests/tools/recording/sample_messages.py"


def test_every_other_registered_type_round_trips_by_default(tmp_path):
    covered = {type(msg) for msg in sample_messages().values()}
    others = {f"/t{index}": cls() for index, cls in enumerate(registered_types().values()) if cls not in covered}
    # e.g. std_msgs/msg/String and the parameter service types of dptpu.graph (imported here: they register then)
    assert graph_interfaces.String in {type(msg) for msg in others.values()}
    with McapRecordWriter(tmp_path / "others.mcap") as writer:
        for topic, msg in others.items():
            writer.write(topic, msg, 1)
    got = {record.topic: record.message for record in read_mcap(tmp_path / "others.mcap")}
    assert got == others


def test_round_trip_is_bit_exact_for_every_type(recording):
    path, samples = recording
    records = list(read_mcap(path))
    assert [record.topic for record in records] == list(samples)
    for index, (topic, msg, log_time_ns) in enumerate(records):
        original = samples[topic]
        assert type(msg) is type(original)
        assert msg == original, topic  # every field, arrays bit for bit (dtype, shape, bytes)
        assert log_time_ns == T0_NS + index * 1_000_000


def test_round_trip_keeps_arrays_headers_and_nan_bits(recording):
    path, samples = recording
    got = {record.topic: record.message for record in read_mcap(path)}
    image = got["/camera/image_be"]
    assert image.header.stamp.sec == -2 and image.header.stamp.nanosec == 999_999_999
    assert image.header.frame_id == "cam" and image.is_bigendian == 1
    np.testing.assert_array_equal(image.to_array(), samples["/camera/image_be"].to_array())
    depth = got["/scanner/depth"].to_array()
    assert np.isnan(depth[2:4, 3:5]).all() and np.isnan(depth).sum() == 4
    padded = got["/camera/image_padded"]
    assert padded.step == 24 and padded.data.tobytes() == samples["/camera/image_padded"].data.tobytes()
    phase = got["/scanner/phase"]
    assert phase.phases.shape == (2, 6, 8) and phase.phases.dtype == np.float32
    assert phase.phases.tobytes() == samples["/scanner/phase"].phases.tobytes()
    assert phase.valid.dtype == np.bool_ and not phase.phases.flags.writeable
    cloud = got["/scanner/points"].to_array()
    np.testing.assert_array_equal(cloud, samples["/scanner/points"].to_array())  # NaN == NaN here
    assert got["/debug/header"].frame_id == "ünïcode frame"
    assert got["/debug/time"].to_ns() == -4_750_000_000


def test_read_mcap_yields_log_time_order_and_filters_topics(tmp_path):
    samples = sample_messages()
    path = tmp_path / "order.mcap"
    with McapRecordWriter(path, compression="lz4", chunk_size_bytes=256) as writer:  # several chunks
        for log_time_ns in (30, 10, 20):
            writer.write("/projector/trigger", samples["/projector/trigger"], T0_NS + log_time_ns)
            writer.write("/camera/image_raw", samples["/camera/image_raw"], T0_NS + log_time_ns + 1)
        assert writer.message_counts == {"/projector/trigger": 3, "/camera/image_raw": 3}
    times = [record.log_time_ns - T0_NS for record in read_mcap(path)]
    assert times == [10, 11, 20, 21, 30, 31]
    only = list(read_mcap(path, topics=["/camera/image_raw"]))
    assert [record.log_time_ns - T0_NS for record in only] == [11, 21, 31]
    assert all(record.message == samples["/camera/image_raw"] for record in only)


def test_writer_accepts_a_binary_stream_and_leaves_it_open():
    stream = io.BytesIO()
    writer = McapRecordWriter(stream, compression="none")
    writer.write("/projector/trigger", sample_messages()["/projector/trigger"], 5)
    writer.close()
    writer.close()  # a second close does nothing
    assert writer.closed and not stream.closed
    stream.seek(0)
    summary = make_reader(stream).get_summary()
    assert summary.statistics.message_count == 1


# --------------------------------------------------------------------------------------------------
# The file as ROS 2 tools see it
# --------------------------------------------------------------------------------------------------

def test_image_is_readable_by_mcap_ros2_decoder_alone(recording):
    path, samples = recording
    [(schema, channel, message, decoded)] = _ros2_decoded(path, "/camera/image_raw")
    original = samples["/camera/image_raw"]
    assert (schema.name, schema.encoding, channel.message_encoding) == ("sensor_msgs/msg/Image", "ros2msg", "cdr")
    assert (decoded.height, decoded.width, decoded.encoding) == (12, 16, "mono8")
    assert (decoded.step, decoded.is_bigendian) == (16, 0)
    assert bytes(decoded.data) == original.data.tobytes() and len(decoded.data) == 12 * 16
    assert decoded.header.frame_id == "scanner_optical_frame"
    assert (decoded.header.stamp.sec, decoded.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert message.data[:4] == b"\x00\x01\x00\x00"  # CDR little-endian encapsulation header


def test_big_endian_mono16_image_and_negative_stamp_through_mcap_ros2(recording):
    path, samples = recording
    [(_, _, _, decoded)] = _ros2_decoded(path, "/camera/image_be")
    assert (decoded.encoding, decoded.is_bigendian, decoded.step) == ("mono16", 1, 18)
    pixels = np.frombuffer(decoded.data, ">u2").reshape(6, 9)
    np.testing.assert_array_equal(pixels, samples["/camera/image_be"].to_array())
    assert (decoded.header.stamp.sec, decoded.header.stamp.nanosec) == (-2, 999_999_999)


def test_camera_info_is_readable_by_mcap_ros2_decoder_alone(recording):
    path, samples = recording
    [(schema, _, _, decoded)] = _ros2_decoded(path, "/camera/camera_info")
    original = samples["/camera/camera_info"]
    assert schema.name == "sensor_msgs/msg/CameraInfo"
    assert (decoded.height, decoded.width, decoded.distortion_model) == (480, 640, "plumb_bob")
    assert list(decoded.d) == [-0.12, 0.05, 1e-4, -2e-4, 0.01]
    assert list(decoded.k) == [1200.0, 0.0, 319.5, 0.0, 1201.0, 239.5, 0.0, 0.0, 1.0]
    assert list(decoded.p) == original.p.tolist() and len(decoded.p) == 12
    assert list(decoded.r) == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    assert (decoded.binning_x, decoded.binning_y) == (2, 2)
    roi = decoded.roi
    assert (roi.x_offset, roi.y_offset, roi.height, roi.width, roi.do_rectify) == (8, 4, 32, 48, True)


def test_point_cloud_is_readable_by_mcap_ros2_decoder_alone(recording):
    path, samples = recording
    [(schema, _, _, decoded)] = _ros2_decoded(path, "/scanner/points")
    original = samples["/scanner/points"]
    assert schema.name == "sensor_msgs/msg/PointCloud2"
    assert (decoded.height, decoded.width, decoded.point_step, decoded.row_step) == (6, 8, 16, 128)
    assert [(f.name, f.offset, f.datatype, f.count) for f in decoded.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1)]
    assert decoded.is_dense is False and decoded.is_bigendian is False
    xyz = np.frombuffer(decoded.data, "<f4").reshape(6, 8, 4)
    assert xyz.tobytes() == original.data.tobytes()
    assert np.isnan(xyz[1:3, 2:5, :3]).all()
    [(_, _, _, mixed)] = _ros2_decoded(path, "/scanner/points_unorganized")
    assert [(f.name, f.offset, f.datatype, f.count) for f in mixed.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 2, 3), ("ring", 16, 4, 1), ("t", 24, 8, 1)]
    assert (mixed.height, mixed.width, mixed.point_step, mixed.row_step) == (1, 9, 32, 288)


def test_ros2_schemas_have_ros2_field_lists_and_dependencies():
    image = ros2_schema_text(Image)
    assert image.splitlines()[:7] == ["std_msgs/Header header", "uint32 height", "uint32 width",
                                      "string encoding", "uint8 is_bigendian", "uint32 step", "uint8[] data"]
    assert "=" * 80 + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id" in image
    assert "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec" in image
    cloud = ros2_schema_text(PointCloud2)
    assert "MSG: sensor_msgs/PointField\nuint8 INT8=1\n" in cloud and "uint8 FLOAT64=8\nstring name" in cloud
    info = ros2_schema_text(CameraInfo)
    assert "float64[9] k" in info and "float64[12] p" in info and "MSG: sensor_msgs/RegionOfInterest" in info


def test_summary_lists_channels_schemas_and_counts(tmp_path):
    samples = sample_messages()
    path = tmp_path / "summary.mcap"
    plan = {"/camera/image_raw": 3, "/scanner/points": 2, "/camera/camera_info": 1, "/projector/trigger": 4,
            "/scanner/phase": 1}
    with McapRecordWriter(path) as writer:
        for topic, count in plan.items():
            for index in range(count):
                writer.write(topic, samples[topic], T0_NS + index)
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    schemas = {schema.name: schema for schema in summary.schemas.values()}
    # every channel ROS 2 CDR with a ros2msg schema and rosbag2's offered_qos_profiles: ROS 2's tools read it all
    assert {name: schema.encoding for name, schema in schemas.items()} == {
        "sensor_msgs/msg/Image": "ros2msg", "sensor_msgs/msg/PointCloud2": "ros2msg",
        "sensor_msgs/msg/CameraInfo": "ros2msg", "dptpu_msgs/msg/Trigger": "ros2msg",
        "dptpu_msgs/msg/PhaseMaps": "ros2msg"}
    channels = {channel.topic: channel for channel in summary.channels.values()}
    assert {channel.message_encoding for channel in channels.values()} == {"cdr"}
    assert all(channel.metadata["offered_qos_profiles"].startswith("- history: 1\n  depth: 10\n  reliability: 1\n"
                                                                    "  durability: 2\n")
               for channel in channels.values())  # ROS 2's default profile: nothing else was offered
    counts = summary.statistics.channel_message_counts
    assert {topic: counts[channel.id] for topic, channel in channels.items()} == plan
    assert summary.statistics.message_count == 11 and summary.statistics.schema_count == 5
    definition = schemas["dptpu_msgs/msg/PhaseMaps"].data.decode()
    assert "uint32 height\nuint32 width\nfloat32[] phases\nfloat32[] modulation\nbool[] valid\n" in definition
    described = {channel.topic: channel for channel in describe_mcap(path)}
    assert {topic: channel.message_count for topic, channel in described.items()} == plan
    assert described["/projector/trigger"].type_name == "dptpu_msgs/msg/Trigger"
    assert all(channel.readable for channel in described.values())


def test_scanner_record_is_cdr_that_mcap_ros2_reads_from_the_schema(recording):
    """An independent reader (mcap-ros2-support's, as Foxglove and rosbag2 read) decodes a scanner channel from
    the file alone: the flattened maps with their height and width."""
    path, samples = recording
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        [(_, channel, _, decoded)] = list(reader.iter_decoded_messages(topics=["/scanner/phase"]))
    phase = samples["/scanner/phase"]
    assert channel.message_encoding == "cdr" and (decoded.height, decoded.width) == (6, 8)
    assert np.array_equal(np.array(decoded.phases, np.float32).reshape(2, 6, 8), phase.phases)
    assert np.array_equal(np.array(decoded.valid, bool).reshape(6, 8), phase.valid)
    assert list(decoded.frequencies) == list(phase.frequencies)


# --------------------------------------------------------------------------------------------------
# Conversions
# --------------------------------------------------------------------------------------------------

def test_is_ros2_type_separates_ros_types_from_scanner_types():
    assert is_ros2_type(Image) and is_ros2_type(CameraInfo) and is_ros2_type(PointCloud2)
    assert not is_ros2_type(Trigger) and not is_ros2_type(PhaseMaps) and not is_ros2_type(int)


def test_to_ros2_dict_and_back_is_exact_for_camera_info():
    original = sample_messages()["/camera/camera_info"]
    plain = to_ros2_dict(original)
    assert plain["k"][2] == 319.5 and plain["roi"]["do_rectify"] is True
    assert from_ros2(CameraInfo, plain) == original


def test_float64_bits_survive_cdr_even_nan_payloads(tmp_path):
    original = sample_messages()["/camera/camera_info"]
    original.d.view(np.uint64)[2] = 0x7FF0000000000123  # a signaling NaN with a payload
    original.k[1] = -0.0
    with McapRecordWriter(tmp_path / "bits.mcap") as writer:
        writer.write("/camera/camera_info", original, 1)
    [(_, msg, _)] = list(read_mcap(tmp_path / "bits.mcap"))
    assert msg.d.view(np.uint64)[2] == 0x7FF0000000000123
    assert np.signbit(msg.k[1]) and msg == original


def test_conversion_errors_name_the_problem():
    with pytest.raises(ValueError, match="dptpu_msgs/msg/Trigger is not recorded as ROS 2 CDR"):
        to_ros2_dict(Trigger())
    plain = to_ros2_dict(sample_messages()["/camera/image_raw"])
    del plain["step"]
    with pytest.raises(ValueError, match="Image: the decoded ROS 2 message has no field 'step'"):
        from_ros2(Image, plain)
    plain = to_ros2_dict(sample_messages()["/camera/image_raw"])
    plain["data"] = plain["data"][:-1]
    with pytest.raises(ValueError, match=r"Image.data must hold step \* height = 16 \* 12 = 192 bytes; got 191"):
        from_ros2(Image, plain)
    plain = to_ros2_dict(sample_messages()["/camera/image_raw"])
    plain["height"] = "12"
    with pytest.raises(ValueError, match="Image.height must be uint32; got str"):
        from_ros2(Image, plain)


# --------------------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------------------

def test_writer_refuses_bad_input(tmp_path):
    samples = sample_messages()
    with McapRecordWriter(tmp_path / "bad.mcap") as writer:
        writer.write("/t", samples["/projector/trigger"], 1)
        with pytest.raises(ValueError, match="topic '/t' is recorded as dptpu_msgs/msg/Trigger; got a "
                                             "sensor_msgs/msg/Image"):
            writer.write("/t", samples["/camera/image_raw"], 2)
        with pytest.raises(ValueError, match=r"log_time_ns must be an int of nanoseconds in \[0, 2\*\*64\); got -1"):
            writer.write("/t", samples["/projector/trigger"], -1)
        with pytest.raises(ValueError, match="topic must be a non-empty str; got ''"):
            writer.write("", samples["/projector/trigger"], 1)
        bad = Image(height=2, width=2, encoding="mono8", step=2, data=np.zeros(3, np.uint8))
        with pytest.raises(EncodeError, match=r"Image.data must hold step \* height = 2 \* 2 = 4 bytes; got 3"):
            writer.write("/image", bad, 1)
        with pytest.raises(ValueError, match="msg must be a message"):
            writer.write("/x", {"height": 1}, 1)
        assert writer.message_counts == {"/t": 1}
    with pytest.raises(ValueError, match="cannot write: the MCAP writer is closed"):
        writer.write("/t", samples["/projector/trigger"], 3)
    with pytest.raises(ValueError, match="compression must be one of zstd, lz4, none; got 'gzip'"):
        McapRecordWriter(tmp_path / "x.mcap", compression="gzip")


def test_reader_refuses_missing_non_mcap_and_truncated_files(tmp_path, recording):
    with pytest.raises(FileNotFoundError, match="no MCAP file at"):
        list(read_mcap(tmp_path / "missing.mcap"))
    (tmp_path / "text.mcap").write_text("not an mcap file at all")
    with pytest.raises(McapReadError, match="not an MCAP file"):
        list(read_mcap(tmp_path / "text.mcap"))
    path, _ = recording
    data = path.read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    with pytest.raises(McapReadError, match="cut.mcap"):
        list(read_mcap(tmp_path / "cut.mcap"))


def test_reader_refuses_or_skips_types_we_do_not_have(tmp_path):
    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as stream:
        writer = Ros2Writer(stream)
        pose = writer.register_msgdef("geometry_msgs/msg/Point", "float64 x\nfloat64 y\nfloat64 z")
        writer.write_message("/point", pose, {"x": 1.0, "y": 2.0, "z": 3.0}, log_time=10)
        image = writer.register_msgdef("sensor_msgs/msg/Image", ros2_schema_text(Image))
        writer.write_message("/image", image, to_ros2_dict(sample_messages()["/camera/image_raw"]), log_time=20)
        writer.finish()
    with pytest.raises(McapReadError, match="topic '/point' has type 'geometry_msgs/msg/Point', which dptpu has "
                                            "no message type for"):
        list(read_mcap(path))
    records = list(read_mcap(path, skip_unknown=True))
    assert [(record.topic, record.log_time_ns) for record in records] == [("/image", 20)]
    assert records[0].message == sample_messages()["/camera/image_raw"]
    assert {channel.topic: channel.readable for channel in describe_mcap(path)} == {"/image": True, "/point": False}


def _raw_scanner_file(path, schema_fields: dict, record: bytes):
    schema = {"format": "dptpu-msgpack", "format_version": 1, "type": "dptpu_msgs/msg/Trigger",
              "version": Trigger.SCHEMA_VERSION, "wire": 1, "definition": ""}
    schema.update(schema_fields)
    with open(path, "wb") as stream:
        writer = RawMcapWriter(stream)
        writer.start(profile="ros2", library="test")
        schema_id = writer.register_schema("dptpu_msgs/msg/Trigger", "dptpu-msgpack", msgpack.packb(schema))
        channel_id = writer.register_channel("/projector/trigger", "dptpu-msgpack", schema_id)
        writer.add_message(channel_id, log_time=7, data=record, publish_time=7)
        writer.finish()


def test_reader_refuses_other_schema_versions_and_malformed_records(tmp_path):
    good = msgpack_records.pack_message(sample_messages()["/projector/trigger"])
    _raw_scanner_file(tmp_path / "v9.mcap", {"version": 9}, good)
    with pytest.raises(McapReadError, match="schema version mismatch for dptpu_msgs/msg/Trigger: the file has "
                                            f"version 9, this build has {Trigger.SCHEMA_VERSION}"):
        list(read_mcap(tmp_path / "v9.mcap"))
    _raw_scanner_file(tmp_path / "ok.mcap", {}, good)
    assert [record.message for record in read_mcap(tmp_path / "ok.mcap")] == [sample_messages()["/projector/trigger"]]
    _raw_scanner_file(tmp_path / "junk.mcap", {}, b"\xc1garbage")
    with pytest.raises(McapReadError, match="message on '/projector/trigger' at log time 7 ns: record on topic "
                                            "'/projector/trigger' is not a msgpack array of frames"):
        list(read_mcap(tmp_path / "junk.mcap"))
    frames = msgpack.unpackb(good)
    _raw_scanner_file(tmp_path / "extra.mcap", {}, msgpack.packb([*frames, b"\x00" * 4]))
    with pytest.raises(McapReadError, match="header declares 0 array"):
        list(read_mcap(tmp_path / "extra.mcap"))
    phase_frames = msgpack.unpackb(msgpack_records.pack_message(sample_messages()["/scanner/phase"]))
    _raw_scanner_file(tmp_path / "wrongtype.mcap", {}, msgpack.packb(phase_frames))
    with pytest.raises(McapReadError, match="expected a dptpu_msgs/msg/Trigger; got a dptpu_msgs/msg/PhaseMaps"):
        list(read_mcap(tmp_path / "wrongtype.mcap"))


def test_msgpack_schema_round_trips_through_parse():
    assert msgpack_records.parse_schema_data("dptpu_msgs/msg/PhaseMaps",
                                             msgpack_records.schema_data(PhaseMaps)) is PhaseMaps
    with pytest.raises(ValueError, match="dptpu-msgpack schema named 'dptpu_msgs/msg/Trigger' describes type "
                                         "'dptpu_msgs/msg/PhaseMaps'"):
        msgpack_records.parse_schema_data("dptpu_msgs/msg/Trigger", msgpack_records.schema_data(PhaseMaps))


def test_offered_qos_is_rosbag2s_yaml_and_refuses_unknown_policies(tmp_path):
    from dptpu.tools.recording.offered_qos import offered_qos_profiles

    text = offered_qos_profiles({"history": "keep_last", "depth": 1, "reliability": "best_effort",
                                 "durability": "transient_local"})
    assert text.startswith("- history: 1\n  depth: 1\n  reliability: 2\n  durability: 1\n  deadline:\n"
                           "    sec: 2147483647\n    nsec: 4294967295\n")
    assert text.endswith("  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n"
                         "    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n")
    with pytest.raises(ValueError, match="QoS reliability must be one of reliable, best_effort; got 'fast'"):
        offered_qos_profiles({"reliability": "fast"})
    path = tmp_path / "offered.mcap"
    with McapRecordWriter(path) as writer:
        writer.offer_qos("/camera/camera_info", {"history": "keep_last", "depth": 1, "reliability": "reliable",
                                                 "durability": "transient_local"})
        writer.write("/camera/camera_info", sample_messages()["/camera/camera_info"], T0_NS)
    with open(path, "rb") as stream:
        (channel,) = make_reader(stream).get_summary().channels.values()
    assert channel.metadata["offered_qos_profiles"].startswith("- history: 1\n  depth: 1\n  reliability: 1\n"
                                                               "  durability: 1\n")
