# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-test
BENCH_STAMP := $(VENV)/.installed-bench

.PHONY: demo demo-real test lint bench fmus clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,bench]"
	touch $(BENCH_STAMP)

# the demo builds this machine's platform only; `make fmus` builds linux64, win64 and darwin64 in parallel
demo: $(STAMP)
	$(PY) -m uavfmu.cli demo

demo-real: $(STAMP)
	$(PY) -m uavfmu.cli demo --real

fmus: $(STAMP)
	$(PY) build_fmus.py --out dist

test: $(STAMP)
	$(PY) -m ruff check .
	$(VENV)/bin/lint-imports
	@$(PY) -m pytest -q; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests - the suite is missing" >&2; fi; \
	exit $$rc

lint: $(STAMP)
	$(PY) -m ruff check .
	$(VENV)/bin/lint-imports

bench: $(BENCH_STAMP)
	for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf dist build reports out .pytest_cache .ruff_cache *.egg-info
