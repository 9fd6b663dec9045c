"""Shared foundation: wire messages, bus, network model, runtimes, config."""
