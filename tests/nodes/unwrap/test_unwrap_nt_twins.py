"""The unwrap node with NT 64 / 10.9 on noisy phases: no near-twin (47 orders off) published, one warning for the
pair however many scans arrive (fpp.nt_twins)."""
import numpy as np

from dptpu.messages import AbsolutePhase, PhaseMaps
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.unwrap import UnwrapNode

F_H, F_L, WIDTH = 64.0, 10.9, 912


def _scan(sequence_id, rng, shape=(40, 300), noise_rad=0.012):
    """A plane across the projector's whole width, phase noise ``noise_rad``; truth x / W."""
    x = np.broadcast_to(np.linspace(0.001, 0.999, shape[1]), shape)
    phases = np.stack([np.mod(2 * np.pi * f * x + rng.normal(0, noise_rad, shape), 2 * np.pi) for f in (F_H, F_L)])
    return x, PhaseMaps(sequence_id=sequence_id, frequencies=np.array([F_H, F_L]), phases=phases.astype(np.float32),
                        modulation=np.full((2, *shape), 60.0, np.float32), valid=np.ones(shape, bool),
                        fringe_axis="x", projector_width=WIDTH, projector_height=1140,
                        steps=np.array([12, 12], np.uint32))


def test_no_twin_published_and_one_warning_for_the_pair():
    rng = np.random.default_rng(1)
    with NodeHarness() as harness:
        node = harness.start(UnwrapNode, method="nt", model="none")
        warnings = []
        logger = node.get_logger()
        logged = logger.warning
        logger.warning = lambda message, **kwargs: (warnings.append(str(message)), logged(message, **kwargs))[1]
        phase_pub = harness.publisher(PhaseMaps, "/scanner/phase")
        absolute = harness.collect(AbsolutePhase, "/scanner/absolute_phase")
        harness.connect()
        truths = []
        for sequence_id in (1, 2):
            x, scan = _scan(sequence_id, rng)
            truths.append(x)
            phase_pub.publish(scan)
        received = harness.wait(absolute, 2)
    twin_lines = [w for w in warnings if w.startswith("NT pair 64 / 10.9 has a near-twin 47 high orders")]
    assert len(twin_lines) == 1
    for msg, x in zip(received, truths):
        shift = np.rint((np.asarray(msg.absolute_phase, np.float64) - 2 * np.pi * F_H * x) / (2 * np.pi))
        valid = np.asarray(msg.valid, bool)
        assert valid.mean() > 0.9
        # the lookup lands on the twin on 731 pixels (459 of them at a reliability >= 0.2): none published
        assert not (valid & (shift != 0)).any()
