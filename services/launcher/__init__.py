"""The launcher: a Zenoh router and every service as a supervised OS process (`tidelink launch`)."""

from services.launcher.launch import LaunchOptions, LaunchOutcome, launch
from services.launcher.policy import RestartPolicy, parse_restart, policies_for
from services.launcher.supervise import Supervisor

__all__ = [
    "LaunchOptions",
    "LaunchOutcome",
    "RestartPolicy",
    "Supervisor",
    "launch",
    "parse_restart",
    "policies_for",
]
