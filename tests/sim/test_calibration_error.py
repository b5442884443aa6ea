"""The calibration_error effect: the rendered rig differs from the given one by exactly the documented change."""
from dataclasses import replace

import numpy as np
import pytest

from dptpu.fpp.calibration import DeviceModel
from dptpu.sim.effects import parse_effects
from dptpu.sim.effects.calibration import calibration_params, calibration_vector, miscalibrated_rig
from dptpu.sim.effects.geometry import render_rig
from dptpu.sim.raycast import project_to_projector


@pytest.fixture
def pinhole_rig(small_rig):
    """The nominal rig with a distortion-free projector (the formulas below are pinhole)."""
    p = small_rig.projector
    return replace(small_rig, projector=DeviceModel(K=p.K, dist=np.zeros(5), R=p.R, T=p.T, size=p.size))


def _points_in_front_of_projector(rig, count=50):
    """World points (count, 3) at 300-500 rig units in front of the projector, spread over its view."""
    rng = np.random.default_rng(0)
    local = np.column_stack([rng.uniform(-0.2, 0.2, count), rng.uniform(-0.2, 0.2, count), np.ones(count)])
    local *= rng.uniform(300, 500, count)[:, None]
    return (local - rig.projector.T) @ rig.projector.R  # X = R^T (X_p - T)


def test_projector_translation_moves_the_coordinate_by_fx_t_over_depth(pinhole_rig):
    small_rig = pinhole_rig
    points = _points_in_front_of_projector(small_rig)
    xy, depth = project_to_projector(small_rig, points)
    moved = miscalibrated_rig(small_rig, {"translation": [2.0, 0.0, 0.0]})
    xy2, _ = project_to_projector(moved, points)
    # x' = fx (X_p + t) / Z_p + cx
    np.testing.assert_allclose(xy2[:, 0] - xy[:, 0], small_rig.projector.K[0, 0] * 2.0 / depth, rtol=1e-9)
    np.testing.assert_allclose(xy2[:, 1], xy[:, 1], atol=1e-9)


def test_projector_rotation_turns_about_its_own_centre(pinhole_rig):
    small_rig = pinhole_rig
    turned = miscalibrated_rig(small_rig, {"rotation_deg": [0.0, 0.3, 0.0]})
    np.testing.assert_allclose(turned.projector.center, small_rig.projector.center, atol=1e-9)
    # a point on the projector's axis moves to fx tan(0.3 deg) from the principal point
    on_axis = small_rig.projector.center + 400.0 * small_rig.projector.R[2]
    xy, _ = project_to_projector(turned, on_axis[None])
    K = small_rig.projector.K
    assert xy[0, 0] - K[0, 2] == pytest.approx(K[0, 0] * np.tan(np.radians(0.3)), rel=1e-6)


def test_focal_scale_and_principal_point(pinhole_rig):
    small_rig = pinhole_rig
    points = _points_in_front_of_projector(small_rig)
    xy, _ = project_to_projector(small_rig, points)
    changed = miscalibrated_rig(small_rig, {"projector_focal_scale": 1.01, "projector_principal_px": [3.0, -2.0],
                                            "camera_focal_scale": 0.99, "camera_principal_px": [1.5, 0.5]})
    xy2, _ = project_to_projector(changed, points)
    K = small_rig.projector.K
    np.testing.assert_allclose(xy2 - K[:2, 2] - [3.0, -2.0], 1.01 * (xy - K[:2, 2]), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(changed.camera.K[0, 0], 0.99 * small_rig.camera.K[0, 0])
    np.testing.assert_allclose(changed.camera.K[:2, 2], small_rig.camera.K[:2, 2] + [1.5, 0.5])


def test_render_rig_applies_it_and_the_neutral_effect_changes_nothing(small_rig):
    effect = parse_effects([{"calibration_error": {"translation": [1.0, 0.0, 0.0]}}])
    rendered = render_rig(small_rig, effect)
    np.testing.assert_allclose(rendered.projector.T, small_rig.projector.T + [1.0, 0.0, 0.0])
    neutral = render_rig(small_rig, parse_effects(["calibration_error"]))
    np.testing.assert_allclose(neutral.projector.T, small_rig.projector.T)
    np.testing.assert_allclose(neutral.projector.R, small_rig.projector.R)
    assert neutral.camera is small_rig.camera


def test_parameter_vector_round_trip_and_bad_values():
    params = {"rotation_deg": [0.1, -0.2, 0.0], "translation": [1.0, 2.0, 3.0], "camera_focal_scale": 1.002,
              "projector_focal_scale": 0.998, "camera_principal_px": [1.0, 2.0], "projector_principal_px": [3.0, 4.0]}
    vector = calibration_vector(params)
    assert vector[6] == pytest.approx(0.002) and vector[7] == pytest.approx(-0.002)
    back = calibration_params(vector)
    for key, value in params.items():
        np.testing.assert_allclose(back[key], value)
    with pytest.raises(ValueError, match=r"calibration_error.camera_principal_px: must be a list of 2 numbers"):
        parse_effects([{"calibration_error": {"camera_principal_px": [1.0]}}])
