"""``python -m dptpu.nodes.phase [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
