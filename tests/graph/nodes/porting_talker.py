"""The ROS 2 tutorial's minimal publisher, on dptpu.graph. docs/porting-to-ros2.md shows this file.

On ROS 2, replace the three imports marked ``# ROS 2:`` and nothing else.
"""

import dptpu.graph as rclpy  # ROS 2: import rclpy
from dptpu.graph.interfaces import String  # ROS 2: from std_msgs.msg import String
from dptpu.graph.node import Node  # ROS 2: from rclpy.node import Node


class MinimalPublisher(Node):

    def __init__(self):
        super().__init__('minimal_publisher')
        self.publisher_ = self.create_publisher(String, 'topic', 10)
        timer_period = self.declare_parameter('period_sec', 0.5).value  # seconds
        self.timer = self.create_timer(timer_period, self.timer_callback)
        self.i = 0

    def timer_callback(self):
        msg = String()
        msg.data = 'Hello World: %d' % self.i
        self.publisher_.publish(msg)
        self.get_logger().info('Publishing: "%s"' % msg.data)
        self.i += 1


def main(args=None):
    rclpy.init(args=args)
    minimal_publisher = MinimalPublisher()
    try:
        rclpy.spin(minimal_publisher)
    except KeyboardInterrupt:
        pass
    minimal_publisher.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
