"""Who renders the work units: threads and forked processes, worker processes of another Python, a Dask cluster, viewport workers."""
