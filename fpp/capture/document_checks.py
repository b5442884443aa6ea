"""Checks on a parsed YAML document whose failures name the file and the key (``capture.yaml: missing key
'projector.size'``)."""

from __future__ import annotations

import numbers
from typing import NoReturn

from ..checks import is_finite_real
from .model import format_number

__all__ = ["DocumentChecker", "MAX_SIDE_PX"]

#: Largest width or height of a camera or projector, pixels (no sensor or panel comes near it).
MAX_SIDE_PX = 100_000


class DocumentChecker:
    """Checks on a parsed YAML document whose failures name the file and the key."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, message: str) -> NoReturn:
        raise ValueError(f"{self.source}: {message}")

    def require(self, mapping: dict, key: str, dotted: str | None = None):
        if key not in mapping or mapping[key] is None:
            self.fail(f"missing key '{dotted or key}'")
        return mapping[key]

    def mapping(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            self.fail(f"{key} must be a mapping; got {value!r}")
        return value

    def number(self, value, key: str) -> float:
        if not is_finite_real(value):
            self.fail(f"{key} must be a finite number; got {value!r}")
        return float(value)

    def positive(self, value, key: str) -> float:
        value = self.number(value, key)
        if value <= 0:
            self.fail(f"{key} must be > 0; got {format_number(value)}")
        return value

    def integer(self, value, key: str, *, minimum: int, maximum: int | None = None) -> int:
        if (isinstance(value, bool) or not isinstance(value, numbers.Integral) or int(value) < minimum
                or (maximum is not None and int(value) > maximum)):
            bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
            self.fail(f"{key} must be an integer {bound}; got {value!r}")
        return int(value)

    def size(self, value, key: str) -> tuple[int, int]:
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                or any(isinstance(v, bool) or not isinstance(v, numbers.Integral) or not 1 <= int(v) <= MAX_SIDE_PX
                       for v in value)):
            self.fail(f"{key} must be [width, height] in pixels (two integers in [1, {MAX_SIDE_PX}]); got {value!r}")
        return int(value[0]), int(value[1])

    def file_name(self, value, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            self.fail(f"{key} must be a file name (relative to the capture folder, or absolute); got {value!r}")
        return value

    def file_list(self, value, key: str) -> list[str]:
        if not isinstance(value, list):
            self.fail(f"{key} must be a list of file names; got {value!r}")
        return [self.file_name(v, f"{key}[{i}]") for i, v in enumerate(value)]
