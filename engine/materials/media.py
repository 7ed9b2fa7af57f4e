"""Nested dielectrics (the report's §4 future work): the stack of media a path is inside.

With `nested_dielectrics` each path keeps the IORs of the glass objects it has entered, innermost
last, so glass inside glass or water in a glass refracts with the ratio of the two IORs instead of
each against air (the report's and Cycles' model).  Entering a surface goes from the medium on
top of the stack into the surface's IOR (pushed); leaving it goes into the medium below the top
(popped).  Air (IOR 1) is outside every stack.
"""
from __future__ import annotations

import numpy as np

MEDIUM_STACK_DEPTH = 4          # media a path can be inside at once


class MediumStack:
    """The stacks of some paths: media (N, MEDIUM_STACK_DEPTH) IORs and depth (N,) heights.
    Usually views of the path state's arrays: updates write through to the paths."""

    def __init__(self, media: np.ndarray, depth: np.ndarray):
        self.media, self.depth = media, depth

    @staticmethod
    def empty(n: int) -> "MediumStack":
        """Stacks of n paths in air."""
        return MediumStack(np.ones((n, MEDIUM_STACK_DEPTH)), np.zeros(n, dtype=np.int64))

    def __getitem__(self, span: slice) -> "MediumStack":
        return MediumStack(self.media[span], self.depth[span])

    def eta(self, entering: np.ndarray, ior: np.ndarray) -> np.ndarray:
        """eta = n1 / n2 at surfaces of IOR `ior`: entering, from the medium the path is in;
        leaving, into the one below it."""
        media, depth = self.media, self.depth
        path = np.arange(len(depth))
        current = np.where(depth > 0, media[path, np.maximum(depth - 1, 0)], 1.0)
        below = np.where(depth > 1, media[path, np.maximum(depth - 2, 0)], 1.0)
        return np.where(entering, current / ior, ior / below)

    def cross(self, through: np.ndarray, entering: np.ndarray, ior: np.ndarray) -> None:
        """The paths `through` (indices) refracted: push `ior` where they entered (while the stack
        has room), pop where they left."""
        media, depth = self.media, self.depth
        push = through[entering[through] & (depth[through] < MEDIUM_STACK_DEPTH)]
        media[push, depth[push]] = ior[push]
        depth[push] += 1
        pop = through[~entering[through] & (depth[through] > 0)]
        depth[pop] -= 1
