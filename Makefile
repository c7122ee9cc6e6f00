# Two entry points, each self-contained on a fresh machine:
#   make demo  -> create .venv, install, fly a shipped policy end to end (embedded SITL)
#   make test  -> create .venv, install with dev extras, run ruff and the test suite
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/uavlink fly --policy policies/circular.zip --scenario circular --seed 0
	$(BIN)/uavlink evaluate --scenario all --policy static --episodes 20 --seed 0
	$(BIN)/uavlink evaluate --scenario all --policy aoa --episodes 20 --seed 0

test: $(STAMP)
	$(BIN)/ruff check uavlink sitl_stub tests benchmarks
	$(BIN)/python -m pytest -q -n 2 -m "not px4_ports and not serial"
	$(BIN)/python -m pytest -q -m "px4_ports or serial"

lint: $(STAMP)
	$(BIN)/ruff check uavlink sitl_stub tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/env_throughput.py

clean:
	rm -rf $(VENV) build *.egg-info
