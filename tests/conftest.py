import os

os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_collection_modifyitems(config, items):
    """Mark every test that runs a real autopilot (the tier in tests/autopilots/ and the contract's
    "firmware" side) `firmware`: `make test` runs those one at a time, the rest two at a time."""
    import pytest

    for item in items:
        callspec = getattr(item, "callspec", None)
        on_firmware = callspec is not None and "firmware" in callspec.params.values()
        if on_firmware or "tests/autopilots/" in item.nodeid:
            item.add_marker(pytest.mark.firmware)
