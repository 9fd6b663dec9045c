"""The launcher: a Zenoh router and every service as a supervised OS process (`tidelink launch`)."""

from services.launcher.launch import LaunchOptions, LaunchOutcome, launch

__all__ = ["LaunchOptions", "LaunchOutcome", "launch"]
