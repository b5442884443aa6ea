"""Moved to :mod:`dptpu.sim.outside_rigs` (one module for every outside-rig generator); re-exported here so that
``from tests.outside_rigs import ...`` keeps working. New code imports ``dptpu.sim.outside_rigs``."""
from dptpu.sim.outside_rigs import (
    PROJECTOR_PANELS,
    SIGMA_2,
    OutsidePhases,
    issue16_rig,
    outside_rig,
    random_outside_rig,
    render_phases,
    spheres_and_plane,
)

__all__ = ["SIGMA_2", "PROJECTOR_PANELS", "OutsidePhases", "issue16_rig", "outside_rig", "random_outside_rig",
           "render_phases", "spheres_and_plane"]
