"""TLS for a Dask cluster: the certificates a `tls://` scheduler address is reached with
(distributed.security.Security), from the command lines' --tls-ca-file / --tls-cert / --tls-key
(engine/cli/cluster_args.py), from the environment, or from Dask's own configuration.

An open scheduler port runs pickled code: anyone who reaches it runs any code on every worker
(docs/user-guide.md, "Render cluster").  TLS with a certificate authority of one's own makes the
scheduler and the workers accept only peers with a certificate that authority signed; beyond one's
own machine use it (or a private network).

Where the certificates come from, first found first:

1. TNCG15_TLS_CA_FILE, TNCG15_TLS_CERT, TNCG15_TLS_KEY (the command lines set them from their
   options, so the add-on's render inside `python -m mcrt_addon render` sees them too);
2. Dask's configuration: distributed.comm.tls.ca-file, .client.cert, .client.key (a YAML file in
   ~/.config/dask/, or DASK_DISTRIBUTED__COMM__TLS__CA_FILE, ...__CLIENT__CERT, ...__CLIENT__KEY).
"""
from __future__ import annotations

import os

from ..core.errors import SceneError

ENV = {"ca": "TNCG15_TLS_CA_FILE", "cert": "TNCG15_TLS_CERT", "key": "TNCG15_TLS_KEY"}
CONFIG = {"ca": "distributed.comm.tls.ca-file", "cert": "distributed.comm.tls.client.cert",
          "key": "distributed.comm.tls.client.key"}
OPTIONS = {"ca": "--tls-ca-file", "cert": "--tls-cert", "key": "--tls-key"}


class TLSError(SceneError):
    """A tls:// address without usable certificates (one line: both command lines print it)."""


def tls_files() -> dict:
    """{"ca", "cert", "key"}: the files found (environment first, then Dask's config), None where none."""
    found = {}
    for part in ENV:
        value = os.environ.get(ENV[part])
        if not value:
            try:
                import dask
                value = dask.config.get(CONFIG[part], None)
            except ImportError:
                value = None
        found[part] = value or None
    return found


def security_for(address: str):
    """The distributed Security to reach `address`: None for tcp://, a TLS one for tls:// (TLSError,
    one line naming what is missing, when the certificates are not given or not readable)."""
    if not address.startswith("tls://"):
        return None
    files = tls_files()
    missing = [OPTIONS[p] for p in ("ca", "cert") if not files[p]]
    if missing:
        raise TLSError(f"{address}: a tls:// scheduler needs the certificate authority and this machine's "
                       f"certificate: give {' and '.join(missing)} (and --tls-key unless the key is in the "
                       f"certificate's file), or set them in Dask's configuration (distributed.comm.tls)")
    for part, path in files.items():
        if path and not os.path.isfile(path):
            raise TLSError(f"{OPTIONS[part]} '{path}': no such file")
    from distributed.security import Security
    return Security(tls_ca_file=files["ca"], tls_client_cert=files["cert"], tls_client_key=files["key"],
                    require_encryption=True)


def use_files(ca=None, cert=None, key=None) -> None:
    """The command lines' options: set for this process and its children (TNCG15_TLS_*)."""
    for part, value in (("ca", ca), ("cert", cert), ("key", key)):
        if value:
            os.environ[ENV[part]] = os.path.abspath(value)


def process_options(ca: str, cert: str, key: str | None = None) -> list:
    """The `dask scheduler` / `dask worker` options for TLS with these files."""
    return ["--tls-ca-file", ca, "--tls-cert", cert] + (["--tls-key", key] if key else [])
