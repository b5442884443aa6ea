"""The temporal phase unwrapping methods, by family: the one definition every package takes them from.

=========================== ================================ ===================================================
family                      methods                          what runs them
=========================== ================================ ===================================================
:data:`TWO_FREQUENCY_METHODS` ``mf``, ``mw``, ``nt``          :func:`dptpu.fpp.tpu.unwrap` (one high and one
                                                             auxiliary frequency, the paper's Eqs. (3)-(9)); the
                                                             DP-TPU network refines their fringe order; the
                                                             twin's datasets and the evaluations use them
:data:`PHASE_SEQUENCE_METHODS` the above + ``heterodyne``    everything unwrapped from phase-shifted sequences
                                                             alone: the unwrap node (a scan's phase maps)
:data:`CAPTURE_METHODS`     the above + ``graycode``          :func:`dptpu.fpp.reconstruct.unwrap_capture` (a
                                                             capture folder may hold a Gray-code sequence too)
=========================== ================================ ===================================================
"""
from __future__ import annotations

__all__ = ["CAPTURE_METHODS", "PHASE_SEQUENCE_METHODS", "TWO_FREQUENCY_METHODS"]

#: Two-frequency temporal unwrapping: multi-frequency (Eq. (5)), multi-wavelength (Eqs. (6)-(7)), number-theoretic
#: (Eqs. (8)-(9)).
TWO_FREQUENCY_METHODS = ("mf", "mw", "nt")
#: Every method that unwraps from phase-shifted sequences alone: the two-frequency ones and the heterodyne beat tree
#: of two or more frequencies.
PHASE_SEQUENCE_METHODS = (*TWO_FREQUENCY_METHODS, "heterodyne")
#: Every method of a capture folder: the phase-sequence ones and the Gray code indexing one phase sequence.
CAPTURE_METHODS = (*PHASE_SEQUENCE_METHODS, "graycode")
