"""``python -m dptpu.nodes.sim [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
