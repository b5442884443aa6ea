"""``python -m dptpu.nodes.camera [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
