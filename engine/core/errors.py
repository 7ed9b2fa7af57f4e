"""Errors the tracer raises for bad input: the message names the object and the problem."""


class SceneError(ValueError):
    """Invalid scene input; the message names the object and the problem."""
