import os

import pytest
from hypothesis import settings

os.environ.setdefault("MPLBACKEND", "Agg")

# Every property test draws the same examples on every run, seeded from the test's name
# (hypothesis's derandomize), so that a run's verdict is the code's and not the draw's; loaded here,
# before any test module builds its settings, so that theirs inherit it. FUZZ_EXPLORE=1 (make fuzz)
# draws new examples each run and prints a failure's reproduce blob. (A run of the suite on
# 2026-12-05 drew, once, a mission whose reference left its volume: now in tests/fuzz/corpus.)
settings.register_profile("fixed", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("explore" if os.environ.get("FUZZ_EXPLORE") == "1" else "fixed")


def boots_ardupilot(nodeid: str) -> bool:
    """Whether a real-tier test boots ArduPilot (its name says ArduPilot or ArduCopter); the others
    boot PX4 (SIH, the MAVSDK examples, PX4 on the plant)."""
    low = nodeid.lower()
    return "ardupilot" in low or "arducopter" in low


def pytest_collection_modifyitems(config, items):
    """Mark every test that runs a real autopilot (the tier in tests/autopilots/ and the contract's
    "firmware" side) `firmware`, and those that boot ArduPilot `ardupilot` as well: `make test` runs
    PX4's, then ArduPilot's, several at a time where they hold (tests/run_tiers.sh; each test process
    boots its firmware on instances of its own, tests/helpers/firmware.py: two of one number would
    share ports and lock files)."""
    for item in items:
        callspec = getattr(item, "callspec", None)
        on_firmware = callspec is not None and "firmware" in callspec.params.values()
        if on_firmware or "tests/autopilots/" in item.nodeid:
            item.add_marker(pytest.mark.firmware)
        if item.get_closest_marker("firmware") is not None and boots_ardupilot(item.nodeid):
            item.add_marker(pytest.mark.ardupilot)
