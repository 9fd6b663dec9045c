"""Record a run to MCAP, read a recording back, replay it, and recompute its metrics."""
