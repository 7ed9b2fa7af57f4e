"""What accuracy costs in time: the studies behind docs/accuracy-vs-time.md and docs/accuracy-stopping.md."""
