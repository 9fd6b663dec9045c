"""`tidelink reproduce`: She & Tian's section-4 comparison, run on the sweep engine.

cases (the comparison's columns) and tuning (a fair gain search) set up the sweeps;
reproduce runs them; claims judges the paper's claims on the cells; report writes REPORT.md
from small builders over the fixed wording (wording.py); figures draws the paper's figures 2
to 6.
"""

# what other packages (the CLI) may import, by module
INTERFACE: dict[str, tuple[str, ...]] = {
    "reproduce": ("CROSSING", "ReproduceOptions", "reproduce"),
}
