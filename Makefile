# onebit: `make demo` and `make test` set everything up from nothing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
BUILD := build

.PHONY: install demo test bench clean

install: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/rerun analytics disable >/dev/null 2>&1 || true
	touch $(STAMP)

demo: install
	$(BIN)/onebit simulate beams-lab $(BUILD)/demo/beams-lab --seed 7 --duration 180 --agents 2
	$(BIN)/onebit run $(BUILD)/demo/beams-lab --out $(BUILD)/demo/run
	$(BIN)/onebit report $(BUILD)/demo/run

test: install
	RERUN_ANALYTICS=0 $(BIN)/python -m pytest

bench: install
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	$(BIN)/python -m benchmarks

clean:
	rm -rf $(BUILD)
