"""The live vehicle's autopilot, the program ``python -m sitl`` runs: PX4/ArduPilot-like modes,
arming and failsafes over a ``sitl.plant`` vehicle, its parameters, telemetry, the MAVLink server
with its peers, request budgets and event catalogue, the step guard, real-time pacing, and the
command line. Uses ``sitl.plant``, never ``sitl.lab``."""
