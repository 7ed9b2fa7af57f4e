"""Typed fields of a scene file.

Every field read from JSON goes through ``Fields``: a wrong type or shape is one SceneError that
names the object and the field, e.g. ``Material 'Red': color must be 3 numbers, got 'red'``.
Value ranges (finite, positive, not too large) are checked afterwards by ``Scene.validate()``,
which the Blender exporter's scenes go through as well.
"""
from __future__ import annotations

import numbers

import numpy as np

from ..core.errors import SceneError

REQUIRED = object()


def describe(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


class Fields:
    """One JSON object of the scene file, ``owner`` names it in messages ("Object 'Floor'")."""

    def __init__(self, data, owner: str):
        if not isinstance(data, dict):
            raise SceneError(f"{owner}: must be a JSON object, got {describe(data)}")
        self.data, self.owner = data, owner

    def __contains__(self, key):
        return key in self.data

    def fail(self, key, expected, value):
        raise SceneError(f"{self.owner}: {key} must be {expected}, got {describe(value)}")

    def get(self, key, default=REQUIRED):
        if key in self.data:
            return self.data[key]
        if default is REQUIRED:
            raise SceneError(f"{self.owner}: {key} is missing")
        return default

    def text(self, key, default=REQUIRED) -> str:
        value = self.get(key, default)
        if not isinstance(value, str):
            self.fail(key, "a string", value)
        return value

    def _floats(self, key, values, expected, value) -> list:
        """float() of each number; an integer beyond float64 (JSON has no bound: 400 digits)
        fails naming the field instead of an OverflowError."""
        try:
            return [float(v) for v in values]
        except OverflowError:
            self.fail(key, f"{expected} within the range of a float (about 1.8e308)", value)

    def number(self, key, default=REQUIRED) -> float:
        value = self.get(key, default)
        if not is_number(value):
            self.fail(key, "a number", value)
        return self._floats(key, [value], "a number", value)[0]

    def numbers(self, key, count: int, default=REQUIRED) -> tuple:
        value = self.get(key, default)
        if not (isinstance(value, (list, tuple)) and len(value) == count and all(map(is_number, value))):
            self.fail(key, f"{count} numbers", value)
        return tuple(self._floats(key, value, f"{count} numbers", value))

    def integers(self, key, count: int, default=REQUIRED) -> tuple:
        value = self.get(key, default)
        if not (isinstance(value, (list, tuple)) and len(value) == count and all(map(is_integer, value))):
            self.fail(key, f"{count} integers", value)
        return tuple(int(v) for v in value)

    def matrix(self, key, rows: int, cols: int, default=REQUIRED) -> np.ndarray:
        value = self.get(key, default)
        ok = (isinstance(value, (list, tuple)) and len(value) == rows
              and all(isinstance(r, (list, tuple)) and len(r) == cols and all(map(is_number, r)) for r in value))
        if not ok:
            self.fail(key, f"{rows} rows of {cols} numbers", value)
        flat = self._floats(key, [v for r in value for v in r], f"{rows} rows of {cols} numbers", value)
        return np.asarray(flat, dtype=np.float64).reshape(rows, cols)

    def objects(self, key) -> list:
        value = self.get(key, [])
        if not isinstance(value, list):
            self.fail(key, "a list", value)
        return value

    def array(self, key, arrays, width: int | None, integer: bool) -> np.ndarray:
        """A list, or "@name" for an array of the NPZ beside the JSON; rows of ``width`` values
        (or a flat list when ``width`` is None), integers or numbers."""
        value = self.get(key)
        kind = "integers" if integer else "numbers"
        expected = f"a list of {kind}" if width is None else f"a list of [{', '.join('xyz'[:width])}] {kind}"
        if isinstance(value, str):
            if not value.startswith("@"):
                self.fail(key, f"{expected} or \"@name\" of an NPZ array", value)
            if value[1:] not in arrays:
                raise SceneError(f"{self.owner}: {key}: array '{value[1:]}' not found in the NPZ file")
            value = arrays[value[1:]]
        try:
            arr = np.asarray(value)
        except (TypeError, ValueError):          # ragged nesting
            self.fail(key, expected, value)
        if arr.size == 0:
            return np.zeros((0,) if width is None else (0, width), dtype=np.int64 if integer else np.float64)
        good_type = (np.issubdtype(arr.dtype, np.integer) if integer
                     else np.issubdtype(arr.dtype, np.number) and not np.issubdtype(arr.dtype, np.complexfloating))
        shape_ok = arr.ndim == 1 if width is None else (arr.ndim == 2 and arr.shape[1] == width)
        if arr.dtype == bool or not good_type or not shape_ok:
            self.fail(key, expected, value if not isinstance(value, np.ndarray)
                      else f"an array of {arr.dtype} with shape {arr.shape}")
        return arr.astype(np.int64 if integer else np.float64)
