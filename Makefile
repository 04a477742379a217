# Two entry points (see README): `make demo` and `make test`. Both set up .venv first.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
OUT ?= results

.PHONY: setup demo experiments test lint bench fuzz mutations clean

# the runtime alone for the demo (pip install . : NumPy, Matplotlib, pymavlink); the test tools on top for make test
$(VENV)/.runtime: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed: $(VENV)/.runtime
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

setup: $(VENV)/.installed

demo: $(VENV)/.runtime
	$(PY) -m companion demo --out flights

experiments: setup
	$(PY) -m sitl.lab.experiments all --out $(OUT)

# everything but the real autopilots six at a time, then ArduPilot's three at a time beside PX4 on our
# plant and MAVSDK's examples one at a time, then PX4 SIH's tests one at a time, alone: tests/run_tiers.sh
# says why. Skipped with the reason where no build is found (docs/autopilots.md)
test: setup lint
	PY=$(PY) bash tests/run_tiers.sh

# the long fuzz run, new examples every run (CI runs the same tests with 150 fixed examples each,
# seeded from each test's name); FUZZ_EXAMPLES to change it; a failure prints its reproduce blob
FUZZ_EXAMPLES ?= 20000
fuzz: setup
	FUZZ_EXPLORE=1 FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) $(PY) -m pytest -q tests/fuzz --durations=0

# the named mutation list of the control core (tests/helpers/mutations.py); CI runs it as
# tests/test_mutations.py, this target also writes the score to docs/mutations.md
mutations: setup
	cd tests && PYTHONPATH=. $(abspath $(PY)) -m helpers.mutations --report ../docs/mutations.md

lint: setup
	$(VENV)/bin/ruff check companion sitl tests benchmarks
	$(VENV)/bin/mypy companion/control

bench: setup
	$(PY) benchmarks/bench_simulation.py
	$(PY) benchmarks/bench_sitl.py
	$(PY) benchmarks/bench_companion.py

clean:
	rm -rf $(VENV) $(OUT) flights .pytest_cache
