"""A robot-side subscriber: print the size and nearest point of every scan (run while a rig launch file runs).

    dptpu launch launch/sim_rig.yaml &      # or a real rig
    python examples/subscriber.py

With rclpy instead of dptpu: ``import rclpy``, ``from rclpy.node import Node``, ``from sensor_msgs.msg import
PointCloud2`` and ``sensor_msgs_py.point_cloud2.read_points_numpy`` for the x, y, z array (docs/porting-to-ros2.md).
"""
import numpy as np

import dptpu.graph as rclpy
from dptpu.graph.node import Node
from dptpu.messages import PointCloud2


class CloudListener(Node):
    def __init__(self):
        super().__init__("cloud_listener")
        self.create_subscription(PointCloud2, "/scanner/points", self.on_cloud, 10)

    def on_cloud(self, cloud: PointCloud2) -> None:
        xyz = cloud.to_array(["x", "y", "z"])            # (H, W, 3) metres, camera optical frame, NaN = no point
        points = xyz[np.isfinite(xyz[..., 2])]
        nearest = points[np.argmin(points[:, 2])] if len(points) else [np.nan] * 3
        print(f"{cloud.width}x{cloud.height} cloud, {len(points)} points, nearest at {np.round(nearest, 3)} m")


rclpy.init()
rclpy.spin(CloudListener())
