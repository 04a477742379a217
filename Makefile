# Two entry points (see README): `make demo` and `make test`. Both set up .venv first.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
OUT ?= results

.PHONY: setup demo experiments test bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

setup: $(VENV)/.installed

demo: experiments

experiments: setup
	$(PY) -m sitl.experiments all --out $(OUT)

test: setup
	$(PY) -m pytest -q

bench: setup
	$(PY) benchmarks/bench_simulation.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
