"""sim.outside_rigs: the outside-rig generators moved from tests/outside_rigs.py, tests/mixed_pixel_rigs.py and
experiments/cloud_eval.py give the same rigs and scenes as before the move, and the old names still resolve."""
import hashlib

import numpy as np
import pytest

from dptpu.sim import outside_rigs

#: SHA-256 (first 16 hex digits) of every device's K, dist, R, T and size as float64, computed with the modules
#: before the move (tests/outside_rigs.py, tests/mixed_pixel_rigs.py, experiments/cloud_eval.py at a5a7cb1).
BEFORE = {"random 0": "3f196bbd12acfcc5", "random 1": "5e5b763d9cdcf65b", "random 2": "53e60615fc65349c",
          "random 3": "1072cef8c8c385a6", "random 4": "7ff508a969d379af", "issue16": "4fc709d06b110a7e",
          "mixed": "8e13a930720484c5", "eval f1800-b150-14deg": "41fb9971872dd9b9",
          "eval f1300-b79-5deg": "61fc9466ff5f7fa3", "eval f2400-b164-20deg": "7f4dee822449c748"}
SCENE_BEFORE = "3100eb80defafe4b"  # spheres_and_plane(issue16_rig(), 3): every mesh's vertices


def _digest(rig) -> str:
    h = hashlib.sha256()
    for device in (rig.camera, rig.projector):
        for array in (device.K, device.dist, device.R, device.T, np.asarray(device.size)):
            h.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def _rigs():
    rigs = {f"random {seed}": outside_rigs.random_outside_rig(seed) for seed in range(5)}
    rigs["issue16"] = outside_rigs.issue16_rig()
    rigs["mixed"] = outside_rigs.MixedPixelRig().rig()
    rigs.update({f"eval {r.name}": r.rig((320, 240)) for r in outside_rigs.OUTSIDE_RIGS})
    return rigs


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_the_same_seeds_give_the_same_rigs_as_before_the_move(name):
    assert _digest(_rigs()[name]) == BEFORE[name]


def test_the_same_seed_gives_the_same_scene():
    scene = outside_rigs.spheres_and_plane(outside_rigs.issue16_rig(), 3)
    vertices = b"".join(np.ascontiguousarray(m.vertices, dtype=np.float64).tobytes() for m in scene.meshes)
    assert hashlib.sha256(vertices).hexdigest()[:16] == SCENE_BEFORE


def test_the_old_modules_re_export_the_same_objects():
    from dptpu.experiments import cloud_eval
    from tests import mixed_pixel_rigs
    from tests import outside_rigs as old

    for name in old.__all__:
        assert getattr(old, name) is getattr(outside_rigs, name), name
    assert mixed_pixel_rigs.OutsideRig is outside_rigs.MixedPixelRig
    assert mixed_pixel_rigs.PROJECTOR_SIZE == outside_rigs.MIXED_PIXEL_PROJECTOR_SIZE
    assert cloud_eval.OUTSIDE_RIGS is outside_rigs.OUTSIDE_RIGS and cloud_eval.EvalRig is outside_rigs.EvalRig
