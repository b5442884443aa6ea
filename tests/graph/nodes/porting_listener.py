"""The ROS 2 tutorial's minimal subscriber, on dptpu.graph. docs/porting-to-ros2.md shows this file.

On ROS 2, replace the three imports marked ``# ROS 2:`` and nothing else.
"""

import dptpu.graph as rclpy  # ROS 2: import rclpy
from dptpu.graph.interfaces import String  # ROS 2: from std_msgs.msg import String
from dptpu.graph.node import Node  # ROS 2: from rclpy.node import Node


class MinimalSubscriber(Node):

    def __init__(self):
        super().__init__('minimal_subscriber')
        self.count = self.declare_parameter('count', 0).value  # stop after this many (0: never)
        self.heard = 0
        self.subscription = self.create_subscription(String, 'topic', self.listener_callback, 10)

    def listener_callback(self, msg):
        self.get_logger().info('I heard: "%s"' % msg.data)
        self.heard += 1
        if self.count and self.heard >= self.count:
            rclpy.shutdown()  # spin returns once the context is shut down


def main(args=None):
    rclpy.init(args=args)
    minimal_subscriber = MinimalSubscriber()
    try:
        rclpy.spin(minimal_subscriber)
    except KeyboardInterrupt:
        pass
    minimal_subscriber.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
