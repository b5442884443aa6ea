"""Test node: declares parameters (overridable from the command line and files) and serves two services.

Parameters: a (int 0), b (int 0), c (str "default"), rate_hz (double 1.0, must stay > 0), nested.x (int 0),
names (string array ["x"]). Services: ``~/toggle`` (SetBool; raises on data=False) and ``~/report``
(Trigger; message = the parameters as JSON). Prints ``{"event": "ready", "params": {...}}``.
"""

import json
import sys
import time

import dptpu.graph as rclpy
from dptpu.graph import SetBool, SetParametersResult, Trigger
from dptpu.graph.node import Node


class ParamNode(Node):
    def __init__(self):
        super().__init__("param_node")
        self.declare_parameters("", [("a", 0), ("b", 0), ("c", "default"), ("rate_hz", 1.0), ("names", ["x"])])
        self.declare_parameter("nested.x", 0)
        self.add_on_set_parameters_callback(self.check)
        self.create_service(SetBool, "~/toggle", self.toggle)
        self.create_service(Trigger, "~/report", self.report)

    def check(self, parameters):
        for parameter in parameters:
            if parameter.name == "rate_hz" and parameter.value <= 0:
                return SetParametersResult(successful=False, reason="rate_hz must be > 0")
        return SetParametersResult(successful=True)

    def values(self):
        return {name: self.get_parameter(name).value for name in ("a", "b", "c", "rate_hz", "nested.x", "names")}

    def toggle(self, request, response):
        if not request.data:
            raise ValueError("refused to switch off")
        response.success = True
        response.message = "on"
        return response

    def report(self, request, response):
        response.success = True
        response.message = json.dumps(self.values())
        return response


def main():
    rclpy.init(args=sys.argv)
    node = ParamNode()
    print(json.dumps({"event": "ready", "params": node.values()}), flush=True)
    deadline = time.monotonic() + 20.0
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
