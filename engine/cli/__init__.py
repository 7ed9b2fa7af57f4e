"""The tracer's command line (python -m engine): render, estimate, bench, study, worker; signals."""
