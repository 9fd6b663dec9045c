"""The one-way delay a receiver observes on a stream: a running median and a robust jitter.

The vehicle measures it on commands (and reports it in its status); the planner on its
estimate input (so that staleness is age beyond the delay it knows). Each sample is
d = t_delivered - stamp (mission time). Over the last `window` samples:
- delay  = median(d)
- jitter = 1.4826 * median(|d - delay|)   (MAD; 1.4826 makes it the standard deviation of
  normal jitter, the consistency constant 1 / Phi^-1(3/4))
Both are order statistics, so a single outlier in a window of n >= 3 samples moves either by
at most one rank, where it would drag a mean by (outlier - mean) / n; a constant delay gives
that delay and zero jitter from the first sample on. Before any sample both are 0.

One sample per message: a copy (the stamp of one of the last `window` samples again: a network
duplicate, or a flood of forged copies of one frame) says nothing new about the link, and a
flood of copies of an old frame would otherwise fill the window with its age, and the planner
would predict that far ahead (docs/notes/0013-delay-meter-counts-copies-once.md).
"""

from __future__ import annotations

from collections import deque
from statistics import median

MAD_TO_SIGMA = 1.4826


class DelayMeter:
    """Median and MAD jitter of the last `window` delay samples (s); pure, no clock."""

    def __init__(self, window: int) -> None:
        if window < 1:
            raise ValueError(f"window: {window!r} samples, expected >= 1")
        self._window: deque[float] = deque(maxlen=window)
        self._stamps: deque[float] = deque(maxlen=window)  # the stamps of the samples in it
        self.count = 0  # samples ever added
        self.copies = 0  # samples refused as copies of one already in the window
        self.delay_s = 0.0
        self.jitter_s = 0.0

    def add(self, delay_s: float, stamp: float | None = None) -> bool:
        """Add one sample (s; negative when a stamp is ahead of the vehicle's clock) of the
        message stamped `stamp`; False (not added) when a sample of that stamp is in the
        window already."""
        if stamp is not None:
            if stamp in self._stamps:
                self.copies += 1
                return False
            self._stamps.append(stamp)
        self._window.append(delay_s)
        self.count += 1
        m = median(self._window)
        self.delay_s = m
        self.jitter_s = MAD_TO_SIGMA * median(abs(d - m) for d in self._window)
        return True
