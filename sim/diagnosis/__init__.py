"""Sim-to-real diagnosis: what the twin gets wrong on measured data, the cause, the extension and its gain.

``dptpu twin diagnose`` (docs/sim-to-real.md). Modules, one idea each: :mod:`.measured` (the data),
:mod:`.reference` (analytic reference surfaces, scene files), :mod:`.registration` and
:mod:`.scene_registration` (their pose), :mod:`.forward` (the twin's
image formation on pixels), :mod:`.pixels` (which pixels, with what the twin knows), :mod:`.candidates`
(effects fitted with the twin in the loop), :mod:`.motion` (motion between frames), :mod:`.response` (a
lookup-table projector response), :mod:`.noise` (the random part), :mod:`.selection` (BIC),
:mod:`.residuals` (decomposition), :mod:`.figures`, :mod:`.rerender`, :mod:`.report` and :mod:`.diagnose`.
"""
from .diagnose import Diagnosis, diagnose

__all__ = ["Diagnosis", "diagnose"]
