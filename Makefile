# Two entry points, each self-contained on a fresh machine:
#   make demo  -> create .venv, install, fly a shipped policy end to end (embedded SITL)
#   make test  -> create .venv, install with dev extras, run the linters, the test suite, the
#                 docs build and the wheel check
#   make docs  -> build the docs site into site/ (mkdocs build --strict)
#   make research-test -> the research scripts' tests (research/tests/), a lane of their own
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test research-test lint docs wheel-check results bench clean

# pip byte-compiles what it installs one file at a time (about a minute, mostly torch's); compileall
# does the same on every core. A file this Python cannot compile (torch ships a 3.12-only example)
# stays source, as pip leaves it.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet --no-compile -e '.[dev]'
	$(BIN)/python -m compileall -qq -j 0 $(VENV)/lib || true
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/uavlink fly --policy policies/circular.zip --scenario circular --seed 0
	$(BIN)/uavlink evaluate --scenario all --policy static --episodes 20 --seed 0
	$(BIN)/uavlink evaluate --scenario all --policy aoa --episodes 20 --seed 0

# The suite in three streams: two pytest-xdist workers run most tests; beside them a second pytest
# runs the tests on PX4's fixed ports one after another (xdist's loadgroup cannot keep them on one
# worker under pytest 9), then the `waits` tests, which mostly wait on a vehicle's clock (its report
# follows the workers'); then the `serial` flights run alone. (Long CPU-bound tests moved beside the
# workers made timed flight tests fail: 2 of 3 runs; the `waits` tests use a sixth of a core.)
test: lint
	@$(BIN)/python -m pytest -q -m "px4_ports or waits" > $(VENV)/beside.log 2>&1 & beside=$$!; \
	$(BIN)/python -m pytest -q -n 2 -m "not px4_ports and not waits and not serial" --durations=15; rest=$$?; \
	wait $$beside; beside_status=$$?; echo "--- tests on PX4's fixed ports and waiting tests (run beside the above):"; \
	cat $(VENV)/beside.log; [ $$rest -eq 0 ] && [ $$beside_status -eq 0 ]
	$(BIN)/python -m pytest -q -m serial
	$(MAKE) --no-print-directory docs
	$(MAKE) --no-print-directory wheel-check

# The research scripts' tests (the experiments behind the docs' figures, some training; about 70 s
# on 2 cores): not on make test's path (research/tests/ lies outside pytest's testpaths).
research-test: $(STAMP)
	$(BIN)/ruff check research
	$(BIN)/python -m pytest -q -n 2 -m research research/tests

# The docs site (mkdocs.yml): the CLI and config reference pages are generated at build time
# (docs/hooks/reference.py), the API pages by mkdocstrings; --strict fails on any broken link.
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir site

# ruff's lint and format check over every Python folder, and mypy over the package (its settings:
# pyproject.toml [tool.mypy]). .pre-commit-config.yaml runs the same before each commit.
LINTED := uavlink sitl_stub tests benchmarks research tools docs
lint: $(STAMP)
	$(BIN)/ruff check $(LINTED)
	$(BIN)/ruff format --check $(LINTED)
	$(BIN)/mypy

# What a user installs: the wheel with [fly] only, in a fresh venv outside the checkout, flying a
# shipped policy and a shipped fleet policy from another folder (.ci/wheel-check).
wheel-check: $(STAMP)
	PYTHON=$(BIN)/python bash .ci/wheel-check

# docs/results.md and docs/results/, every section, from the shipped policies and the sweep records
# beside them (policies/*.sweep.json: a fresh clone needs no runs/): 41 to 75 minutes on 2 cores, the
# fleet part at D = 1 to 4 included, most of it its genie at D = 3 and 4 (2026-12-06: 74 min 42 s
# idle in one session, 41 min 8 s in another: the machines differ).
# The fleet part pairs the any-size policies (--fleet) with the per-size D = 2 ones (--fleet-per-size,
# beside which a per-size sweep's record, sweeps/fleet.toml's, is read).
results: $(STAMP)
	$(BIN)/uavlink evaluate --scenario all --policy policies/ --episodes 100 --seed 0 \
		--out docs/results --markdown docs/results.md --sweep sweeps/table1.toml \
		--sweep sweeps/table1_spatial.toml --sweep sweeps/fleet.toml --spatial policies/spatial \
		--fleet policies/fleet --fleet-per-size policies/fleet_d2 --map policies/map \
		--sweep sweeps/map.toml --workers 2

bench: $(STAMP)
	$(BIN)/python benchmarks/env_throughput.py

clean:
	rm -rf $(VENV) build site *.egg-info
