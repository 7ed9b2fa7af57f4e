"""A multi-host Dask cluster without leaving this machine: network namespaces joined by veth pairs
(`ip netns`, needs root or CAP_NET_ADMIN: skipped with the reason otherwise), a scheduler in one,
a worker in each of two others, this process (the client) in the machine's own namespace.  A render
through them is the local render bit for bit; with one worker's link cut mid-render
(`ip link set ... down`: its TCP connections stay open and silent, as when a cable is pulled) the
render recovers through the unit deadline (engine/pools/dask_watch.py), bit for bit again.

    root  10.231.0.1 ── 10.231.0.2  scheduler namespace (forwards)  10.231.1.1 ── 10.231.1.2  worker a
                                                                    10.231.2.1 ── 10.231.2.2  worker b
"""
import os
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from engine import RenderSettings, render                     # noqa: E402
from engine.pools import faults                               # noqa: E402
from engine.pools.dask_cluster import RENDER_WORKER_CONFIG, connect   # noqa: E402
from engine.pools.spec import make_pool                       # noqa: E402
from engine.scene.builtin import cornell_scene                # noqa: E402
from tests.load_tolerance import guarded                       # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DASK = os.path.join(os.path.dirname(sys.executable), "dask")
HANG = 240.0       # seconds: a guard against a hang, not a timing check
QUIET = dict(log=lambda *a: None)
PORT = 8786
TAG = f"t{os.getpid() % 100000}"
NS = {"s": f"{TAG}s", "a": f"{TAG}a", "b": f"{TAG}b"}
NET = "10.231"


def ip(*args, ns=None, check=True):
    command = (["ip", "netns", "exec", ns] if ns else []) + list(args)
    return subprocess.run(command, capture_output=True, text=True, check=check)


def netns_unavailable() -> str | None:
    if shutil.which("ip") is None:
        return "no `ip` command (iproute2)"
    probe = f"{TAG}probe"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if made.returncode != 0:
        return f"`ip netns add` is not permitted here: {made.stderr.strip() or made.returncode}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def veth(outer, inner, outer_ns, inner_ns, outer_ip, inner_ip):
    """A veth pair: `outer` in outer_ns (None: the root namespace) with outer_ip, `inner` in inner_ns."""
    ip("ip", "link", "add", outer, "type", "veth", "peer", "name", inner, ns=outer_ns)
    ip("ip", "link", "set", inner, "netns", inner_ns, ns=outer_ns)
    ip("ip", "addr", "add", f"{outer_ip}/24", "dev", outer, ns=outer_ns)
    ip("ip", "link", "set", outer, "up", ns=outer_ns)
    ip("ip", "addr", "add", f"{inner_ip}/24", "dev", inner, ns=inner_ns)
    ip("ip", "link", "set", inner, "up", ns=inner_ns)
    ip("ip", "link", "set", "lo", "up", ns=inner_ns)


class NamespaceCluster:
    """The scheduler in NS["s"], one no-nanny worker in each of NS["a"], NS["b"]; close() removes it all."""

    def __init__(self, directory):
        self.directory, self.procs = directory, {}
        try:
            for ns in NS.values():
                ip("ip", "netns", "add", ns)
            veth(f"{TAG}r", f"{TAG}rs", None, NS["s"], f"{NET}.0.1", f"{NET}.0.2")
            veth(f"{TAG}sa", f"{TAG}as", NS["s"], NS["a"], f"{NET}.1.1", f"{NET}.1.2")
            veth(f"{TAG}sb", f"{TAG}bs", NS["s"], NS["b"], f"{NET}.2.1", f"{NET}.2.2")
            ip("sysctl", "-qw", "net.ipv4.ip_forward=1", ns=NS["s"])
            for w, n in (("a", 1), ("b", 2)):
                ip("ip", "route", "add", "default", "via", f"{NET}.{n}.1", ns=NS[w])
                ip("ip", "route", "add", f"{NET}.{n}.0/24", "via", f"{NET}.0.2")
            self.address = f"tcp://{NET}.0.2:{PORT}"
            self._spawn("scheduler", NS["s"], ["scheduler", "--host", f"{NET}.0.2", "--port", str(PORT),
                                                "--no-dashboard", "--dashboard-address", f"{NET}.0.2:0"])
            self.client = connect(self.address, timeout=30)
            for w, n in (("a", 1), ("b", 2)):
                self._spawn(w, NS[w], ["worker", self.address, "--host", f"{NET}.{n}.2", "--nthreads", "1",
                                       "--no-nanny", "--no-dashboard", "--name", f"worker-{w}"], pythonpath=ROOT)
            self.client.wait_for_workers(2, timeout=120)
        except BaseException:
            self.close()
            raise

    def _spawn(self, name, ns, args, pythonpath=None):
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env.update(RENDER_WORKER_CONFIG)
        if pythonpath:
            env["PYTHONPATH"] = pythonpath
        with open(os.path.join(self.directory, f"{name}.log"), "ab") as log:
            self.procs[name] = subprocess.Popen(["ip", "netns", "exec", ns, DASK, *args], stdout=log,
                                                stderr=subprocess.STDOUT, env=env, start_new_session=True)

    def worker_of(self, name) -> str:
        return next(a for a, w in self.client.scheduler_info()["workers"].items() if w.get("name") == f"worker-{name}")

    def cut(self, name):
        """The worker's only link down: its connections stay open and silent."""
        ip("ip", "link", "set", f"{TAG}{name}s", "down", ns=NS[name])

    def close(self):
        client = getattr(self, "client", None)
        if client is not None:
            try:
                client.close(timeout=5)
            except Exception:
                pass
        for proc in self.procs.values():
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(timeout=10)
        for n in (1, 2):
            ip("ip", "route", "del", f"{NET}.{n}.0/24", check=False)
        ip("ip", "link", "del", f"{TAG}r", check=False)
        for ns in NS.values():
            ip("ip", "netns", "del", ns, check=False)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    why = netns_unavailable()
    if why:
        pytest.skip(why)
    c = NamespaceCluster(str(tmp_path_factory.mktemp("netns")))
    try:
        yield c
    finally:
        c.close()


SCENE, SETTINGS = (96, 96), dict(samples=48, tile_size=16, seed=13)


@pytest.fixture(scope="module")
def reference():
    return render(cornell_scene(SCENE), RenderSettings(threads=1, **SETTINGS), **QUIET).image




def render_through(cluster, on_first_tile=None):
    tiles = []

    def on_tile(*args):
        tiles.append(args[:4])
        if len(tiles) == 1 and on_first_tile is not None:
            on_first_tile()

    pool = make_pool(f"dask:{cluster.address}", 2, **QUIET)
    return guarded(HANG, lambda: render(cornell_scene(SCENE), RenderSettings(**SETTINGS), pool=pool, on_tile=on_tile, **QUIET))


@pytest.mark.slow          # namespaces, a cluster of processes
def test_a_render_through_three_network_namespaces_is_the_local_render(cluster, reference):
    result = render_through(cluster)
    assert result.stats["parallelism"] == f"dask {cluster.address} (2 workers)"
    assert np.array_equal(result.image, reference)


@pytest.mark.slow          # namespaces, a cluster of processes and a 5 s unit deadline
def test_a_worker_whose_link_is_cut_mid_render_is_removed_and_the_image_is_bit_identical(cluster, reference,
                                                                                           monkeypatch):
    monkeypatch.setattr(faults, "DEADLINE_MIN", 5.0)
    lost = cluster.worker_of("a")
    result = render_through(cluster, on_first_tile=lambda: cluster.cut("a"))
    assert np.array_equal(result.image, reference)
    assert not result.cancelled and result.stats["units_done"] == result.stats["units"]
    assert any(f"Dask worker {lost} stopped answering" in w for w in result.warnings), result.warnings
