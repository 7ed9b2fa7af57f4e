"""The denoiser where the zip did not bring one (mcrt_addon/denoiser_install.py, bpy 5.0): the
preferences' "Install Denoiser" pip-installs the pinned pyoidn, cffi and pycparser into the add-on's
private directory (here a temporary one, from local fake wheels: no network), tries it in a process
of its own and puts it on the workers' path; a failing pip is reported, nothing installed.  Also
the Denoise checkboxes of Sampling > Render and Sampling > Viewport, and the warning that points to
the button."""
import importlib.util
import os
import sys
import zipfile
from types import SimpleNamespace

import bpy
import pytest

from conftest import REPO

FAKE_PYOIDN = ("import numpy as np\n"
               "def denoise(color, hdr=True, albedo=None, normal=None):\n"
               "    return np.full_like(color, color.mean())\n")


def fake_wheel(folder, name, version, files):
    dist = f"{name}-{version}.dist-info"
    files = dict(files)
    files[f"{dist}/METADATA"] = f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n"
    files[f"{dist}/WHEEL"] = "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n"
    files[f"{dist}/RECORD"] = "".join(f"{f},,\n" for f in files) + f"{dist}/RECORD,,\n"
    path = os.path.join(folder, f"{name}-{version}-py3-none-any.whl")
    with zipfile.ZipFile(path, "w") as zf:
        for f, text in files.items():
            zf.writestr(f, text)
    return path


@pytest.fixture
def private(addon, tmp_path, monkeypatch):
    """The private directory in tmp_path, pip offline on a folder of fake wheels."""
    from mcrt_addon import denoiser_install, worker_python
    wheels = tmp_path / "wheels"
    wheels.mkdir()
    target = tmp_path / "user" / "denoiser"
    monkeypatch.setattr(worker_python, "denoiser_dir",
                        lambda create=False: (target.mkdir(parents=True, exist_ok=True) if create else None) or str(target))
    monkeypatch.setattr(denoiser_install, "INDEX_OPTIONS", ("--no-index", "--find-links", str(wheels)))
    yield SimpleNamespace(wheels=wheels, target=target)
    if str(target) in sys.path:
        sys.path.remove(str(target))


def test_install_denoiser_puts_pyoidn_in_the_private_directory(private):
    from mcrt_addon import bridge, denoiser_install, worker_python
    fake_wheel(private.wheels, "pyoidn", "2.5.1.0", {"pyoidn/__init__.py": FAKE_PYOIDN})
    fake_wheel(private.wheels, "cffi", "2.1.1", {"cffi/__init__.py": ""})
    fake_wheel(private.wheels, "pycparser", "3.12", {"pycparser/__init__.py": ""})
    assert worker_python.denoiser_dir_installed() is None
    assert bpy.ops.tncg15.install_denoiser() == {"FINISHED"}
    target = str(private.target)
    assert os.path.isfile(os.path.join(target, "pyoidn", "__init__.py"))
    assert {"cffi", "pycparser"} <= set(os.listdir(target)) and "numpy" not in os.listdir(target)
    assert worker_python.extra_paths()[0] == target and target in sys.path
    assert "pyoidn" not in sys.modules or not sys.modules["pyoidn"].__file__.startswith(target), \
        "the operator must not import pyoidn into Blender"
    # the workers now find the private one first: the trial process imports the fake
    denoise = bridge.module("film.denoise")
    out = denoise.denoise_in_subprocess(sys.executable, [[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]],
                                        extra_paths=worker_python.extra_paths())
    assert out.tolist() == [[[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]]]
    assert denoiser_install.pip_command("py", "T")[:8] == ["py", "-m", "pip", "install", "--target", "T",
                                                           "--no-deps", "--only-binary=:all:"]


def test_a_failing_install_is_reported_and_installs_nothing(private):
    from mcrt_addon import worker_python
    with pytest.raises(RuntimeError, match="Install Denoiser: installing the denoiser failed"):
        bpy.ops.tncg15.install_denoiser()            # no wheels: pip finds no pyoidn (an ERROR report)
    assert worker_python.denoiser_dir_installed() is None


def test_the_pins_are_the_bundled_wheels():
    from mcrt_addon import denoiser_install
    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(REPO, "scripts", "build_extension.py"))
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    assert tuple(build.DENOISER) == denoiser_install.REQUIREMENTS


class Recorder:
    def __init__(self, drawn):
        self.drawn, self.active, self.use_property_split, self.use_property_decorate = drawn, True, None, None

    def prop(self, data, name, **kw):
        self.drawn.append(name)

    def label(self, text="", **kw):
        self.drawn.append(text)

    def column(self, **kw):
        return self


@pytest.mark.parametrize("panel, prop", [("RENDER_PT_tncg15_sampling_render_denoise", "use_denoising"),
                                         ("RENDER_PT_tncg15_sampling_viewport_denoise", "use_preview_denoising")])
def test_denoise_checkboxes_sit_in_sampling_as_in_cycles(addon, monkeypatch, panel, prop):
    from mcrt_addon import denoiser_install
    cls = getattr(bpy.types, panel)
    parent = "render" if "render" in panel else "viewport"
    assert cls.bl_label == "Denoise" and cls.bl_parent_id == f"RENDER_PT_tncg15_sampling_{parent}"
    drawn = []
    context = SimpleNamespace(scene=bpy.context.scene)
    cls.draw_header(SimpleNamespace(layout=Recorder(drawn)), context)
    assert drawn == [prop]
    monkeypatch.setattr(denoiser_install, "known_problem", lambda: "no pyoidn")
    cls.draw(SimpleNamespace(layout=Recorder(drawn)), context)
    assert "Denoiser missing: Preferences > Add-ons > Install Denoiser" in drawn


def test_the_missing_denoiser_warning_points_to_the_button(addon):
    from mcrt_addon import bridge
    assert "Install Denoiser" in bridge.module("film.denoise").missing_message("/usr/bin/python3.11", "no module")
