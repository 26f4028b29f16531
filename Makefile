# pbd: set-up, demo, tests and benchmarks. Every target creates .venv/ at the repo root first.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow test-all lint typecheck bench sysdeps clean

$(STAMP): pyproject.toml
	@command -v $(PY) >/dev/null 2>&1 || { echo "need $(PY) on PATH" >&2; exit 1; }
	$(MAKE) sysdeps
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip uninstall --quiet --yes open3d 2>/dev/null || true  # replaced by open3d-cpu (same module)
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# open3d-cpu needs libusb-1.0 from the system; install it where missing (Debian, as root).
sysdeps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
		echo "installing libusb-1.0-0 (needed by open3d-cpu)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libusb-1.0-0 >/dev/null; \
	fi

demo: $(STAMP)
	$(BIN)/pbd demo

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(STAMP)
	$(BIN)/mypy

# Tests run in $(WORKERS) processes (pytest-xdist; WORKERS=0: in pytest's own), a module's tests in one of them.
WORKERS ?= 2
PYTEST := $(BIN)/pytest -q -n $(WORKERS) --dist loadscope

# The fast set: every test but those marked slow (whole-benchmark plans, long simulations, full flow runs).
test: lint typecheck
	$(PYTEST) -m "not slow"

# The slow set alone (CI runs it after `make test`); the real Prefect server's tests last, in one process, so that
# `pbd serve` registers its deployments within their deadline.
test-slow: $(STAMP)
	$(PYTEST) -m "slow and not server"
	$(BIN)/pytest -q -m "slow and server"

# Everything: lint, types, the fast and the slow tests.
test-all: lint typecheck
	$(PYTEST) -m "not server"
	$(BIN)/pytest -q -m server

bench: $(STAMP)
	@for b in bench/*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) .mypy_cache .ruff_cache .pytest_cache
