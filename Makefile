# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
# test processes (pytest-xdist): one per core; the wall-clock pacing tests (marker `realtime`) then run alone
TEST_WORKERS ?= auto
STAMP  := $(VENV)/.installed-test
BENCH_STAMP := $(VENV)/.installed-bench
MUT_STAMP := $(VENV)/.installed-mutation

.PHONY: demo demo-real test lint bench fmus clean mutation docs docs-check libtbb

# uv (from PyPI) installs what pip would, faster (parallel downloads); pip does the install where uv cannot be
# installed or cannot install (no wheel for this machine). No bytecode is compiled at install: every target runs
# Python without PYTHONDONTWRITEBYTECODE (CI images often set it; `unexport` below), so each module a run imports is
# compiled once, on its first import, and cached for every later process; compiling the whole environment (1.3 GB)
# took about 22 s of every fresh `make test`, mostly for modules no run imports. Without the cache every test worker,
# Dask worker and subprocess would compile what it imports again; pytest also caches its assertion-rewritten test
# modules only where bytecode may be written.
unexport PYTHONDONTWRITEBYTECODE
# a comma inside $(call ...) would split its argument: extras lists name it
comma := ,
INSTALL = { $(PY) -m pip install --quiet uv && $(PY) -m uv pip install --quiet --python $(PY) $(1); } \
	|| { $(PY) -m pip install --quiet --upgrade pip && $(PY) -m pip install --quiet $(1); }

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(call INSTALL,-e ".[test]")
	touch $(STAMP)

# Ecos (ecospy, a test extra) loads Debian's libtbb12: installed when missing; where that cannot be done (not root,
# not Debian, no registry) the Ecos tests skip and say so, the rest of `make test` is unaffected
libtbb:
	@if ! dpkg -s libtbb12 >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing Debian's libtbb12 (Ecos's library needs it)"; \
	    (apt-get install -y -qq libtbb12 || (apt-get update -qq && apt-get install -y -qq libtbb12)) >/dev/null 2>&1 \
	      || echo "libtbb12 could not be installed: the Ecos tests will skip" >&2; \
	  else echo "libtbb12 missing and apt-get unavailable here: the Ecos tests will skip" >&2; fi; \
	fi

$(BENCH_STAMP): $(STAMP)
	$(call INSTALL,-e ".[test$(comma)bench]")
	touch $(BENCH_STAMP)

$(MUT_STAMP): $(STAMP)
	$(call INSTALL,-e ".[test$(comma)mutation]")
	touch $(MUT_STAMP)

# the demo builds this machine's platform only; `make fmus` builds linux64, win64 and darwin64 in parallel
demo: $(STAMP)
	$(PY) -m uavfmu.cli demo

demo-real: $(STAMP)
	$(PY) -m uavfmu.cli demo --real

fmus: $(STAMP)
	$(PY) build_fmus.py --out dist

# our sources' bytecode is written once before the suite, in parallel, rather than by both test workers at once
PYTEST := $(PY) -m pytest
# the wall-clock pacing tests (marker `realtime`) all live here (tests/conftest.py refuses one elsewhere, which the
# parallel run would leave out): the second run collects this folder only
REALTIME_TESTS := tests/hil_adapter
test: $(STAMP) libtbb
	$(PY) -m ruff check .
	$(VENV)/bin/lint-imports
	$(PY) -m compileall -q -j 0 fmu_models identification hil_adapter uavfmu bench tests build_fmus.py > /dev/null
	@$(PYTEST) -q -n $(TEST_WORKERS) -m "not realtime"; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests - the suite is missing" >&2; fi; \
	$(PYTEST) -q -m realtime $(REALTIME_TESTS); rt=$$?; \
	if [ $$rt -eq 5 ]; then echo "make test: no wall-clock pacing tests collected" >&2; fi; \
	if [ $$rc -ne 0 ]; then exit $$rc; fi; exit $$rt

lint: $(STAMP)
	$(PY) -m ruff check .
	$(VENV)/bin/lint-imports

# every benchmark script runs (a module without a main, such as replica_verdict.py, is a shared helper), each miss is
# named at the end, and the target fails when any one missed: stopping at the first miss hid every later figure
bench: $(BENCH_STAMP)
	@failed=""; for b in bench/*.py; do \
	  grep -q '__name__ == "__main__"' $$b || continue; \
	  echo "== $$b"; $(PY) $$b || failed="$$failed $$b"; \
	done; \
	if [ -n "$$failed" ]; then echo "make bench: missed or failed:$$failed" >&2; exit 1; fi; echo "make bench: every benchmark met"

# mutation testing of the modules whose mistakes cost users most, each against its tests (tests/mutation_run.py);
# not in CI: about an hour on 2 shared cores. Per-module scores and surviving mutants: reports/mutation.md (exit 1 below 80 %).
mutation: $(MUT_STAMP)
	$(PY) tests/mutation_run.py
	$(PY) tests/mutation_report.py --out reports/mutation.md

# reference pages of the config files, from the schemas
docs: $(STAMP)
	$(PY) -m uavfmu.docs_gen

# every command in README.md and docs/ marked runnable (after the demo, whose output they use)
docs-check: $(STAMP)
	$(PY) -m uavfmu.docs_gen --check
	$(PY) -m uavfmu.cli demo --out dist > /dev/null || { echo "make docs-check: make demo fails" >&2; exit 1; }
	$(PY) -m uavfmu.docs_check

clean:
	rm -rf dist build reports out mutants .mutation .pytest_cache .ruff_cache *.egg-info
