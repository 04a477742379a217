"""The simulated vehicle itself: rigid-body dynamics, airframe, wind, external disturbances,
sensors and their noise and faults, the onboard 1 kHz attitude loop, and the scenario that sets
them all. Imports nothing else of ``sitl``; ``sitl.autopilot`` and ``sitl.lab`` both build on it."""
