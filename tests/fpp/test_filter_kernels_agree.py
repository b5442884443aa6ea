"""The cloud filters' faster kernels agree bit for bit with their whole-image versions: the triangulation of chosen
pixels (:meth:`dptpu.fpp.triangulate.Triangulator.camera_points` with ``pixels``), the shadow test's second
triangulation asked only where :func:`dptpu.fpp.depth_edges.edge_points` needs it, the continuation of a side at
chosen pixels, the order islands of a float32 phase. On outside rigs (projector and camera distortion drawn by a
seed, several focal lengths, baselines and angles) rendered with mixed pixels at depth edges, projector shadows and
the paper's camera noise."""
from functools import cache

import cv2
import numpy as np
import pytest

from dptpu.fpp import depth_steps, phase, tpu
from dptpu.fpp import flying_points as flying_points_module
from dptpu.fpp import order_islands as order_islands_module
from dptpu.fpp import shadow_border as shadow_border_module
from dptpu.fpp.depth_edges import edge_points
from dptpu.fpp.depth_steps import continues_a_side
from dptpu.fpp.flying_points import flying_points
from dptpu.fpp.order_islands import _order_regions, _ValidModulation, order_islands
from dptpu.fpp.shadow_border import depth_per_pixel
from dptpu.fpp.triangulate import Triangulator, camera_depth, projector_coordinate
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import SIGMA_2, issue16_rig, random_outside_rig, render_phases, spheres_and_plane
from dptpu.sim.render import raycast_frames
from dptpu.sim.rig import load_twin_rig
from dptpu.sim.scenes.random_scene import random_scene

FREQUENCY = 16.0


RIGS = {"random-3": (lambda: random_outside_rig(3, size=(160, 120)), 3),
        "random-8": (lambda: random_outside_rig(8, size=(160, 120)), 8),
        "issue16": (lambda: issue16_rig(size=(160, 120)), 1)}


@cache
def rendered(name):
    """``(rig, projector coordinate (H, W), modulation, lit)`` of a noisy 12-step capture of spheres before a plane
    on rig ``name`` (the true order on the rendered wrapped phase: mixed pixels at the depth edges, NaN in the
    projector's shadow)."""
    make_rig, seed = RIGS[name]
    rig = make_rig()
    capture = render_phases(rig, spheres_and_plane(rig, seed), [FREQUENCY], steps=12, noise_dn=SIGMA_2, seed=seed)
    phase = capture.phases[FREQUENCY] + 2 * np.pi * capture.order(FREQUENCY)
    lit = capture.valid & (capture.modulation[FREQUENCY] > 3.0)
    x_p = projector_coordinate(np.where(lit, phase, np.nan), FREQUENCY, capture.extent)
    return rig, x_p, capture.modulation[FREQUENCY], lit


@pytest.mark.parametrize("name", RIGS)
def test_edge_points_with_the_second_triangulation_where_needed_marks_what_the_whole_image_marks(name):
    rig, x_p, modulation, lit = rendered(name)
    triangulator = Triangulator(rig, axis="x")
    assert (triangulator._projector_distortion is not None) == name.startswith("random")  # Newton's passes too
    points = triangulator.camera_points(x_p, dtype=np.float32)
    depth = np.ascontiguousarray(points[..., 2])
    focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])

    def whole_image(x):  # the second triangulation of every pixel (the kernels before this change)
        return triangulator.camera_points(x, dtype=np.float32)[..., 2]

    def depth_at(x, pixels):
        return triangulator.camera_points(x, dtype=np.float32, pixels=pixels)[:, 2]

    steps = np.abs(np.diff(x_p, axis=1))
    g = float(np.median(steps[np.isfinite(steps)]))
    everywhere = np.abs(whole_image(x_p + g).astype(np.float64) - depth)
    asked = []

    def per_px(where):
        asked.append(int(np.count_nonzero(where)))
        return depth_per_pixel(x_p, depth_at, "x", depth=depth, where=where)

    reference = edge_points(depth, focal_px, modulation, lit=lit, depth_per_px=everywhere, max_edge_error=1.0)
    masked = edge_points(depth, focal_px, modulation, lit=lit, depth_per_px=per_px, max_edge_error=1.0)
    for reason in ("flying", "beside_step", "modulation_dip", "isolated", "shadow_border"):
        assert np.array_equal(getattr(masked, reason), getattr(reference, reason)), reason
    assert reference.shadow_border.any() and reference.modulation_dip.any()  # the tests had something to mark
    assert 0 < asked[0] < 0.2 * np.count_nonzero(np.isfinite(depth))  # a few pixels triangulated again
    where = np.isfinite(depth) & ~lit[:, ::-1]  # any pixels: the same values bit for bit
    assert np.array_equal(per_px(where)[where], everywhere[where], equal_nan=True)


@pytest.mark.parametrize("name", RIGS)
def test_points_of_chosen_pixels_are_the_whole_image_points_bit_for_bit(name):
    rig, x_p, _, _ = rendered(name)
    triangulator = Triangulator(rig, axis="x")
    whole32 = triangulator.camera_points(x_p, scale=1e-3, dtype=np.float32)
    whole = triangulator.points(x_p)
    rng = np.random.default_rng(len(name))
    for count in (1, 2, 7, 500):
        pixels = np.sort(rng.choice(x_p.size, count, replace=False))
        chosen = x_p.ravel()[pixels]
        assert np.array_equal(triangulator.camera_points(chosen, scale=1e-3, dtype=np.float32, pixels=pixels),
                              whole32.reshape(-1, 3)[pixels], equal_nan=True)
        assert np.array_equal(triangulator.points(chosen, pixels=pixels), whole.reshape(-1, 3)[pixels],
                              equal_nan=True)
        assert np.array_equal(camera_depth(triangulator.points(chosen, pixels=pixels), rig.camera),
                              camera_depth(whole, rig.camera).ravel()[pixels], equal_nan=True)
    with pytest.raises(ValueError, match="pixels"):
        triangulator.camera_points(x_p.ravel()[:3], pixels=np.array([0, 1, x_p.size]))
    with pytest.raises(ValueError, match="out"):
        triangulator.camera_points(x_p.ravel()[:1], pixels=np.array([0]), out=whole32)


def test_a_side_continued_at_chosen_pixels_is_the_whole_image_answer(monkeypatch):
    rng = np.random.default_rng(5)
    rows, cols = np.mgrid[0:40, 0:50]
    depth = (600.0 + 0.3 * cols + 0.1 * rows + rng.normal(0, 0.2, rows.shape)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.1] = np.nan
    pure = np.isfinite(depth) & (rng.random(depth.shape) < 0.8)
    where = rng.random(depth.shape) < 0.3
    where[0, :] = where[:, -1] = True  # the image's border: neighbours outside it count as not pure
    whole = continues_a_side(depth, pure, 0.25)
    assert 0 < np.count_nonzero(whole & where) < np.count_nonzero(where)
    for share in (1.0, 0.0):  # gathered at the pixels asked; the whole image's answer there
        monkeypatch.setattr(depth_steps, "_CONTINUE_GATHER_SHARE", share)
        assert np.array_equal(continues_a_side(depth, pure, 0.25, where=where), whole & where)


@pytest.mark.parametrize("name", RIGS)
def test_order_islands_of_a_float32_phase_are_those_of_its_float64_copy(name):
    # the phase differences are taken in float64 from either dtype (a float32 difference could round across pi)
    rig, x_p, modulation, lit = rendered(name)
    phase = x_p * (2 * np.pi * FREQUENCY / rig.projector.size[0])
    rng = np.random.default_rng(len(name))
    for _ in range(8):  # patches whole orders off
        row, col = rng.integers(5, 100), rng.integers(5, 140)
        phase[row:row + rng.integers(2, 12), col:col + rng.integers(2, 12)] += 2 * np.pi * rng.choice([-1, 1, 2])
    phase32 = phase.astype(np.float32)
    single = order_islands(phase32, modulation.astype(np.float32), lit)
    double = order_islands(phase32.astype(np.float64), modulation, lit)
    assert single.island_regions >= 4  # the patches were found
    assert np.array_equal(single.islands, double.islands) and np.array_equal(single.step, double.step)
    assert (single.regions, single.island_regions) == (double.regions, double.island_regions)


#: The outside rigs' captures and the graph's own scene (random-1 from the sim rig).
PHASE_SCENES = [*RIGS, "sim random-1"]


def phase_scene(name):
    """``(absolute phase (H, W) float32 with an island one order off, modulation float32, lit)`` of a scene of
    :data:`PHASE_SCENES`."""
    if name in RIGS:
        rig, x_p, modulation, lit = rendered(name)
        absolute = (x_p * (2 * np.pi * FREQUENCY / rig.projector.size[0])).astype(np.float32)
    else:
        _, modulation, unwrapped = sim_unwrapped()
        absolute, lit = unwrapped.absolute_phase.copy(), unwrapped.valid
    absolute[40:50, 60:75] += np.float32(2 * np.pi)  # an island: broken pairs inside the lit area too
    return absolute, modulation.astype(np.float32), lit


@pytest.mark.parametrize("name", PHASE_SCENES)
def test_the_broken_pairs_of_order_regions_are_the_plain_definitions(name):
    # the kernel lists the broken neighbour pairs from flat indices; the definition, with numpy's 2-D nonzero
    phase32, _, lit = phase_scene(name)
    valid = lit & np.isfinite(phase32)
    _, a, b, difference = _order_regions(phase32, valid)
    right = np.subtract(phase32[:, 1:], phase32[:, :-1], dtype=np.float64)
    down = np.subtract(phase32[1:, :], phase32[:-1, :], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        rows_r, cols_r = np.nonzero(valid[:, 1:] & valid[:, :-1] & ~(np.abs(right) < np.pi))
        rows_d, cols_d = np.nonzero(valid[1:, :] & valid[:-1, :] & ~(np.abs(down) < np.pi))
    width = phase32.shape[1]
    assert rows_r.size > 20 and rows_d.size > 20
    assert np.array_equal(a, np.concatenate([rows_r * width + cols_r, rows_d * width + cols_d]))
    assert np.array_equal(b, np.concatenate([rows_r * width + cols_r + 1, (rows_d + 1) * width + cols_d]))
    assert np.array_equal(difference, np.concatenate([right[rows_r, cols_r], down[rows_d, cols_d]]))
    assert a.dtype == b.dtype == np.int64


def test_order_links_of_float32_differences_are_the_float64_ones():
    # order_islands links two neighbours where |Phi_b - Phi_a| < pi in float64; the kernel decides it in float32
    # and takes the differences within float32 rounding of pi again in float64. Pairs a few float32 steps either
    # side of a difference of pi (where the two roundings part), over the phases' range, with NaN, inf and huge values
    rng = np.random.default_rng(20)
    before = rng.uniform(0.0, 2 * np.pi * 64, 4000).astype(np.float32)
    before[:50] = rng.uniform(-1e-3, 1e-3, 50)  # near zero: the float32 difference exact, the exponents apart
    after = (before.astype(np.float64) + np.pi * rng.choice([-1.0, 1.0], before.size)).astype(np.float32)
    offset = rng.integers(-4, 5, before.size)  # float32 steps off the nearest difference of pi
    for walked in range(4):
        move = np.abs(offset) > walked
        after[move] = np.nextafter(after[move], np.float32(np.inf) * np.sign(offset[move]).astype(np.float32))
    far = rng.uniform(-3 * np.pi, 3 * np.pi, 1000)
    after = np.concatenate([after, (before[:1000] + far).astype(np.float32), [np.nan, 1.0, np.inf, 3e38, 1.0]])
    before = np.concatenate([before, before[:1000], [1.0, np.nan, np.inf, -3e38, np.inf]]).astype(np.float32)
    after2, before2 = after.reshape(-1, 5), before.reshape(-1, 5)  # 2-D, as the kernel's images
    with np.errstate(invalid="ignore", over="ignore"):
        want = np.abs(np.subtract(after2, before2, dtype=np.float64)) < np.pi
        near = np.abs(np.abs(np.subtract(after2, before2, dtype=np.float64)) - np.pi) < 1e-5
    assert near.sum() > 1000 and 0 < want[near].sum() < near.sum()  # both sides of pi, closely
    assert np.array_equal(order_islands_module._linked(after2, before2), want)
    assert np.array_equal(order_islands_module._linked(after2.astype(np.float64), before2.astype(np.float64)), want)


@pytest.mark.parametrize("name", PHASE_SCENES)
def test_the_shadow_borders_normal_at_chosen_pixels_is_opencvs_sobel_there(name):
    # the predicted error's |cos| from the 3x3 neighbourhoods of the pixels asked; OpenCV's Sobel over the whole
    # image, with the border replicated (the kernel before): the same float32 values, on the rig's shadows and on a
    # random mask, at pixels of the image's border too
    _, _, lit = phase_scene(name)
    rng = np.random.default_rng(len(name))
    for unlit in (~lit, rng.random(lit.shape) < 0.3):
        height, width = unlit.shape
        border = np.concatenate([np.arange(width), (height - 1) * width + np.arange(width),
                                 np.arange(height) * width, np.arange(height) * width + width - 1])
        pixels = np.unique(np.concatenate([border, rng.choice(unlit.size, 500, replace=False)]))
        for axis in ("x", "y"):
            whole = shadow_border_module._across_fringes(unlit, axis)
            assert np.array_equal(shadow_border_module._across_fringes(unlit, axis, pixels), whole.ravel()[pixels])
            assert 0 < np.count_nonzero(whole.ravel()[pixels]) < pixels.size


@pytest.mark.parametrize("name", PHASE_SCENES)
def test_the_brightest_modulation_within_two_pixels_of_a_pair_is_opencvs_dilation_there(name):
    # order_islands' smooth-pair test gathers the 5 x 5 windows of the broken pairs' pixels; the kernel before it,
    # OpenCV's dilation of the whole image: the same float32 values, at the image's border too
    _, modulation, lit = phase_scene(name)
    modulation = modulation.copy()
    modulation[::7, ::5] = np.nan  # NaN modulation counts as 0, as the whole map made it
    values = np.nan_to_num(modulation)
    values[~lit] = 0.0
    height, width = values.shape
    rng = np.random.default_rng(len(name))
    border = np.concatenate([np.arange(width), (height - 1) * width + np.arange(width), np.arange(height) * width,
                             np.arange(height) * width + width - 1, [width + 1, 2 * width - 2]])
    pixels = np.concatenate([border, rng.choice(values.size, 800)])
    whole = cv2.dilate(values, np.ones((5, 5), np.uint8)).ravel()
    gathered = _ValidModulation(modulation, lit)
    assert np.array_equal(gathered.brightest_near(pixels), whole[pixels])
    assert np.array_equal(gathered.at(pixels), values.ravel()[pixels])
    assert gathered.brightest_near(pixels[:0]).shape == (0,)


@pytest.mark.parametrize("name", RIGS)
def test_flying_points_are_the_plain_definitions_marks(name):
    # the kernel takes |a - b| from cv2.absdiff into reused buffers; the definition, written plainly in numpy
    rig, x_p, _, _ = rendered(name)
    depth = Triangulator(rig, axis="x").camera_points(x_p, dtype=np.float32)[..., 2]
    focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])
    padded = np.pad(depth, 1, constant_values=np.nan)
    height, width = depth.shape
    footprint = np.abs(depth) * np.float32(1.0 / focal_px)
    plain = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for dr, dc, factor in ((0, 1, 1.0), (1, 0, 1.0), (1, 1, np.sqrt(2.0)), (1, -1, np.sqrt(2.0))):
            before = padded[1 - dr:1 - dr + height, 1 - dc:1 - dc + width]
            after = padded[1 + dr:1 + dr + height, 1 + dc:1 + dc + width]
            limit = np.float32(4.0 * factor) * footprint
            plain |= (np.abs(depth - before) > limit) & (np.abs(after - depth) > limit)
    assert plain.sum() > 20 and np.array_equal(flying_points(depth, focal_px, max_slope=4.0), plain)


ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


@cache
def sim_unwrapped():
    """``(rig, modulation (H, W) float32, Unwrapped)`` of random-1 as the sim node renders it (the raycast twin, the
    shipped rig at 160x120, 2 x 12 steps) through the phase and Eq. (5): the graph's own scene."""
    rig = load_twin_rig(ROOT / "launch" / "params" / "shipped_rig.yaml", size=(160, 120))
    specs = [SequenceSpec(64.0, 12, axis="x", shift_sign=-1), SequenceSpec(1.0, 12, axis="x", shift_sign=-1)]
    stacks, _ = raycast_frames(rig, random_scene(rig, 1), specs, seed=0)
    maps = [phase.maps_from_sums(phase.sequence_sums(stack)) for stack in stacks]
    valid = (maps[0].modulation >= 10.0) & (maps[1].modulation >= 10.0)
    return rig, maps[0].modulation, tpu.unwrap_mf_float32(maps[0].phase, maps[1].phase, 64.0, 1.0, valid=valid)


@cache
def sim_capture():
    """``(depth (H, W) float32 m, focal px, modulation, lit)`` of :func:`sim_unwrapped`, triangulated."""
    rig, modulation, unwrapped = sim_unwrapped()
    x_p = projector_coordinate(unwrapped.absolute_phase, 64.0, rig.projector.size[0])
    depth = Triangulator(rig, axis="x").camera_points(x_p, scale=rig.scale_to_m, dtype=np.float32)[..., 2]
    return np.ascontiguousarray(depth), 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1]), modulation, \
        unwrapped.valid


def steep_planes(rig, seed):
    """Depth (H, W) float32 of two surfaces whose depth changes by 6 and by 12 pixel footprints ``z / f`` a column
    (80.5 and 85.2 degrees from facing the camera; left and right half, a depth step between), with depth noise of
    0.05 footprints, and a modulation with a few dips: the ramp test and the continuation asked at most pixels."""
    width, height = rig.camera.size
    focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])
    cols = np.broadcast_to(np.arange(width, dtype=np.float64), (height, width))
    slope = np.where(cols < width // 2, 6.0, 12.0)
    depth = np.where(cols < width // 2, 600.0, 700.0) * np.exp(slope * (cols - width // 2) / focal_px)  # dz = s z / f
    rng = np.random.default_rng(seed)
    depth *= 1.0 + 0.05 / focal_px * rng.normal(size=depth.shape)
    modulation = 60.0 + rng.normal(0.0, 1.0, depth.shape)
    modulation[rng.random(depth.shape) < 0.02] *= 0.4
    return depth.astype(np.float32), modulation.astype(np.float32)


def _scenes():
    for name in RIGS:
        rig, x_p, modulation, lit = rendered(name)
        depth = np.ascontiguousarray(Triangulator(rig, axis="x").camera_points(x_p, dtype=np.float32)[..., 2])
        focal_px = 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1])
        yield name, depth, focal_px, modulation, lit, 1.0
        planes, plane_modulation = steep_planes(rig, len(name))
        yield f"{name} steep planes", planes, focal_px, plane_modulation, np.isfinite(planes), 1.0
    depth, focal_px, modulation, lit = sim_capture()
    yield "sim random-1", depth, focal_px, modulation, lit, 1e-3
    # the pipeline bench's analytic ramp across the projector (``--floor --source ramp``), a steep plane
    rig = load_twin_rig(ROOT / "launch" / "params" / "shipped_rig.yaml", size=(160, 120))
    rows, cols = np.mgrid[0:120, 0:160]
    x_p = 40.0 + (rig.projector.size[0] - 80.0) * cols / 160 + 0.05 * rows
    depth = Triangulator(rig, axis="x").camera_points(x_p, scale=rig.scale_to_m, dtype=np.float32)[..., 2]
    yield "steep analytic ramp", np.ascontiguousarray(depth), 0.5 * float(rig.camera.K[0, 0] + rig.camera.K[1, 1]), \
        np.full(depth.shape, 100.0, dtype=np.float32), np.isfinite(depth), 1e-3


def test_the_whole_image_ramp_and_continuation_mark_what_the_gathered_ones_mark(monkeypatch):
    """The straight-ramp test of :func:`flying_points` and the continuation of :func:`edge_points` on the whole
    image (a steep plane, where most pixels ask) or gathered (the kernels of 12dcb77 and b74d1e2): the same marks bit
    for bit, on the three outside rigs' spheres and on steep planes seen by them, on the sim's random-1 and on the
    pipeline bench's analytic ramp."""
    ramps = 0
    for name, depth, focal_px, modulation, lit, max_edge_error in _scenes():
        marks = {}
        for share in (1.0, 0.0, None):  # all gathered, all on the whole image, the default switch
            if share is not None:
                monkeypatch.setattr(flying_points_module, "_RAMP_GATHER_SHARE", share)
                monkeypatch.setattr(depth_steps, "_CONTINUE_GATHER_SHARE", share)
            else:
                monkeypatch.undo()
            marks[share] = (flying_points(depth, focal_px), flying_points(depth, focal_px, max_ramp_bend=0.5),
                            edge_points(depth, focal_px, modulation, lit=lit, max_edge_error=max_edge_error))
        for share in (0.0, None):
            for got, want in zip(marks[share][:2], marks[1.0][:2]):
                assert np.array_equal(got, want), (name, share)
            for reason in ("flying", "beside_step", "modulation_dip", "isolated", "shadow_border"):
                assert np.array_equal(getattr(marks[share][2], reason), getattr(marks[1.0][2], reason)), \
                    (name, share, reason)
        kept_on_ramps = np.count_nonzero(flying_points(depth, focal_px, max_ramp_bend=0.0) & ~marks[None][0])
        ramps += kept_on_ramps
        if name.startswith("steep") or name.endswith("steep planes"):
            assert kept_on_ramps > 0.1 * depth.size, name  # the 6-footprint half: the ramp test on the whole image
            # the 12-footprint half: steps everywhere, the continuation asked on the whole image
            assert np.count_nonzero(marks[None][2].beside_step) > 0.1 * depth.size, name
    assert ramps > 0
