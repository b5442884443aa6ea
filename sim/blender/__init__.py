"""The Blender renderer of the twin: Cycles path tracing of the same rig and scene as the raycast renderer.

Blender (``bpy`` 4.5) pins numpy < 2, so it runs in its own environment as a worker process
(:mod:`~dptpu.sim.blender.environment`, created by ``dptpu sim setup-blender``); :func:`render_frames` writes a job,
runs :mod:`~dptpu.sim.blender.worker` there, and resamples the frames into the real camera
(:mod:`~dptpu.sim.blender.camera_warp`). The Blender parameters of the paper's Table 1 are in
:mod:`dptpu.sim.blender_params`. docs/blender.md tells the whole story.
"""
from .environment import BlenderNotInstalledError, blender_env_dir, blender_python, setup_blender
from .render import BlenderRender, BlenderWorkerError, render, render_frames

__all__ = ["BlenderNotInstalledError", "BlenderRender", "BlenderWorkerError", "blender_env_dir", "blender_python",
           "render", "render_frames", "setup_blender"]
