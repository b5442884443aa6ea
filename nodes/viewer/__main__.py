"""``python -m dptpu.nodes.viewer [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
