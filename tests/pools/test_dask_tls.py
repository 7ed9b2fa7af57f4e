"""A tls:// Dask cluster (engine/pools/dask_tls.py): a certificate authority and a certificate made
here (the `cryptography` package is not needed: the openssl command line), a scheduler and workers
on 127.0.0.1 that accept only peers with a certificate of that authority, and renders through it
from the engine's command line, the add-on's and the pool, bit for bit the local render; without
the certificates, one line."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from engine import RenderSettings, render                     # noqa: E402
from engine.film.image_files import read_image                # noqa: E402
from engine.pools import dask_tls                             # noqa: E402
from engine.pools.dask_cluster import ProcessCluster          # noqa: E402
from engine.pools.spec import make_pool                       # noqa: E402
from engine.scene.builtin import cornell_scene                # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
QUIET = dict(log=lambda *a: None)
NO_TLS_ENV = {k: v for k, v in os.environ.items() if not k.startswith(("TNCG15_TLS_", "DASK_DISTRIBUTED__COMM__TLS"))}


def make_certificates(directory) -> dict:
    """A self-signed CA and a certificate for 127.0.0.1 / localhost signed by it (PEM files)."""
    openssl = shutil.which("openssl")
    if openssl is None:
        pytest.skip("no openssl command line to make test certificates")
    d = str(directory)
    ca_key, ca, key, csr, cert = (os.path.join(d, n) for n in ("ca.key", "ca.pem", "node.key", "node.csr", "node.pem"))
    ext = os.path.join(d, "san.ext")
    with open(ext, "w") as f:
        f.write("subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth,clientAuth\n")
    run = lambda *a: subprocess.run([openssl, *a], check=True, capture_output=True)      # noqa: E731
    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca, "-days", "2",
        "-subj", "/CN=tncg15 test CA")
    run("req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", csr, "-subj", "/CN=localhost")
    run("x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial", "-out", cert, "-days", "2",
        "-extfile", ext)
    return {"ca": ca, "cert": cert, "key": key}


def test_a_tls_address_without_certificates_is_one_line(monkeypatch):
    for name in dask_tls.ENV.values():
        monkeypatch.delenv(name, raising=False)
    import dask
    with dask.config.set({"distributed.comm.tls.ca-file": None, "distributed.comm.tls.client.cert": None}):
        with pytest.raises(dask_tls.TLSError, match="--tls-ca-file and --tls-cert") as err:
            dask_tls.security_for("tls://127.0.0.1:8786")
    assert "\n" not in str(err.value)
    assert dask_tls.security_for("tcp://127.0.0.1:8786") is None


def test_the_tls_options_are_checked_before_anything_runs(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "engine", "render", "--cluster", "tls://127.0.0.1:9",
                           "--tls-ca-file", str(tmp_path / "nope.pem"), "-o", str(tmp_path / "x.exr")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120, env=NO_TLS_ENV)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().endswith("--tls-ca-file '" + str(tmp_path / "nope.pem") + "': no such file"), proc.stderr


@pytest.fixture(scope="module")
def tls_cluster(tmp_path_factory):
    certs = make_certificates(tmp_path_factory.mktemp("certs"))
    c = ProcessCluster(tmp_path_factory.mktemp("dask-tls"), workers=2, tls=certs)
    try:
        yield c, certs
    finally:
        c.close()


SCENE, SETTINGS = (64, 64), dict(samples=16, tile_size=16, seed=9)


@pytest.mark.slow          # a TLS cluster of processes
def test_a_render_through_a_tls_scheduler_is_the_local_render(tls_cluster, monkeypatch):
    cluster, certs = tls_cluster
    assert cluster.address.startswith("tls://127.0.0.1:")
    monkeypatch.setenv(dask_tls.ENV["ca"], certs["ca"])
    monkeypatch.setenv(dask_tls.ENV["cert"], certs["cert"])
    monkeypatch.setenv(dask_tls.ENV["key"], certs["key"])
    local = render(cornell_scene(SCENE), RenderSettings(threads=1, **SETTINGS), **QUIET)
    on_tls = render(cornell_scene(SCENE), RenderSettings(**SETTINGS), pool=make_pool(f"dask:{cluster.address}", 2, **QUIET),
                    **QUIET)
    assert on_tls.stats["units_done"] == on_tls.stats["units"]
    assert np.array_equal(on_tls.image, local.image)


@pytest.mark.slow          # a TLS cluster and the command lines (the add-on's imports bpy)
@pytest.mark.parametrize("cli", ["engine", "mcrt_addon"])
def test_both_command_lines_render_through_a_tls_scheduler(cli, tls_cluster, tmp_path):
    cluster, certs = tls_cluster
    scene = ["--builtin", "cornell"] if cli == "engine" else [os.path.join(ROOT, "sample_blends", "cornell.blend")]
    common = [sys.executable, "-m", cli, "render", *scene, "--resolution", "32", "32", "--samples", "8",
              "--cluster", cluster.address]
    tls = ["--tls-ca-file", certs["ca"], "--tls-cert", certs["cert"], "--tls-key", certs["key"]]
    out = tmp_path / "tls.exr"
    proc = subprocess.run(common + tls + ["-o", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env=NO_TLS_ENV)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert read_image(str(out)).max() > 0
    refused = subprocess.run(common + ["-o", str(tmp_path / "no.exr")], cwd=ROOT, capture_output=True, text=True,
                             timeout=300, env=NO_TLS_ENV)
    assert refused.returncode == 2 and "Traceback" not in refused.stderr, refused.stderr[-3000:]
    lines = [line for line in refused.stderr.splitlines() if "error:" in line]
    assert len(lines) == 1 and "needs the certificate authority" in lines[0], refused.stderr[-3000:]


def test_the_tls_options_go_to_the_environment_of_the_render(tmp_path, monkeypatch):
    """engine/cli/cluster_args.py: both command lines' --tls-* options, checked and handed on."""
    from types import SimpleNamespace
    from engine.cli.cluster_args import use_tls_options
    from engine.core.errors import SceneError
    for name in dask_tls.ENV.values():
        monkeypatch.delenv(name, raising=False)
    pem = tmp_path / "a.pem"
    pem.write_text("not checked here\n")
    with pytest.raises(SceneError, match="are for a tls:// --cluster"):
        use_tls_options(SimpleNamespace(cluster=None, tls_ca_file=str(pem), tls_cert=None, tls_key=None))
    with pytest.raises(SceneError, match="--tls-cert '.*nope.pem': no such file"):
        use_tls_options(SimpleNamespace(cluster="tcp://h:1", tls_ca_file=None, tls_cert=str(tmp_path / "nope.pem"),
                                        tls_key=None))
    use_tls_options(SimpleNamespace(cluster="tcp://h:1", tls_ca_file=str(pem), tls_cert=str(pem), tls_key=None))
    assert os.environ[dask_tls.ENV["ca"]] == str(pem) and os.environ[dask_tls.ENV["cert"]] == str(pem)
    use_tls_options(SimpleNamespace(cluster=None, tls_ca_file=None, tls_cert=None, tls_key=None))   # nothing given
