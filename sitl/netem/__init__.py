"""Network emulation between a client and a vehicle: ``sitl.netem.relay`` impairs a MAVLink
link (loss, delay with jitter, duplication, reordering, outages). Knows nothing of the vehicle."""
