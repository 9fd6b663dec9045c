"""Input defence every service shares: plausibility judgements and flood-proof warnings."""

from common.guard.plausibility import MAX_ITEMS, Plausibility, Reason, first_reason
from common.guard.ratelog import RateLimitedLog

__all__ = ["MAX_ITEMS", "Plausibility", "RateLimitedLog", "Reason", "first_reason"]
