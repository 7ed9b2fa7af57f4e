"""`python -m engine bench-memory`: the memory estimate (engine/rendering/memory.py) against the
memory a render really takes, for a few scene sizes, resolutions and pools.

Each case runs in a fresh Python (a driver started here), so its peak is its own; this process
polls the driver and its worker processes every POLL seconds and records
* summed VmHWM: the peak resident set of each process (/proc/<pid>/status), added up (what a
  worker-process pool such as the add-on's really holds: each worker has its own copy), and
* peak summed PSS: the largest sum over the processes at one instant of their proportional set
  (/proc/<pid>/smaps_rollup), which counts the copy-on-write pages forked workers share once.
The ratio is estimate / measured (VmHWM for threads and worker processes, PSS for forked ones).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

POLL = 0.05
CASES = (   # (triangles, resolution, pool, threads)
    (200_000, 1024, "threads", 1),
    (1_000_000, 1024, "threads", 1),
    (200_000, 2048, "threads", 1),
    (200_000, 1024, "workers", 2),
    (1_000_000, 1024, "workers", 2),
    (1_000_000, 2048, "workers", 2),
    (1_000_000, 1024, "processes", 2),
)

# The process measured; PKG: the tracer package (absolute imports would break the bundled copy).
DRIVER = r"""
import json, sys
from PKG.cli.bench_memory import torus_scene
from PKG.core.settings import RenderSettings
from PKG.rendering.memory import estimate_bytes
from PKG.api import render
from PKG.pools.spec import make_pool
triangles, res, pool, threads = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
scene = torus_scene(triangles, res)
settings = RenderSettings(samples=1, threads=threads, parallelism="threads" if pool == "workers" else pool)
print(json.dumps({"estimate": estimate_bytes(scene, settings, pool=pool)}), flush=True)
spec = f"workers:{sys.executable}" if pool == "workers" else (pool if threads > 1 else "threads")
render(scene, settings, pool=make_pool(spec, threads, log=lambda *a: None), log=lambda *a: None)
"""


def torus_scene(triangles: int, resolution: int):
    """The built-in room with a torus of about `triangles` triangles instead of the Cornell one."""
    from ..scene.builtin import BLUE, cornell_scene, torus
    scene = cornell_scene((resolution, resolution))
    n = max(3, int(round((triangles / 2) ** 0.5)))
    scene.meshes = [m for m in scene.meshes if m.name != "Torus"] + [
        torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, n, n, BLUE)]
    return scene


def _status_kib(pid: int, key: str) -> int:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith(key):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _pss_kib(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            for line in fh:
                if line.startswith("Pss:"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            children.setdefault(ppid, []).append(int(name))
    found, todo = [], [root]
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo.extend(children.get(pid, ()))
    return found


def measure(triangles: int, resolution: int, pool: str, threads: int) -> dict:
    """Run one case in a driver process; its estimate and measured peaks in bytes."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))]
        + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    driver = DRIVER.replace("PKG", __package__.split(".")[0])      # the tracer package's name, bundled or not
    proc = subprocess.Popen([sys.executable, "-c", driver, str(triangles), str(resolution), pool, str(threads)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    hwm: dict[int, int] = {}
    peak_pss = 0
    while proc.poll() is None:
        pids = _descendants(proc.pid)
        for pid in pids:
            hwm[pid] = max(hwm.get(pid, 0), _status_kib(pid, "VmHWM:"))
        peak_pss = max(peak_pss, sum(_pss_kib(pid) for pid in pids))
        time.sleep(POLL)
    out, err = proc.communicate()
    if proc.returncode:
        raise RuntimeError(f"the driver failed (rc {proc.returncode}): {err[-2000:]}")
    estimate = json.loads(out.splitlines()[0])["estimate"]
    return {"triangles": triangles, "resolution": resolution, "pool": pool, "threads": threads,
            "processes": len(hwm), "estimate": estimate, "summed_hwm": sum(hwm.values()) * 1024,
            "peak_pss": peak_pss * 1024, "per_process": sorted(v * 1024 for v in hwm.values())}


def run_bench_memory(cases=CASES) -> list[dict]:
    gib = 2.0 ** 30
    print(f"TNCG15 MC bench-memory: {os.cpu_count()} core(s), load {os.getloadavg()[0]:.1f}; 1 spp each")
    print("| triangles | resolution | pool | workers | processes | estimate GiB | summed VmHWM GiB "
          "| peak summed PSS GiB | estimate / measured |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    rows = []
    for case in cases:
        row = measure(*case)
        measured = row["peak_pss"] if row["pool"] == "processes" else row["summed_hwm"]
        row["ratio"] = row["estimate"] / measured
        rows.append(row)
        print(f"| {row['triangles']:,} | {row['resolution']}² | {row['pool']} | {row['threads']} | {row['processes']} "
              f"| {row['estimate'] / gib:.2f} | {row['summed_hwm'] / gib:.2f} | {row['peak_pss'] / gib:.2f} "
              f"| {row['ratio']:.2f} |", flush=True)
    return rows


if __name__ == "__main__":
    run_bench_memory()
