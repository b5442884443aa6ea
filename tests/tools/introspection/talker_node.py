"""Test node for the introspection CLI: publishes a small Image at ``rate_hz`` and serves two services.

Node ``/talker`` (remappable). Parameters: ``level`` (int, 7): the image is ``level + [0, 1, ..., 31]``
as a 4x8 mono8 image, so its data has min ``level``, max ``level + 31``, mean ``level + 15.5``;
``frame_id`` (str, ``"talker_frame"``): its ``header.frame_id``; ``rate_hz`` (double, 20.0, must stay
> 0). Topic ``~/image`` (``sensor_msgs/msg/Image``, depth 10). Services ``~/reset`` (Trigger: the
message says how many images were published, then the count restarts) and ``~/enable`` (SetBool:
pause or resume publishing). Prints ``{"event": "ready"}`` once everything exists; exits after
``--lifetime`` seconds at the latest.
"""

import json
import sys
import time

import numpy as np

import dptpu.graph as rclpy
from dptpu.graph import SetBool, SetParametersResult, Trigger
from dptpu.graph.node import Node
from dptpu.messages import Header, Image, Time

IMAGE_SHAPE = (4, 8)


class Talker(Node):
    def __init__(self):
        super().__init__("talker")
        self.declare_parameter("level", 7)
        self.declare_parameter("frame_id", "talker_frame")
        self.declare_parameter("rate_hz", 20.0)
        self.add_on_set_parameters_callback(self.check)
        self.publisher = self.create_publisher(Image, "~/image", 10)
        self.count = 0
        self.enabled = True
        self.create_service(Trigger, "~/reset", self.reset)
        self.create_service(SetBool, "~/enable", self.enable)
        self.timer = self.create_timer(1.0 / self.get_parameter("rate_hz").value, self.tick)

    def check(self, parameters):
        for parameter in parameters:
            if parameter.name == "rate_hz" and parameter.value <= 0:
                return SetParametersResult(successful=False, reason="rate_hz must be > 0")
            if parameter.name == "level" and not 0 <= parameter.value <= 224:
                return SetParametersResult(successful=False, reason="level must lie in [0, 224]")
        return SetParametersResult(successful=True)

    def tick(self):
        if not self.enabled:
            return
        level = self.get_parameter("level").value
        pixels = (level + np.arange(IMAGE_SHAPE[0] * IMAGE_SHAPE[1])).astype(np.uint8).reshape(IMAGE_SHAPE)
        header = Header(stamp=Time.from_ns(time.time_ns()), frame_id=self.get_parameter("frame_id").value)
        self.publisher.publish(Image.from_array(pixels, header=header))
        self.count += 1

    def reset(self, request, response):
        response.success = True
        response.message = f"published {self.count} images"
        self.count = 0
        return response

    def enable(self, request, response):
        self.enabled = bool(request.data)
        response.success = True
        response.message = "publishing" if self.enabled else "paused"
        return response


def main():
    lifetime_s = float(sys.argv[sys.argv.index("--lifetime") + 1]) if "--lifetime" in sys.argv else 60.0
    rclpy.init(args=sys.argv)
    node = Talker()
    print(json.dumps({"event": "ready", "node": node.get_fully_qualified_name(),
                      "topic": node.publisher.topic_name}), flush=True)
    deadline = time.monotonic() + lifetime_s
    try:
        while time.monotonic() < deadline and rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
