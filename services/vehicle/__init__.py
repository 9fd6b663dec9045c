"""The vehicle service: simulated AUV plant (eqs. 7, 11, 14) in the world's current; watchdog."""

from services.vehicle.core import VehicleCore

__all__ = ["VehicleCore"]
