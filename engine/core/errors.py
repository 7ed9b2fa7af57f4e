"""Errors the tracer raises for bad input: the message names the object and the problem."""


class SceneError(ValueError):
    """Invalid scene input; the message names the object and the problem."""


class WorkersLost(SceneError):
    """Every worker of a pool died (or a unit killed two): one line naming the last.  The frame
    (engine/rendering/frame.py) sets `result` to the finished units' image before raising it, so a
    command line can write them (a SceneError: both command lines print it as one line)."""

    result = None
