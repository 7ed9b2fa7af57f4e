"""scripts/check_warm_up.py: backend.warm_up compiles every kernel, for every type, that the renders
of the built-in scenes and the sample files call (else each worker compiles it in the first
render's way: docs/performance.md "Compiled kernels"); its control (a kernel called with a
type no render passes) is reported."""
import os
import subprocess
import sys

import pytest

from tests.backend_capture import require_compiled

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "scripts", "check_warm_up.py")


def run(*args, timeout=900):
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT)


@pytest.mark.slow
def test_the_check_reports_a_kernel_compiled_after_warm_up():
    require_compiled()
    r = run("--control", "--files", "--no-builtins", timeout=300)
    assert r.returncode == 1, r.stdout[-2000:] + r.stderr[-2000:]
    assert "control: integrators.wavefront_jit._take_1d" in r.stdout and "float32" in r.stdout


@pytest.mark.slow
def test_no_render_of_a_builtin_scene_or_sample_file_compiles_a_kernel():
    require_compiled()
    r = run("--each")                      # each scene as a worker's first render of it
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "0 scene(s) compiled kernels" in r.stdout
