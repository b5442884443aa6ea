"""``python -m dptpu.nodes.projector [--ros-args ...]``."""
import sys

from .node import main

sys.exit(main())
