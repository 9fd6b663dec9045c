"""The launcher: a Zenoh router and every service as a supervised OS process (`tidelink launch`).

Import `launch` and `LaunchOptions` from services.launcher.launch: this package imports
nothing itself, so what a run leaves on disk (services.launcher.outputs, used by every
`tidelink run`) comes without the launcher's runtime, bus and supervisor (~50 ms of a
process's start).
"""
