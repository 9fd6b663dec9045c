"""Path following for the planner and the onboard tracker: controllers, command link, loop."""
