"""``python -m dptpu.nodes.unwrap [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
