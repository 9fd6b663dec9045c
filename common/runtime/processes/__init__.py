"""OS process management: fork server, child processes, supervision, signals."""
