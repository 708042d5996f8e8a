# onebit: `make demo` and `make test` set everything up from nothing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
RAY_STAMP := $(VENV)/.ray-installed
WARM_STAMP := $(VENV)/.kernels-warm
SOURCES := $(shell find onebit -name '*.py' 2>/dev/null)
BUILD := build

.PHONY: install demo test browser-test bench clean

install: $(STAMP) $(WARM_STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/python -m pip install --quiet --no-deps 'trackeval>=1.3,<2'
	$(BIN)/rerun analytics disable >/dev/null 2>&1 || true
	touch $(STAMP)

# compile the numba kernels (cached) before a run or the tests need them, again whenever a source changes: a
# kernel edited since the last install would otherwise compile inside the first test or run that calls it.
$(WARM_STAMP): $(STAMP) $(SOURCES)
	$(BIN)/python -m benchmarks.warm_kernels
	touch $(WARM_STAMP)

# demo: one simulated dataset per paper; each run writes OUT/rrd/*.rrd, OUT/report.csv and prints one summary table
# (the skipped stages one line per reason); `onebit report OUT` prints the whole report.
demo: install
	@$(BIN)/onebit simulate beams-lab $(BUILD)/demo/beams-lab --seed 7 --duration 180 --agents 2
	@$(BIN)/onebit run $(BUILD)/demo/beams-lab --out $(BUILD)/demo/run
	@$(BIN)/onebit simulate pir14 $(BUILD)/demo/pir14 --seed 7 --param refractory=4
	@$(BIN)/onebit run $(BUILD)/demo/pir14 --out $(BUILD)/demo/pir14-run
	@$(BIN)/onebit simulate proximity-line $(BUILD)/demo/proximity-line --seed 7
	@$(BIN)/onebit run $(BUILD)/demo/proximity-line --out $(BUILD)/demo/proximity-line-run
	@$(BIN)/onebit simulate hallway $(BUILD)/demo/hallway --seed 7 --users 3 --duration 150
	@$(BIN)/onebit run $(BUILD)/demo/hallway --out $(BUILD)/demo/hallway-run
	@$(BIN)/onebit simulate istate-room $(BUILD)/demo/istate-room --seed 7
	@$(BIN)/onebit run $(BUILD)/demo/istate-room --out $(BUILD)/demo/istate-room-run

# the ray extra (onebit run-many / experiment --executor ray); the executor tests use it.
$(RAY_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,ray]'
	touch $(RAY_STAMP)

# test: lint and format (ruff), the layers contract (import-linter, pyproject.toml), the size limits
# of functions and modules (tools/sizes.py), the docs site (mkdocs.yml, strict: a broken link or
# anchor fails) and the test suite on both cores (pytest-xdist; a test file stays on one worker, so
# module fixtures are built once).
test: install $(RAY_STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports --no-cache
	$(BIN)/python tools/sizes.py
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir $(BUILD)/site
	RERUN_ANALYTICS=0 $(BIN)/python -m pytest -n 2 --dist loadfile -m "not browser"

# browser-test: headless Chromium (Debian's, software GL) opens the page of `onebit follow --serve-web`
# and checks the stream reached it and is drawn (tests/viz/test_live_browser.py, docs/live.md). Not in
# `test`: it takes about a minute (the viewer's wasm started on a software renderer).
CHROMIUM := /usr/bin/chromium
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
browser-test: install
	test -x $(CHROMIUM) || ($(SUDO) apt-get update && $(SUDO) apt-get install -y chromium)
	RERUN_ANALYTICS=0 $(BIN)/python -m pytest -m browser tests/viz/test_live_browser.py

bench: install
	$(BIN)/python -m pip install --quiet -e '.[test,bench,ray]'
	$(BIN)/python -m benchmarks

clean:
	rm -rf $(BUILD)
