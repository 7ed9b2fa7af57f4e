"""The tracer's command line (python -m engine): render, estimate, bench, bench-cluster, study, worker; the settings arguments both command lines share; signals."""
