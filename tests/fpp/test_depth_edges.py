"""Flying points, modulation dips and isolated points at depth edges (dptpu.fpp.depth_edges), on analytic depth maps
and on an outside rig rendered with mixed pixels (tests/mixed_pixel_rigs.py)."""
import numpy as np
import pytest

from dptpu.fpp import phase, tpu
from dptpu.fpp.depth_edges import edge_points
from dptpu.fpp.depth_steps import beside_steps
from dptpu.fpp.flying_points import DEFAULT_MAX_SLOPE, flying_points, on_a_ramp
from dptpu.fpp.shadow_border import depth_per_pixel
from dptpu.fpp.triangulate import Triangulator
from tests.mixed_pixel_rigs import PROJECTOR_SIZE, OutsideRig, default_scene, render


def test_a_tilted_plane_has_no_flying_point_up_to_the_slope_limit():
    focal_px = 500.0
    rows, cols = np.mgrid[0:40, 0:50].astype(float)
    z0 = 600.0
    # depth changes by slope footprints per column: z(c+1) - z(c) = slope * z / f (a surface atan(slope) steep)
    for slope, expected in ((0.9 * DEFAULT_MAX_SLOPE, 0), (1.1 * DEFAULT_MAX_SLOPE, 40 * 48)):
        depth = z0 * (1 + slope / focal_px) ** cols
        # without the ramp test every pixel with two sides is apart from both (the border columns have one side)
        assert np.count_nonzero(flying_points(depth, focal_px, max_ramp_bend=0.0)) == expected
        # a straight ramp, however steep: a plane, kept (but two pixels from the image's border: no line of five)
        assert not flying_points(depth, focal_px)[:, 2:-2].any()


def test_a_steep_plane_is_kept_where_its_line_runs_straight_a_mixed_pixel_never():
    focal_px, z0, steps = 500.0, 600.0, np.arange(30, dtype=float)
    rng = np.random.default_rng(3)
    # a plane 81 degrees from facing the camera (6 footprints a column), depth noise 0.1 footprint: the second
    # differences' noise (sqrt(6) * 0.1 = 0.25 footprint) stays below a quarter of the mean step (1.5 footprints)
    ramp = z0 * (1 + 6.0 / focal_px) ** steps + rng.normal(0.0, 0.1 * z0 / focal_px, (8, 30))
    flying = flying_points(ramp, focal_px)
    assert not flying[2:-2, 2:-2].any()
    # a pixel next to the border's pixel has no line of five along the row (nor along a diagonal, apart too at 6
    # footprints a column: above sqrt(2) * 4): not judged a ramp, still flying
    assert flying[:, [1, -2]].all() and flying[[1, -2], 2:-2].all()
    assert on_a_ramp(ramp, np.array([4]), np.array([10]), 0, 1).tolist() == [True]
    # a step of 100 footprints between two flat sides: the mixed column, for any share w of the far side, bends its
    # line by at least the mean step (ratio >= 1), so it stays flying and the sides stay clean
    for w in (0.1, 0.3, 0.5, 0.7, 0.9):
        depth = np.full((5, 12), 500.0)
        depth[:, 7:] = 600.0
        depth[:, 6] = 500.0 + w * 100.0
        flying = flying_points(depth, 500.0)
        assert flying[:, 6].all() and not flying[:, :6].any() and not flying[:, 7:].any(), w
    # a step blurred over two pixels (1/3, 2/3): both bend (1/3 of the step against a limit of 1/12): flying
    depth = np.full((5, 12), 500.0)
    depth[:, 6], depth[:, 7], depth[:, 8:] = 500.0 + 100.0 / 3, 500.0 + 200.0 / 3, 600.0
    assert np.argwhere(flying_points(depth, 500.0).any(axis=0)).ravel().tolist() == [6, 7]
    with pytest.raises(ValueError, match="max_ramp_bend"):
        flying_points(depth, 500.0, max_ramp_bend=-1.0)


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
    assert np.argwhere(beside_steps(depth, 500.0, max_step=10.0, side="far").any(axis=0)).ravel().tolist() == [5]
    assert np.argwhere(beside_steps(depth, 500.0, max_step=10.0, side="near").any(axis=0)).ravel().tolist() == [4]
    assert not beside_steps(depth, 500.0, max_step=150.0).any()
    # without a tolerance to judge them by, both are dropped
    edges = edge_points(depth, 500.0)
    assert np.argwhere(edges.beside_step.any(axis=0)).ravel().tolist() == [4, 5]
    assert not edge_points(depth, 500.0, max_step=np.inf).dropped.any()


def test_a_clean_pixel_beside_a_step_is_kept_a_mixed_one_is_not():
    # two planes 100 footprints apart (1 mm footprint: f = 500 px at 500 mm), uniform modulation 100
    focal_px, modulation = 500.0, np.full((5, 12), 100.0)
    depth = np.full((5, 12), 500.0)
    depth[:, 6:] = 600.0
    edges = edge_points(depth, focal_px, modulation, max_edge_error=1.0)
    assert not edges.dropped.any()  # the last pixel of each side: on its side's line, no dip: kept
    # a sliver w of the far side in the near side's last pixel adds a phasor of another phase: its modulation is
    # |(1 - w) + w exp(i delta)| and its depth leaves the line. w = 0.2 at delta = pi: B = 60 % (no dip below 0.6
    # of 100), depth moved by 3 mm (3 footprints: not flying) -> off its side's line by more than 0.5 mm: dropped
    mixed = depth.copy()
    mixed[:, 5] = 503.0
    b = modulation.copy()
    b[:, 5] = 100.0 * abs(0.8 + 0.2 * np.exp(1j * np.pi))
    edges = edge_points(mixed, focal_px, b, max_edge_error=1.0)
    assert np.argwhere(edges.beside_step.any(axis=0)).ravel().tolist() == [5]
    assert np.argwhere(edges.dropped.any(axis=0)).ravel().tolist() == [5]
    # on its side's line but with its modulation dipped (w = 0.3 at delta = pi: 40 %): dropped beside the step, the
    # far side's clean pixel kept
    b[:, 5] = 100.0 * abs(0.7 + 0.3 * np.exp(1j * np.pi))
    edges = edge_points(depth, focal_px, b, max_edge_error=1.0)
    assert np.argwhere(edges.beside_step.any(axis=0)).ravel().tolist() == [5]
    # within half the tolerance of its side (0.4 mm off): kept
    mixed[:, 5] = 500.4
    assert not edge_points(mixed, focal_px, modulation, max_edge_error=1.0).dropped.any()
    with pytest.raises(ValueError, match="side"):
        beside_steps(depth, 500.0, max_step=10.0, side="left")


def test_a_thin_object_is_not_flying_a_one_pixel_sliver_is():
    depth = np.full((7, 12), 800.0)
    depth[:, 4:6] = 700.0  # a bar two pixels wide, 100 footprints before the plane
    depth[:, 9] = 700.0  # a sliver one pixel wide
    edges = edge_points(depth, 700.0)
    assert not edges.flying[:, 4:6].any()  # each bar pixel has a neighbour on the bar: not flying
    assert edges.beside_step[:, 3:7].all()  # beside the step: the bar's two columns and the plane's beside them
    assert edges.flying[:, 9].all()  # apart from both neighbours along the row


def test_a_modulation_dip_is_dropped_at_a_depth_edge_only():
    focal_px = 500.0
    rows, cols = np.mgrid[0:8, 0:12].astype(float)
    depth = 500.0 * (1 + 3.0 / focal_px) ** cols  # a face 72 degrees from facing the camera: 3 footprints a column
    modulation = np.full(depth.shape, 100.0)
    modulation[:, 6:] = 40.0  # an albedo edge: the dark side dips below 0.6 of its bright neighbours
    edges = edge_points(depth, focal_px, modulation, max_edge_error=1.0)
    assert not edges.dropped.any()  # a texture edge on a smooth (tilted) surface: every point kept
    # a depth step at the same columns: the dark side is 50 mm farther, its first column mixes both surfaces
    stepped = np.where(cols >= 6, depth + 50.0, depth)
    stepped[:, 6] += 2.0  # the mixed column: 2 mm off the far surface's continuation
    edges = edge_points(stepped, focal_px, modulation, max_edge_error=1.0)
    assert edges.modulation_dip[:, 6].all() and not edges.modulation_dip[:, 8:].any()
    # a dipped pixel that its side continues to within half of max_edge_error is kept
    stepped[:, 6] -= 2.0
    edges = edge_points(stepped, focal_px, modulation, max_edge_error=1.0)
    assert not edges.modulation_dip[:, 6].any()
    assert edge_points(stepped, focal_px, modulation).modulation_dip[:, 6].all()  # no tolerance: no rescue


def test_a_partly_shadowed_point_is_dropped_by_its_predicted_depth_error():
    depth = np.full((6, 8), 500.0)
    lit = np.ones(depth.shape, dtype=bool)
    lit[:, 5:] = False  # the projector's shadow
    depth[~lit] = np.nan
    modulation = np.where(lit, 100.0, 1.0)
    modulation[0, 4], modulation[1, 4], modulation[2, 4] = 30.0, 80.0, 70.0  # lit fractions 0.3, 0.8, 0.7
    per_px = np.full(depth.shape, 5.0)  # 5 mm of depth per camera pixel of fringe (a narrow baseline)
    edges = edge_points(depth, 500.0, modulation, lit=lit, depth_per_px=per_px, max_edge_error=0.6)
    # (1 - r) / 2 * 5 mm: 0.3 -> centre in the shadow; 0.8 -> 0.5 mm kept; 0.7 -> 0.75 mm dropped
    assert edges.shadow_border[:3, 4].tolist() == [True, False, True]
    assert not edges.shadow_border[3:, 4].any()  # fully lit border pixels
    assert not edge_points(depth, 500.0, modulation, lit=lit, depth_per_px=per_px / 10,
                           max_edge_error=0.6).shadow_border[1:3, 4].any()  # a wide baseline: 0.05-0.075 mm
    # fringes along y: the lit parts' offsets (across the vertical border, along x) leave the phase as it is
    assert edge_points(depth, 500.0, modulation, lit=lit, depth_per_px=per_px, max_edge_error=0.6,
                       axis="y").shadow_border[:3, 4].tolist() == [True, False, False]  # 0.3: centre in the shadow


def test_depth_per_pixel_is_the_depth_change_of_one_camera_pixel_of_fringe():
    x_p = np.tile(np.arange(10.0) * 2.0, (3, 1))  # 2 projector pixels per camera pixel
    per_px = depth_per_pixel(x_p, lambda x, pixels: 1000.0 - 3.0 * x, "x")  # 3 mm per projector pixel
    np.testing.assert_allclose(per_px, 6.0)
    where = np.zeros(x_p.shape, dtype=bool)
    where[1, 2:5] = True  # only there: NaN elsewhere, and depth_at sees those pixels' flat indices
    asked = []
    per_px = depth_per_pixel(x_p, lambda x, pixels: asked.append(pixels.tolist()) or 1000.0 - 3.0 * x, "x",
                             where=where)
    np.testing.assert_allclose(per_px[where], 6.0)
    assert np.isnan(per_px[~where]).all() and asked == [[12, 13, 14]] * 2
    assert np.isnan(depth_per_pixel(x_p, lambda x, pixels: x, "x", where=np.zeros(x_p.shape, bool))).all()


def test_isolated_points_and_bad_parameters():
    depth = np.full((6, 6), 500.0)
    depth[4, :] = np.nan
    depth[5, :5] = np.nan  # (5, 5) keeps no neighbour with a point
    edges = edge_points(depth, 500.0, np.full((6, 6), 100.0))
    assert np.argwhere(edges.isolated).tolist() == [[5, 5]]
    assert edges.counts(np.isfinite(depth)) == {"flying": 0, "beside_step": 0, "modulation_dip": 0,
                                                "shadow_border": 0, "isolated": 1, "total": 1}
    assert not edge_points(depth, 500.0, None, min_neighbours=0).dropped.any()
    with pytest.raises(ValueError, match="min_modulation_ratio"):
        edge_points(depth, 500.0, None, min_modulation_ratio=1.5)
    with pytest.raises(ValueError, match="max_edge_error"):
        edge_points(depth, 500.0, None, max_edge_error=0.0)
    with pytest.raises(ValueError, match="axis"):
        edge_points(depth, 500.0, None, axis="z")


@pytest.mark.parametrize("outside", [OutsideRig(),
                                     OutsideRig(camera_focal_px=700, projector_focal_px=1800, baseline_mm=300,
                                                toe_in_deg=22, distance_mm=1000)])
def test_edge_filter_leaves_no_point_off_the_surface_on_a_12_step_capture_with_mixed_pixels(outside):
    # heterodyne 96/95 at 12 steps, 1.57 DN noise, no confidence threshold: what lies off the surface are the mixed
    # pixels at depth edges, the partly shadowed ones and the classical wrong orders; measured: 2.2 / 2.6 % of the
    # points more than 1 mm off without the filter, 0.006 / 0.006 % with it, 97.25 / 97.05 % of the pure pixels kept
    # (0.006 / 0.000 % and 97.17 / 96.96 % when every modulation dip was dropped)
    capture = render(outside, default_scene(outside, seed=1), [96.0, 95.0], steps=12, noise_dn=1.5693, seed=1)
    maps = [phase.wrapped_phase(capture.frames[f]) for f in (96.0, 95.0)]
    valid = maps[0].modulation >= 5.1
    result = tpu.unwrap_heterodyne([m.phase for m in maps], [96.0, 95.0], valid=valid)
    x_p = np.where(result.valid, result.absolute_phase * PROJECTOR_SIZE[0] / (2 * np.pi * 96.0), np.nan)
    points = Triangulator(capture.rig, axis="x", distortion=False).camera_points(x_p, dtype=np.float64)
    has_point = np.isfinite(points[..., 2])
    off = has_point & (capture.scene.distance_mm(np.nan_to_num(points)) > 1.0)
    assert off.sum() > 0.005 * has_point.sum()  # the mixed pixels are there
    triangulator = Triangulator(capture.rig, axis="x", distortion=False)
    per_px = depth_per_pixel(x_p, lambda x, pixels: triangulator.camera_points(x, dtype=np.float64,
                                                                               pixels=pixels)[:, 2], "x",
                             depth=points[..., 2])
    keep = has_point & ~edge_points(points[..., 2], outside.camera_focal_px, maps[0].modulation, lit=result.valid,
                                    depth_per_px=per_px, max_edge_error=1.0).dropped
    assert (keep & off).sum() <= 0.0005 * keep.sum()
    assert (keep & capture.pure).sum() >= 0.96 * capture.pure.sum()
