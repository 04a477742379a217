import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


def firmware_group(nodeid: str) -> str:
    """Which autopilot a real-tier test boots: "ardupilot" where its name says ArduPilot or ArduCopter,
    "px4" otherwise (PX4 SIH, the MAVSDK examples, PX4 on the plant)."""
    low = nodeid.lower()
    return "ardupilot" if "ardupilot" in low or "arducopter" in low else "px4"


@pytest.hookimpl(tryfirst=True)  # before xdist's own, which reads the groups
def pytest_collection_modifyitems(config, items):
    """Mark every test that runs a real autopilot (the tier in tests/autopilots/ and the contract's
    "firmware" side) `firmware`, in an xdist group per autopilot: `make test` runs the tier on two
    workers, PX4's tests one at a time on one and ArduPilot's on the other (their ports differ; two
    of one autopilot would share its ports and its lock files)."""
    for item in items:
        callspec = getattr(item, "callspec", None)
        on_firmware = callspec is not None and "firmware" in callspec.params.values()
        if on_firmware or "tests/autopilots/" in item.nodeid:
            item.add_marker(pytest.mark.firmware)
            item.add_marker(pytest.mark.xdist_group(firmware_group(item.nodeid)))
