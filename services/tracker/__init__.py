"""The onboard tracker service: the path controller on the vehicle's node (controller.placement)."""
