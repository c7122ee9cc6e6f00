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

# The suite in three streams: two pytest-xdist workers run most tests; beside them a second pytest
# runs the tests on PX4's fixed ports one after another (its report follows the workers'; xdist's
# loadgroup cannot keep them on one worker under pytest 9); then the `serial` flights run alone.
# (Long CPU-bound tests moved beside the workers as well made timed flight tests fail: 2 of 3 runs.)
test: $(STAMP)
	$(BIN)/ruff check uavlink sitl_stub tests benchmarks
	@$(BIN)/python -m pytest -q -m px4_ports > $(VENV)/px4_ports.log 2>&1 & px4=$$!; \
	$(BIN)/python -m pytest -q -n 2 -m "not px4_ports and not serial"; rest=$$?; \
	wait $$px4; px4_status=$$?; echo "--- tests on PX4's fixed ports (run beside the above):"; \
	cat $(VENV)/px4_ports.log; [ $$rest -eq 0 ] && [ $$px4_status -eq 0 ]
	$(BIN)/python -m pytest -q -m serial

lint: $(STAMP)
	$(BIN)/ruff check uavlink sitl_stub tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/env_throughput.py

clean:
	rm -rf $(VENV) build *.egg-info
