"""The columns of `tidelink reproduce`'s comparison: a network (perfect or lossy) and whether
the controllers compensate its delay, plus the ablation of the eq. (2)-(3) prefilter."""

from __future__ import annotations

from dataclasses import dataclass

from services.experiments.reproduction.tuning import PERFECT_NETWORK
from services.experiments.sweep.schema import SetValue


@dataclass(frozen=True, kw_only=True)
class Case:
    """One column of the comparison: a network, and delay compensation for all or for none."""

    label: str
    network: str  # "perfect" | "lossy"
    compensation: bool
    prefilter: bool = True  # eq. (2)-(3) on (the ablation switches them off)

    def overrides(self) -> dict[str, SetValue]:
        out: dict[str, SetValue] = {"controller.delay_compensation": self.compensation}
        if self.network == "perfect":
            out.update(PERFECT_NETWORK)
        if not self.prefilter:
            out["estimator.prefilter"] = "none"
        return out


CASES = (
    Case(label="perfect", network="perfect", compensation=True),
    Case(label="perfect-uncompensated", network="perfect", compensation=False),
    Case(label="lossy", network="lossy", compensation=True),
    Case(label="lossy-uncompensated", network="lossy", compensation=False),
    # the ablation of eqs. (2)-(3): where they matter, with a noisy, lossy network
    Case(label="lossy-no-prefilter", network="lossy", compensation=True, prefilter=False),
)
