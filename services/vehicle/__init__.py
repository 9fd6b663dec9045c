"""The vehicle service: simulated AUV plant (eqs. 7, 11, 14), ocean current and watchdog."""

from services.vehicle.core import VehicleCore

__all__ = ["VehicleCore"]
