"""Tests of dptpu.experiments: the study, the unwrapping evaluation and the downstream fine-tune."""
