"""The TLS options of both command lines' --cluster (python -m engine render, python -m mcrt_addon
render): --tls-ca-file, --tls-cert, --tls-key, the PEM files of engine/pools/dask_tls.py."""
from __future__ import annotations

import os

from ..core.errors import SceneError

HELP = {
    "--tls-ca-file": "for a tls:// --cluster: the certificate authority (PEM) the scheduler's certificate is signed by",
    "--tls-cert": "for a tls:// --cluster: this machine's certificate (PEM), signed by that authority",
    "--tls-key": "for a tls:// --cluster: the private key of --tls-cert (PEM; not needed if it is in the same file)",
}


def add_tls_options(parser) -> None:
    for flag, text in HELP.items():
        parser.add_argument(flag, metavar="PEM", help=text)


def use_tls_options(args) -> None:
    """Check the files (one line naming a missing one: SceneError) and hand them to the cluster's
    client (engine/pools/dask_tls.py use_files); a tls:// --cluster without them is one line too,
    before anything is read or rendered."""
    given = {"ca": args.tls_ca_file, "cert": args.tls_cert, "key": args.tls_key}
    for (part, path), flag in zip(given.items(), HELP):
        if path and not os.path.isfile(path):
            raise SceneError(f"{flag} '{path}': no such file")
    if any(given.values()):
        if not getattr(args, "cluster", None):
            raise SceneError("--tls-ca-file/--tls-cert/--tls-key are for a tls:// --cluster")
        from ..pools.dask_tls import use_files
        use_files(**given)
    if str(getattr(args, "cluster", None) or "").startswith("tls://"):
        from ..pools.dask_tls import security_for
        security_for(args.cluster)
