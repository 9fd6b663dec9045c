"""Work a core hands off and takes back at a later step: done at once in virtual time, beside
the loop on the wall clock.

A core stays pure: it starts the work and asks for its result through `Deferred`, never
touching a thread. In virtual time (inproc, lockstep) `AtOnce` does the work when it is
started, so its result is there in the same step and the run is what it was without it,
bit for bit. On the wall clock (realtime) `InThread` does it in a worker thread, so a step
that starts a long piece of work (a replan of seconds) does not hold up the steps after it:
they go on at their period meanwhile (the thread shares the interpreter's lock with them:
they slow down, they do not stop).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Generic, Protocol, TypeVar

T = TypeVar("T")


class Deferred(Protocol[T]):
    """One piece of work at a time, started by one step, its result taken by a later one."""

    @property
    def running(self) -> bool:
        """Whether work was started and its result not yet taken."""
        ...

    def start(self, work: Callable[[], T]) -> None:
        """Start `work` (none may be running)."""
        ...

    def result(self) -> T | None:
        """The finished work's result, once; None while it runs or when none was started. An
        exception the work raised is raised here."""
        ...


class _Outcome(Generic[T]):
    """The finished work's value or exception, until taken."""

    def __init__(self) -> None:
        self._done: tuple[T | None, BaseException | None] | None = None

    def _do(self, work: Callable[[], T]) -> None:
        """Do the work and keep its outcome (one reference assignment: seen whole by
        another thread)."""
        try:
            done: tuple[T | None, BaseException | None] = (work(), None)
        except Exception as exc:  # noqa: BLE001 - raised where the result is taken
            done = (None, exc)
        self._done = done

    @property
    def running(self) -> bool:
        """Whether work was started and its result not yet taken."""
        raise NotImplementedError

    def _refuse_if_running(self) -> None:
        """Deferred.start's rule: one piece of work at a time."""
        if self.running:
            raise RuntimeError("work is already running")

    def _take(self) -> T | None:
        done, self._done = self._done, None
        if done is None:
            return None
        value, exc = done
        if exc is not None:
            raise exc
        return value


class AtOnce(_Outcome[T]):
    """Virtual time: the work is done when started; its result is there at once."""

    @property
    def running(self) -> bool:
        return self._done is not None

    def start(self, work: Callable[[], T]) -> None:
        self._refuse_if_running()
        self._do(work)

    def result(self) -> T | None:
        return self._take()


class InThread(_Outcome[T]):
    """The wall clock: the work runs in a daemon thread of its own (one at a time)."""

    def __init__(self, name: str = "tidelink-deferred") -> None:
        super().__init__()
        self._name = name
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None

    def start(self, work: Callable[[], T]) -> None:
        self._refuse_if_running()
        self._done = None
        self._thread = threading.Thread(target=self._do, args=(work,), name=self._name, daemon=True)
        self._thread.start()

    def result(self) -> T | None:
        if self._thread is None or self._done is None:
            return None
        self._thread.join()
        self._thread = None
        return self._take()
