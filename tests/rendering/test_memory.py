"""The memory estimate's arithmetic (engine/rendering/memory.py), the limits it reads (faked /proc
and cgroup files), the refusals, and the Embree build's RLIMIT_AS pre-check
(engine/geometry/accel/embree.py).  The measured figures: engine/cli/bench_memory.py."""
import logging

import pytest

from engine.core.errors import SceneError
from engine.core.settings import RenderSettings
from engine.geometry.accel import embree
from engine.rendering import memory
from engine.rendering.memory import (BUILD_BYTES_PER_TRIANGLE, BYTES_PER_PIXEL, MESSAGE_BYTES_PER_TRIANGLE,
                                     PROCESS_BYTES, SCENE_BYTES_PER_TRIANGLE, TRACING_BYTES_PER_TRIANGLE,
                                     WORKER_BYTES, check_memory, cgroup_room, estimate_bytes, memory_estimate,
                                     memory_limits)
from engine.scene.builtin import cornell_scene


def scene_of(resolution, big_triangles=0):
    from engine.cli.bench_memory import torus_scene
    return torus_scene(big_triangles, resolution) if big_triangles else cornell_scene((resolution, resolution))


def triangles(scene):
    return sum(len(m.triangles) for m in scene.meshes)


def test_shared_pools_hold_one_copy_and_worker_processes_one_each():
    scene = scene_of(512, big_triangles=200_000)
    n, pixels = triangles(scene), 512 * 512
    settings = RenderSettings(threads=2)
    shared = memory_estimate(scene, settings, pool="processes")
    assert shared.worker_processes == 0
    assert shared.total == (PROCESS_BYTES + n * (SCENE_BYTES_PER_TRIANGLE + TRACING_BYTES_PER_TRIANGLE)
                            + max(n * BUILD_BYTES_PER_TRIANGLE, pixels * BYTES_PER_PIXEL + 2 * WORKER_BYTES))
    assert memory_estimate(scene, settings, pool="threads") == shared
    own = memory_estimate(scene, settings, pool="workers")
    assert own.worker_processes == 2
    assert own.main == PROCESS_BYTES + n * (SCENE_BYTES_PER_TRIANGLE + 2 * MESSAGE_BYTES_PER_TRIANGLE) \
        + pixels * BYTES_PER_PIXEL
    assert own.per_worker == PROCESS_BYTES + n * (SCENE_BYTES_PER_TRIANGLE + TRACING_BYTES_PER_TRIANGLE) \
        + max(n * BUILD_BYTES_PER_TRIANGLE, WORKER_BYTES)
    assert own.total == own.main + 2 * own.per_worker > shared.total
    four = memory_estimate(scene, RenderSettings(threads=4), pool="workers:/usr/bin/python3")
    assert four.total - own.total == 2 * own.per_worker + 2 * n * MESSAGE_BYTES_PER_TRIANGLE
    remote = memory_estimate(scene, settings, pool="dask")
    assert remote.worker_processes == 0 and remote.main < own.main
    assert estimate_bytes(scene, settings, pool="workers") == own.total


def fake_files(tmp_path, meminfo_kib=None, cgroup_line=None, files=None):
    proc = tmp_path / "proc"
    (proc / "self").mkdir(parents=True)
    if meminfo_kib is not None:
        (proc / "meminfo").write_text(f"MemTotal: 99999999 kB\nMemAvailable: {meminfo_kib} kB\n")
    if cgroup_line is not None:
        (proc / "self" / "cgroup").write_text(cgroup_line + "\n")
    root = tmp_path / "cgroup"
    for rel, text in (files or {}).items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return str(proc), str(root)


def test_cgroup_v2_v1_and_unlimited(tmp_path):
    proc, root = fake_files(tmp_path / "v2", 8 << 20, "0::/user.slice/job",
                            {"user.slice/job/memory.max": str(3 << 30), "user.slice/job/memory.current": str(1 << 30)})
    assert cgroup_room(proc, root) == 2 << 30
    assert memory_limits(proc, root) == [(8 << 30, "MemAvailable"), (2 << 30, "the cgroup's memory limit")]
    proc, root = fake_files(tmp_path / "max", 8 << 20, "0::/", {"memory.max": "max\n", "memory.current": "5"})
    assert cgroup_room(proc, root) is None
    proc, root = fake_files(tmp_path / "v1", 8 << 20, "12:pids:/x\n7:memory:/docker/abc",
                            {"memory/docker/abc/memory.limit_in_bytes": str(1 << 30),
                             "memory/docker/abc/memory.usage_in_bytes": str(1 << 28)})
    assert cgroup_room(proc, root) == (1 << 30) - (1 << 28)
    proc, root = fake_files(tmp_path / "v1max", 8 << 20, "7:memory:/",
                            {"memory/memory.limit_in_bytes": "9223372036854771712"})
    assert cgroup_room(proc, root) is None
    proc, root = fake_files(tmp_path / "container", 8 << 20, "4:memory:/host/path\n0::/",
                            {"memory/memory.limit_in_bytes": str(1 << 30), "memory/memory.usage_in_bytes": "0"})
    assert cgroup_room(proc, root) == 1 << 30          # the host's path is absent: the mount root's limit
    proc, root = fake_files(tmp_path / "none", 8 << 20)
    assert cgroup_room(proc, root) is None


def test_refused_with_the_smallest_limit_named(monkeypatch):
    scene, settings = scene_of(1024, big_triangles=200_000), RenderSettings(threads=2)
    need = estimate_bytes(scene, settings)
    monkeypatch.setattr(memory, "memory_limits", lambda: [(need * 4, "MemAvailable"),
                                                          (need // 2, "the cgroup's memory limit")])
    monkeypatch.setattr(memory, "address_space_limit", lambda: None)
    with pytest.raises(SceneError, match=r"needs about .* GB of memory, only .* GB is available \(the cgroup's "
                                         r"memory limit\): with 2 worker\(s\); use fewer threads \(--threads\) or a "
                                         r"lower resolution"):
        check_memory(scene, settings)
    monkeypatch.setattr(memory, "memory_limits", lambda: [(need * 4, "MemAvailable")])
    assert check_memory(scene, settings) == need                        # the control: enough memory
    monkeypatch.setattr(memory, "address_space_limit", lambda: need // 4)
    with pytest.raises(SceneError, match=r"of address space in one process, the limit \(RLIMIT_AS"):
        check_memory(scene, settings)
    monkeypatch.setattr(memory, "address_space_limit", lambda: need * 4)
    assert check_memory(scene, settings) == need


def test_embree_buffers_refused_when_their_address_space_cannot_be_mapped(monkeypatch):
    def no_room(n, dtype):
        raise MemoryError
    monkeypatch.setattr(embree.np, "empty", no_room)
    monkeypatch.setattr(embree, "address_space_limit", lambda: 800_000_000)
    with pytest.raises(SceneError, match=r"Embree cannot build the BVH of 1000000 triangles \(0.15 GB of address space "
                                         r"could not be mapped\); the address-space limit \(RLIMIT_AS, ulimit -v\) "
                                         r"is 0.7 GB: raise it or use fewer triangles or threads"):
        embree.probe_room(1_000_000)
    monkeypatch.undo()
    embree.probe_room(1000)                                             # the control: room enough


class FakeScene:
    """An embreex scene whose commit reports through embreex's logger, as Embree's error callback does."""

    def __init__(self, messages):
        self.messages = messages

    def run(self, origins, directions):
        assert len(origins) == 0                        # the commit alone: no ray meets an unbuilt scene
        for m in self.messages:
            logging.getLogger("embreex").error(m)


def test_embree_build_errors_become_one_scene_error(monkeypatch):
    monkeypatch.setattr(embree, "address_space_limit", lambda: None)
    with pytest.raises(SceneError, match=r"^Embree cannot build the BVH of 5 triangles \(ERROR: Out of memory; ERROR "
                                         r"MESSAGE: b'out of memory'\): use fewer triangles or threads$"):
        embree.build(FakeScene(["ERROR CAUGHT IN EMBREE", "ERROR: Out of memory", "ERROR MESSAGE: b'out of memory'"]), 5)
    embree.build(FakeScene([]), 5)                                      # the control: no error, no exception
    assert not logging.getLogger("embreex").handlers


@pytest.mark.slow
def test_the_cli_under_an_address_space_limit_gives_one_line_never_a_crash(tmp_path):
    """Embree out of memory prints and then crashes the process (rc 139): the CLI must refuse first."""
    import os
    import resource
    import subprocess
    import sys
    from engine.cli.bench_memory import torus_scene
    from engine.scene.files import save_scene
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = str(tmp_path / "torus.json")
    save_scene(torus_scene(1_000_000, 64), path)
    # on the tracer before these checks, 800 MB and 850 MB crashed inside Embree (rc 139); 900 MB renders
    for limit in (400_000_000, 800_000_000, 850_000_000):
        r = subprocess.run([sys.executable, "-m", "engine", "render", path, "--samples", "1", "--threads", "2",
                            "-o", str(tmp_path / "out.exr"), "--quiet"], cwd=root, capture_output=True, text=True,
                           env=dict(os.environ, PYTHONPATH=root),
                           preexec_fn=lambda n=limit: resource.setrlimit(resource.RLIMIT_AS, (n, n)))
        assert r.returncode in (1, 2), (limit, r.returncode, r.stderr[-2000:])
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "error:" in lines[0] and ("memory" in lines[0] or "address space" in lines[0]), \
            (limit, r.stderr[-2000:])
