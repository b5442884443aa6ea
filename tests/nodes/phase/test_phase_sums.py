"""The phase node's per-frame path: the assembler's slots fed to fpp's IncrementalScanPhase frame by frame (as
nodes/phase/node.py does) give the maps of the assembled scan's stacked frames; and the cloud's in-place
triangulation (Triangulator.camera_points(out=...)) the points of the plain call. The sums themselves:
tests/fpp/test_scan_phase.py."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.fpp.scan_phase import IncrementalScanPhase, scan_phase_maps
from dptpu.nodes.phase.sequence_assembler import AssembledScan, FrameInfo, ScanLayout, SequenceAssembler
from tests.fpp.test_scan_phase import SHAPE, fringe_images


def assemble(entries, layout=None, *, shift_sign=-1):
    """Feed one scan's frames (entries: list of (frequency, images)) through an assembler, accumulating as the
    phase node does; returns the AssembledScan and the IncrementalScanPhase."""
    assembler = SequenceAssembler(timeout_s=1.0, shift_sign=shift_sign)
    assembler.set_layout(layout)
    count = sum(len(images) for _, images in entries)
    sums, events, index = IncrementalScanPhase(), [], 0
    for frequency, images in entries:
        for step, image in enumerate(images):
            frame = FrameInfo(sequence_id=7, pattern_index=index, pattern_count=count, frequency=frequency,
                              steps=len(images), step=step, image=image)
            events += assembler.add(frame, 0.0)
            slot = assembler.slot(7, index)
            if slot is not None:
                sums.add(index, image, slot)
            else:  # the last frame completed the scan: placed by the scan's layout
                sums.add(index, image, events[-1].slot(index))
            index += 1
    (scan,) = events
    assert isinstance(scan, AssembledScan)
    return scan, sums


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_accumulated_sums_give_the_maps_of_the_stacked_frames(dtype):
    high, phi_high = fringe_images(16.0, 12, dtype=dtype, seed=1)
    low, _ = fringe_images(1.0, 4, dtype=dtype, seed=2)
    scan, sums = assemble([(16.0, high), (1.0, low)])
    level = 250.0 if dtype == np.uint8 else None
    accumulated = sums.maps(scan.slots(), min_modulation=20.0, saturation_level=level)
    stacked = scan_phase_maps(scan.stacks, scan.layout.phase_offsets, shift_sign=scan.layout.shift_sign,
                              min_modulation=20.0, saturation_level=level)
    for ours, theirs in zip(accumulated[:2], stacked[:2]):
        assert ours.dtype == np.float32 and ours.shape == (2, *SHAPE)
        np.testing.assert_allclose(ours, theirs, atol=2e-5)  # the same sums, up to float32 summation order
    assert np.array_equal(accumulated[2], stacked[2])
    assert not accumulated[2][:3, :3].any() and accumulated[2][5:, 5:].all()  # the saturated corner only
    error = np.angle(np.exp(1j * (accumulated[0][0] - phi_high)))[5:, 5:]
    assert np.abs(error).max() < 0.08  # the ramp's phase: noise sqrt(2/12) * 1 % / 35 % = 0.012 rad rms


def test_phase_offsets_and_shift_sign_of_the_layout_are_applied_frame_by_frame():
    images, phi = fringe_images(4.0, 5, dtype=np.uint8, shift_sign=1, phase_offset=0.7, seed=3)
    low, _ = fringe_images(1.0, 3, dtype=np.uint8, shift_sign=1, seed=4)
    layout = ScanLayout(frequencies=(4.0, 1.0), steps=(5, 3), phase_offsets=(0.7, 0.0), shift_sign=1)
    scan, sums = assemble([(4.0, images), (1.0, low)], layout, shift_sign=1)
    phases, modulation, valid = sums.maps(scan.slots(), min_modulation=10.0, saturation_level=None)
    error = np.angle(np.exp(1j * (phases[0] - phi)))[5:, 5:]
    assert np.abs(error).max() < 0.1  # noise sqrt(2/5) * 1 % / 35 % = 0.018 rad rms; a lost offset would be 0.7
    assert 80 < float(np.median(modulation[0])) < 100  # B = 0.35 * 255 = 89 DN


def test_camera_points_written_into_a_cloud_buffer_equal_the_plain_call():
    from dptpu.fpp.triangulate import Triangulator
    from dptpu.sim.rig import load_twin_rig

    rig = load_twin_rig("nominal", camera_size=(160, 120))
    triangulator = Triangulator(rig, axis="x")
    height, width = triangulator.shape
    coord = np.linspace(100.0, 800.0, width)[None, :] + np.zeros((height, width))
    coord[::7, ::5] = np.nan
    plain = triangulator.camera_points(coord, scale=1e-3)
    cloud = np.full((height, width, 5), -1.0, dtype=np.float32)
    written = triangulator.camera_points(coord, scale=1e-3, out=cloud[..., :3])
    assert written.base is cloud or written.base is cloud.base
    np.testing.assert_array_equal(cloud[..., :3], plain)
    assert (cloud[..., 3:] == -1.0).all()
    assert np.isnan(cloud[::7, ::5, 2]).all() and np.isfinite(plain[1:7, 1:5]).all()
    with pytest.raises(ValueError, match="out must be an array of shape"):
        triangulator.camera_points(coord, out=np.empty((height, width, 3), dtype=np.float64))
