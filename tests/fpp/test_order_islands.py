"""fpp.order_islands: patches whole orders off found from their border; real depth steps and occlusions left alone."""
import numpy as np
import pytest

from dptpu.fpp.order_islands import order_islands

TWO_PI = 2.0 * np.pi


def _ramp(height=180, width=240, gradient=(0.55, 0.2), offset=40.0):
    """Absolute phase of a tilted plane, radians: ``offset + gx * col + gy * row`` (under pi per pixel)."""
    rows, cols = np.mgrid[0:height, 0:width]
    return offset + gradient[0] * cols + gradient[1] * rows


def _disc(shape, centre, radius):
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    return (rows - centre[0]) ** 2 + (cols - centre[1]) ** 2 <= radius ** 2


@pytest.mark.parametrize("orders", [1, -1, 2])
def test_a_patch_whole_orders_off_is_found_exactly(orders):
    phi = _ramp()
    patch = _disc(phi.shape, (40, 60), 9)
    modulation = np.full(phi.shape, 60.0)
    found = order_islands(phi + TWO_PI * orders * patch, modulation, np.ones(phi.shape, bool))
    np.testing.assert_array_equal(found.islands, patch)
    np.testing.assert_array_equal(found.step, np.where(patch, orders, 0))
    assert found.island_regions == 1 and found.regions == 2


def test_a_region_larger_than_the_island_share_is_an_object_of_its_own():
    """A face before the plane, exactly one period nearer, no modulation dip at its edge: phase alone cannot tell
    it from a patch one order off; at 3.5 % of the image it is kept by default, an island when the share allows it."""
    phi = _ramp()
    face = _disc(phi.shape, (90, 120), 22)  # 1521 pixels, 3.5 % of 43,200
    phi = phi + TWO_PI * face
    modulation = np.full(phi.shape, 60.0)
    assert not order_islands(phi, modulation, np.ones(phi.shape, bool)).islands.any()
    np.testing.assert_array_equal(order_islands(phi, modulation, np.ones(phi.shape, bool),
                                                max_island_share=0.05).islands, face)


def test_a_lone_wrong_pixel_is_an_island():
    phi = _ramp()
    wrong = np.zeros(phi.shape, bool)
    wrong[30, 70] = True
    found = order_islands(phi + TWO_PI * wrong, np.full(phi.shape, 60.0), np.ones(phi.shape, bool))
    np.testing.assert_array_equal(found.islands, wrong)


def test_a_noisy_surface_without_wrong_orders_has_no_island():
    rng = np.random.default_rng(3)
    phi = _ramp(gradient=(0.7, 0.3)) + rng.normal(0.0, 0.25, (180, 240))  # noise of a 3-step capture at low B
    modulation = 60.0 * (1.0 + 0.05 * rng.standard_normal(phi.shape))
    found = order_islands(phi, modulation, np.ones(phi.shape, bool))
    assert not found.islands.any()


@pytest.mark.parametrize("depth_periods", [1.0, 1.3, 2.0, 3.6])
def test_an_occluding_object_with_mixed_pixels_at_its_edge_is_kept(depth_periods):
    """A disc in front of the plane, its phase offset any number of periods (whole ones too), its rim a ring of mixed
    pixels whose modulation dips (two phasors add to less than either): not an island, whatever the offset."""
    phi = _ramp()
    disc = _disc(phi.shape, (90, 110), 14)
    rim = disc & ~_disc(phi.shape, (90, 110), 13)
    rows, cols = np.mgrid[0:180, 0:240]
    front = 40.0 + TWO_PI * depth_periods + 0.35 * cols - 0.1 * rows  # another plane, another tilt
    phi = np.where(disc, front, phi)
    modulation = np.where(rim, 22.0, 60.0)
    found = order_islands(phi, modulation, np.ones(phi.shape, bool), max_island_share=1.0)  # the rule, not the size
    assert not found.islands.any()


def test_a_step_whose_phase_jump_varies_along_the_edge_is_kept():
    """A box face nearer by an amount that changes along its edge (a tilted face), no modulation dip at all."""
    phi = _ramp()
    rows, cols = np.mgrid[0:180, 0:240]
    face = (cols >= 200) & (rows >= 60) & (rows < 80)
    phi = np.where(face, phi + TWO_PI * (0.6 + 0.06 * (rows - 60)), phi)
    found = order_islands(phi, np.full(phi.shape, 60.0), np.ones(phi.shape, bool), max_island_share=1.0)
    assert not found.islands.any()


def test_invalid_pixels_split_nothing_and_are_never_islands():
    phi = _ramp()
    patch = _disc(phi.shape, (40, 60), 9)
    valid = np.ones(phi.shape, bool)
    valid[:, 30] = False  # a column of dropped pixels between two parts of the plane
    valid[40, 60] = False
    found = order_islands(phi + TWO_PI * patch, np.full(phi.shape, 60.0), valid)
    np.testing.assert_array_equal(found.islands, patch & valid)


def test_shapes_and_parameters_are_checked():
    phi = _ramp()
    with pytest.raises(ValueError, match="one shape"):
        order_islands(phi, np.ones((3, 3)), np.ones(phi.shape, bool))
    with pytest.raises(ValueError, match="min_share"):
        order_islands(phi, np.ones(phi.shape), np.ones(phi.shape, bool), min_share=0.0)
    with pytest.raises(ValueError, match="max_island_share"):
        order_islands(phi, np.ones(phi.shape), np.ones(phi.shape, bool), max_island_share=0.0)
