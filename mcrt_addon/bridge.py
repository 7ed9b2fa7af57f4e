"""Finds the tracer package.

* In the repository (and with PYTHONPATH=<repo>) the tracer is the top-level package ``engine``.
* In the extension / legacy zip built by ``scripts/build_extension.py`` a copy of it is shipped
  inside the add-on as the sub-package ``tracer``, imported relatively: ``<addon package>.tracer``.

The tracer is imported lazily (at render time), so the add-on registers even when embreex is
missing and the user gets a readable error instead of a failed registration.  The one part of it
registration needs is the settings table (``core.settings``, standard library only; the tracer's
``__init__`` imports nothing heavy): `settings_table` finds it without the check for numpy that
`tracer_base` makes.
"""
import importlib

_base = None


def tracer_base() -> str:
    """Module path of the tracer package; raises ImportError with a user-readable message."""
    global _base
    if _base is not None:
        return _base
    errors = []
    for base in (__package__ + ".tracer", "engine"):
        try:
            module = importlib.import_module(base)
        except ImportError as exc:          # not there (or a dependency missing)
            errors.append(f"{base}: {exc}")
            continue
        if hasattr(module, "__path__"):
            try:
                importlib.import_module(base + ".scene.model")
            except ImportError as exc:
                errors.append(f"{base}.scene.model: {exc}")
                continue
            _base = base
            return base
        errors.append(f"{base}: not a package")
    raise ImportError("TNCG15 MC: the tracer package was not found (" + "; ".join(errors) + ")")


def module(name: str):
    """``module('scene')`` -> the tracer's scene module, wherever it lives."""
    return importlib.import_module(tracer_base() + "." + name)


def scene_module():
    return module("scene.model")


def settings_table():
    """The tracer's settings table module (engine/core/settings.py) without importing numpy."""
    errors = []
    for base in (__package__ + ".tracer", "engine"):
        try:
            return importlib.import_module(base + ".core.settings")
        except ImportError as exc:
            errors.append(f"{base}.core.settings: {exc}")
    raise ImportError("TNCG15 MC: the tracer's settings table was not found (" + "; ".join(errors) + ")")


def settings_class():
    return module("core.settings").RenderSettings


def render_function():
    """``engine.api.render``; raises ImportError with a clear message when it does not exist yet."""
    return module("api").render
