"""The tracer's name and version: a worker or cluster of another version is refused."""
ENGINE_NAME = "TNCG15 MC"
ENGINE_VERSION = "0.2.0"          # workers of another version are refused (engine/pools/dask_cluster.py)
