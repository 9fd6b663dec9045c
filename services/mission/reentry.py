"""Returns to a path: how often a track that left a band around the path came back into it.

The paper's fuzzy-PID comparison counts returns to the best path, not actions on it. A
return needs hysteresis, or a track grazing the band's edge would count one return per
sample: the track *leaves* when its distance to the path exceeds the band's half-width
`tol_m`, and *returns* only when it is again within `tol_m / 2`. A track that starts outside
the band and joins it later has arrived, not returned: that first entry does not count.
"""

from __future__ import annotations

import numpy as np


def reentries(dist_m: np.ndarray, tol_m: float) -> int:
    """Returns into the band |d| <= tol_m of a track with distances dist_m: (n,) to the path,
    by the hysteresis of the module docstring."""
    if not (np.isfinite(tol_m) and tol_m > 0.0):
        raise ValueError(f"tol_m: {tol_m!r} is invalid, expected a finite value > 0")
    d = np.asarray(dist_m, dtype=np.float64)
    if len(d) == 0:
        return 0
    # the state changes only where the track leaves (d > tol) or is back (d <= tol / 2);
    # in between it keeps the state it had. Outside: True. It starts inside unless d > tol.
    out, back = d > tol_m, d <= tol_m / 2.0
    outside = np.concatenate(([out[0]], out[np.flatnonzero(out | back)]))
    returns = int(np.count_nonzero(outside[:-1] & ~outside[1:]))
    # a track that started outside arrived the first time it came in: no return
    return returns - int(bool(out[0]) and returns > 0)
