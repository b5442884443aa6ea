"""``python -m dptpu.nodes.cloud [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
