"""Shared fixtures of the twin's tests: a small DP-TPU-like rig (160x120) and traced scenes."""
import numpy as np
import pytest

from dptpu.sim.rig import nominal_rig


@pytest.fixture(scope="session")
def small_rig():
    """The nominal rig (camera 640x480 resampled to 160x120), no effects."""
    return nominal_rig(camera_size=(160, 120))


@pytest.fixture(scope="session")
def plane_samples(small_rig):
    from dptpu.sim.raycast import trace
    from dptpu.sim.scenes import load_scene

    return trace(small_rig, load_scene("plane", small_rig))


@pytest.fixture(scope="session")
def sphere_samples(small_rig):
    from dptpu.sim.raycast import trace
    from dptpu.sim.scenes import sphere_scene

    return trace(small_rig, sphere_scene(small_rig, subdivisions=5))


def rng():
    return np.random.default_rng(0)
