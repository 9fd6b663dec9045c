"""How the reports name the three controllers, in the order their tables list them."""

from __future__ import annotations

CONTROLLER_NAMES = {
    "nurbs": "NURBS method",
    "backstepping": "Backstepping",
    "fuzzy_pid": "immune fuzzy PID",
}
