"""``python -m dptpu.sim.blender``: create the Blender environment (what ``dptpu sim setup-blender`` does)."""
import sys

from .environment import BlenderNotInstalledError, setup_blender

try:
    setup_blender()
except BlenderNotInstalledError as exc:
    print(f"dptpu sim setup-blender: error: {exc}", file=sys.stderr)
    sys.exit(2)
