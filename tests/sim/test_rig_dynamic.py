"""The paper's dynamic (unseen) rig preset of dptpu.sim.rig."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.sim.rig import dynamic_rig, load_twin_rig, working_distance, working_point


def test_dynamic_rig_matches_the_published_numbers():
    rig = dynamic_rig()
    assert rig.camera.size == (640, 480) and rig.projector.size == (1024, 768)
    assert rig.camera.K[0, 0] == pytest.approx(18.7 / 0.0048)  # 3895.8 px
    axis_c = rig.camera.R.T @ [0.0, 0.0, 1.0]
    axis_p = rig.projector.R.T @ [0.0, 0.0, 1.0]
    assert np.degrees(np.arccos(axis_c @ axis_p)) == pytest.approx(10.07, abs=1e-9)
    assert working_distance(rig) == pytest.approx(600.0, abs=1e-6)
    np.testing.assert_allclose(working_point(rig), [0.0, 0.0, 600.0], atol=1e-6)
    baseline = np.linalg.norm(rig.projector.center - rig.camera.center)
    assert baseline == pytest.approx(600.0 * np.tan(np.radians(10.07)), rel=1e-12)  # 106.6 mm (module notes)


def test_dynamic_rig_projector_lights_the_camera_field_at_the_working_point():
    rig = dynamic_rig()
    # the camera's image corners at 600 mm project inside the 1024x768 DMD
    corners = np.array([[0.0, 0.0], [639.0, 0.0], [0.0, 479.0], [639.0, 479.0]])
    K = rig.camera.K
    rays = np.c_[(corners[:, 0] - K[0, 2]) / K[0, 0], (corners[:, 1] - K[1, 2]) / K[1, 1], np.ones(4)]
    points = rays * 600.0  # (4, 3) world = camera frame, distortion ignored (k1 = -0.03 moves corners < 1 px)
    cam = rig.projector.R @ points.T + rig.projector.T[:, None]  # (3, 4)
    uv = (rig.projector.K @ (cam / cam[2]))[:2].T
    assert np.all(uv > 0) and np.all(uv[:, 0] < 1023) and np.all(uv[:, 1] < 767)


def test_load_twin_rig_builds_the_dynamic_preset_at_a_render_size():
    rig = load_twin_rig("dynamic", size="160x120")
    assert rig.camera.size == (160, 120) and rig.projector.size == (1024, 768)
    assert rig.camera.K[0, 0] == pytest.approx(18.7 / 0.0048 / 4)
