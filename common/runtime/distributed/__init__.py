"""The Zenoh runtimes: lockstep coordinator, realtime driver, and the service process."""
