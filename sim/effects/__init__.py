"""Physical effects of the twin: named, parameterized stages of image formation, all off by default.

See :mod:`dptpu.sim.effects.registry` for how they are switched on and docs/effects.md for each effect's
parameters and its signature in the data.
"""
from .registry import EFFECTS, STAGES, Effect, EffectSpec, effects_to_yaml, find_effect, load_effects, parse_effects

__all__ = ["EFFECTS", "STAGES", "Effect", "EffectSpec", "effects_to_yaml", "find_effect", "load_effects",
           "parse_effects"]
