"""``python -m dptpu.nodes.ros2_bridge [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
