"""The sensor service: navigation fixes and obstacle detections sampled from the truth."""

from services.sensor.core import SensorCore

__all__ = ["SensorCore"]
