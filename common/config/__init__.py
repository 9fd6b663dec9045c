"""Scenario configuration: TOML parsed once, at the edge, into frozen dataclasses."""
