"""A small publisher process for the recording end-to-end test (``python -m tests.tools.recording.publish_samples``).

It publishes, with the rclpy-style API of ``dptpu.graph``:

1. one ``CameraInfo`` on ``/camera/camera_info`` (TRANSIENT_LOCAL, depth 1) right away, before anyone
   listens, so only a TRANSIENT_LOCAL subscription (the recorder's) can get it;
2. once ``/projector/trigger``, ``/camera/image_raw``, ``/scanner/points`` and the CameraInfo topic each
   have a subscription, and :data:`GAP_S` seconds later (so the CameraInfo's replay to the late subscriber
   comes first): a ``Trigger``, three mono8 ``Image``\\ s and one ``PointCloud2``, :data:`GAP_S` seconds apart;

then stays up :data:`LINGER_S` seconds and exits 0 (3 when nobody subscribed within :data:`WAIT_S`).
:func:`published_messages` gives the same messages to the test for comparison.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from dptpu import graph
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import CameraInfo, Header, Image, PointCloud2, Time, Trigger

#: Seconds between two published messages of step 2.
GAP_S = 0.15
#: Seconds to wait for the subscriptions.
WAIT_S = 15.0
#: Seconds to stay up after the last message.
LINGER_S = 1.0
CAMERA_INFO_TOPIC = "/camera/camera_info"


def published_messages() -> list[tuple[str, object]]:
    """``[(topic, message), ...]`` of step 2, in publication order (seeded)."""
    rng = np.random.default_rng(0)
    out = [("/projector/trigger", Trigger(header=Header(stamp=Time(sec=100, nanosec=1), frame_id="projector"),
                                          sequence_id=7, pattern_index=2, pattern_count=3, frequency=10.9,
                                          steps=3, step=2))]
    for index in range(3):
        pixels = rng.integers(0, 256, (24, 32), dtype=np.uint8)
        header = Header(stamp=Time(sec=100, nanosec=1000 + index), frame_id="scanner_optical_frame")
        out.append(("/camera/image_raw", Image.from_array(pixels, header=header)))
    xyz = rng.normal(0.0, 1.0, (6, 8, 3)).astype(np.float32)
    xyz[2, 3] = np.nan
    out.append(("/scanner/points", PointCloud2.from_array(
        xyz, ("x", "y", "z"), header=Header(stamp=Time(sec=100, nanosec=5000), frame_id="scanner_optical_frame"))))
    return out


def camera_info() -> CameraInfo:
    """The CameraInfo of step 1."""
    return CameraInfo.from_intrinsics([[500.0, 0.0, 15.5], [0.0, 501.0, 11.5], [0.0, 0.0, 1.0]],
                                      [0.01, -0.02, 0.0, 0.0, 0.003], 32, 24,
                                      header=Header(stamp=Time(sec=99, nanosec=0), frame_id="scanner_optical_frame"))


def main() -> int:
    graph.init(args=sys.argv)
    node = graph.create_node("sample_publisher")
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    info_publisher = node.create_publisher(CameraInfo, CAMERA_INFO_TOPIC, latched)
    info_publisher.publish(camera_info())
    messages = published_messages()
    publishers = {}
    for topic, msg in messages:
        if topic not in publishers:
            publishers[topic] = node.create_publisher(type(msg), topic, 10)
    for publisher in [*publishers.values(), info_publisher]:
        if not publisher.wait_for_subscriptions(1, timeout_sec=WAIT_S):
            print(f"publish_samples: no subscription on {publisher.topic} within {WAIT_S} s", file=sys.stderr)
            graph.shutdown()
            return 3
    time.sleep(GAP_S)
    for topic, msg in messages:
        publishers[topic].publish(msg)
        time.sleep(GAP_S)
    time.sleep(LINGER_S)
    graph.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
