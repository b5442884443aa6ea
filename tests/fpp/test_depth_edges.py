"""Flying points, modulation dips and isolated points at depth edges (dptpu.fpp.depth_edges), on analytic depth maps
and on an outside rig rendered with mixed pixels (tests/mixed_pixel_rigs.py)."""
import numpy as np
import pytest

from dptpu.fpp import phase, tpu
from dptpu.fpp.depth_edges import DEFAULT_MAX_SLOPE, beside_steps, edge_points, flying_points
from dptpu.fpp.triangulate import Triangulator
from tests.mixed_pixel_rigs import PROJECTOR_SIZE, OutsideRig, default_scene, render


def test_a_tilted_plane_has_no_flying_point_up_to_the_slope_limit():
    focal_px = 500.0
    rows, cols = np.mgrid[0:40, 0:50].astype(float)
    z0 = 600.0
    # depth changes by slope footprints per column: z(c+1) - z(c) = slope * z / f (a surface atan(slope) steep)
    for slope, expected in ((0.9 * DEFAULT_MAX_SLOPE, 0), (1.1 * DEFAULT_MAX_SLOPE, 40 * 48)):
        depth = z0 * (1 + slope / focal_px) ** cols
        assert np.count_nonzero(flying_points(depth, focal_px)) == expected  # the two border columns have 1 side


def test_a_pixel_between_two_surfaces_is_flying_and_the_edge_pixels_are_not():
    depth = np.full((5, 9), 500.0)
    depth[:, 5:] = 600.0  # a step of 100 mm at a 1 mm footprint
    depth[:, 4] = 550.0  # the mixed column
    flying = flying_points(depth, 500.0)
    assert flying[:, 4].all() and not flying[:, :4].any() and not flying[:, 5:].any()
    depth[2, 4] = np.nan  # no point: never flying, nor does a NaN neighbour make one
    assert not flying_points(depth, 500.0)[2, 4]


def test_the_last_pixel_on_each_side_of_a_step_is_beside_it():
    depth = np.full((5, 9), 500.0)
    depth[:, 5:] = 600.0  # 100 mm at a 1 mm footprint: 100 footprints
    beside = beside_steps(depth, 500.0, max_step=10.0)
    assert np.argwhere(beside.any(axis=0)).ravel().tolist() == [4, 5]
    assert not beside_steps(depth, 500.0, max_step=150.0).any()
    assert not edge_points(depth, 500.0, max_step=np.inf).dropped.any()


def test_modulation_dips_and_isolated_points():
    depth = np.full((6, 6), 500.0)
    modulation = np.full((6, 6), 100.0)
    modulation[2, 2] = 55.0  # below 0.6 of its brightest neighbour
    depth[5, 5] = 500.0
    depth[4, :] = np.nan
    depth[5, :5] = np.nan  # (5, 5) keeps no neighbour with a point
    edges = edge_points(depth, 500.0, modulation)
    assert np.argwhere(edges.modulation_dip).tolist() == [[2, 2]]
    assert np.argwhere(edges.isolated).tolist() == [[5, 5]]
    assert edges.counts(np.isfinite(depth)) == {"flying": 0, "beside_step": 0, "modulation_dip": 1, "isolated": 1,
                                                "total": 2}
    assert not edge_points(depth, 500.0, None, min_neighbours=0).dropped.any()
    with pytest.raises(ValueError, match="min_modulation_ratio"):
        edge_points(depth, 500.0, modulation, min_modulation_ratio=1.5)


@pytest.mark.parametrize("outside", [OutsideRig(),
                                     OutsideRig(camera_focal_px=700, projector_focal_px=1800, baseline_mm=300,
                                                toe_in_deg=22, distance_mm=1000)])
def test_edge_filter_leaves_no_point_off_the_surface_on_a_12_step_capture_with_mixed_pixels(outside):
    # heterodyne 96/95 at 12 steps, 1.57 DN noise, no confidence threshold: what lies off the surface are the mixed
    # pixels at depth edges, the partly shadowed ones and the classical wrong orders; measured: 2.2 / 2.6 % of the
    # points more than 1 mm off without the filter, 0.006 / 0.000 % with it, 97.2 / 97.0 % of the pure pixels kept
    capture = render(outside, default_scene(outside, seed=1), [96.0, 95.0], steps=12, noise_dn=1.5693, seed=1)
    maps = [phase.wrapped_phase(capture.frames[f]) for f in (96.0, 95.0)]
    valid = maps[0].modulation >= 5.1
    result = tpu.unwrap_heterodyne([m.phase for m in maps], [96.0, 95.0], valid=valid)
    x_p = np.where(result.valid, result.absolute_phase * PROJECTOR_SIZE[0] / (2 * np.pi * 96.0), np.nan)
    points = Triangulator(capture.rig, axis="x", distortion=False).camera_points(x_p, dtype=np.float64)
    has_point = np.isfinite(points[..., 2])
    off = has_point & (capture.scene.distance_mm(np.nan_to_num(points)) > 1.0)
    assert off.sum() > 0.005 * has_point.sum()  # the mixed pixels are there
    keep = has_point & ~edge_points(points[..., 2], outside.camera_focal_px, maps[0].modulation).dropped
    assert (keep & off).sum() <= 0.0005 * keep.sum()
    assert (keep & capture.pure).sum() >= 0.96 * capture.pure.sum()
