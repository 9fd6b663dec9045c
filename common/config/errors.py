"""Config error types that carry the key path as data: ConfigValueError below a field, ConfigError.

A key path is a tuple of table keys and array indices, e.g. ``("world", "polygons", 2,
"vertices_m")``, printed as ``world.polygons[2].vertices_m``. A config dataclass raises
ConfigValueError naming its own field (and any index below it); the loader prefixes the path of
the table it was building and raises ConfigError, which also names the file. Nothing has to
re-parse a message to learn where an error is.
"""

from __future__ import annotations

KeyPath = tuple[str | int, ...]


def format_key(path: KeyPath) -> str:
    """``("network", "links", 0, "loss_p")`` -> ``"network.links[0].loss_p"``."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else part
    return out


class ConfigValueError(ValueError):
    """A config dataclass rejects a value: the offending field (a name or a path) and the problem.

    It prints as ``"field: problem"``; it is a ValueError, so code that builds config
    dataclasses directly and catches ValueError keeps working.
    """

    def __init__(self, field: str | KeyPath, problem: str) -> None:
        self.key_path: KeyPath = (field,) if isinstance(field, str) else field
        self.problem = problem
        super().__init__(f"{format_key(self.key_path)}: {problem}")

    def __reduce__(self) -> tuple[type[ConfigValueError], tuple[KeyPath, str]]:
        # rebuilt from its fields, not its message, when it crosses a process (a sweep's pool)
        return (type(self), (self.key_path, self.problem))


class ConfigError(ValueError):
    """A scenario or experiment file is wrong: names the file, the key path and the expectation.

    ``key`` may be given as a path tuple or as text (kept as one element, printed as given).
    Prints as ``"file: key.path: problem"``, leaving out an empty file or key.
    """

    def __init__(self, file: str, key: str | KeyPath, problem: str) -> None:
        self.file = file
        self.key_path: KeyPath = ((key,) if key else ()) if isinstance(key, str) else key
        self.problem = problem
        where = f"{file}: " if file else ""
        super().__init__(f"{where}{self.key + ': ' if self.key_path else ''}{problem}")

    def __reduce__(self) -> tuple[type[ConfigError], tuple[str, KeyPath, str]]:
        # rebuilt from its fields, not its message, when it crosses a process (a sweep's pool)
        return (type(self), (self.file, self.key_path, self.problem))

    @property
    def key(self) -> str:
        """The key path as printed, e.g. ``"world.polygons[2].vertices_m"``."""
        return format_key(self.key_path)
