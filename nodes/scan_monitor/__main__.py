"""``python -m dptpu.nodes.scan_monitor [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
