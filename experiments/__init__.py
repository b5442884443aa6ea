"""Experiments that need both the twin (:mod:`dptpu.sim`) and the network (:mod:`dptpu.models`).

The frequency-set study, the unwrapping evaluation on an unseen rig and the downstream fine-tuning of the
sim-to-real diagnosis live here, so that the twin and the network each import only the measurement core.
"""
