"""Restart policies of supervised services: never, on-failure or always, with doubling back-off."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal, cast

from common.config.errors import ConfigValueError

RestartMode = Literal["never", "on-failure", "always"]
MODES: tuple[RestartMode, ...] = ("never", "on-failure", "always")


@dataclass(frozen=True, kw_only=True)
class RestartPolicy:
    """Whether a service that exited is started again, how often, and after what delay.

    As ros2 launch's `respawn` and dora's restart policies: "never" fails the run, "on-failure"
    restarts a non-zero exit (or a death by signal), "always" restarts any exit. The delay
    before restart n (1-based) is backoff_s * 2**(n-1), capped at backoff_max_s.
    """

    mode: RestartMode = "never"
    max_restarts: int = 3
    backoff_s: float = 0.5
    backoff_max_s: float = 30.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: {self.mode!r}, expected one of {', '.join(MODES)}")
        if self.max_restarts < 0:
            raise ValueError(f"max_restarts: {self.max_restarts}, expected >= 0")
        if not 0.0 <= self.backoff_s <= self.backoff_max_s:
            raise ValueError(
                f"backoff_s: {self.backoff_s}, expected 0 <= backoff_s <= backoff_max_s "
                f"({self.backoff_max_s})"
            )

    def should_restart(self, exit_code: int, restarts_so_far: int) -> bool:
        """True if an exit with this code (negative: killed by a signal) is restarted."""
        if self.mode == "never" or restarts_so_far >= self.max_restarts:
            return False
        return self.mode == "always" or exit_code != 0

    def delay_s(self, restarts_so_far: int) -> float:
        """The back-off before the next restart: doubles with each restart already made."""
        return min(self.backoff_max_s, self.backoff_s * 2.0**restarts_so_far)

    def describe(self) -> str:
        if self.mode == "never":
            return "never"
        return f"{self.mode}, at most {self.max_restarts} restarts"


def parse_restart(text: str, default: RestartPolicy) -> tuple[str | None, RestartPolicy]:
    """Parse `[NAME=]MODE[:MAX]`: (the service it is for, or None for every service; policy).

    The back-off of `default` is kept; e.g. "filter=on-failure:5", "always", "never". A bad
    one is a ConfigValueError naming --restart (the CLI exits 2, as for a bad config).
    """
    name, sep, rest = text.rpartition("=")
    mode, _, count = rest.partition(":")
    if mode not in MODES:
        raise _bad(text, f"mode {mode!r}, expected one of {', '.join(MODES)}")
    try:
        max_restarts = int(count) if count else default.max_restarts
    except ValueError:
        raise _bad(text, f"{count!r} is not a number of restarts") from None
    if max_restarts < 0:
        raise _bad(text, f"{max_restarts} restarts, expected >= 0")
    if sep and not name:
        raise _bad(text, "expected NAME=MODE[:MAX]")
    policy = replace(default, mode=cast(RestartMode, mode), max_restarts=max_restarts)
    return (name or None), policy


def policies_for(
    names: tuple[str, ...],
    specs: list[str],
    default: RestartPolicy,
    *,
    named_only: tuple[str, ...] = (),
) -> dict[str, RestartPolicy]:
    """Each service's policy from repeated --restart options (later ones win); the processes
    `named_only` (the router) get one only from a NAME=... option, never from a bare MODE."""
    out = dict.fromkeys(names, default)
    for text in specs:
        name, policy = parse_restart(text, default)
        if name is None:
            out.update(dict.fromkeys(names, policy))
        elif name not in out and name not in named_only:
            known = ", ".join((*names, *named_only))
            raise _bad(text, f"unknown service {name!r}; this launch has {known}")
        else:
            out[name] = policy
    return out


def _bad(text: str, problem: str) -> ConfigValueError:
    """A --restart option that cannot be read: prints as `--restart: 'TEXT': problem`."""
    return ConfigValueError("--restart", f"{text!r}: {problem}")
