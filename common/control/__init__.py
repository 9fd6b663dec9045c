"""What both ends of the command link share: a command's schedule and the delay meter."""

from common.control.delay import DelayMeter
from common.control.schedule import Applied, Schedule

__all__ = ["Applied", "DelayMeter", "Schedule"]
