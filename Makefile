# The two commands a new user needs: `make demo` and `make test`.
# Both create and reuse .venv and install the pinned dependencies (constraints.txt is the lock).
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo demo-stages test test-isa test-slow lint bench cluster clean-venv

NODE_STAMP := node_modules/.installed
LLVM_STAMP := $(VENV)/.llvm

$(STAMP): pyproject.toml setup.py constraints.txt src/probeplace/geometry/_packet_loop.c
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade "pip==26.3"
	$(PY) -m pip install -q -c constraints.txt -e '.[dev]'
	$(PY) -m pip install -q --no-deps -c constraints.txt hydra-ray-launcher==1.2.2
	@touch $(STAMP)

# Test tools outside PyPI. The Khronos glTF-Validator (npm, pinned by package-lock.json) checks exported
# glTF files; Debian's libllvm19 lets Mitsuba 3 use its fast llvm_ad_rgb variant for the path-tracer
# cross-check. Neither is needed to run probeplace: without them the tests that use them say why they
# skip (validator) or fall back to Mitsuba's scalar_rgb variant.
$(NODE_STAMP): package.json package-lock.json
	@if command -v npm >/dev/null; then \
	  (npm ci --silent --no-audit --no-fund && touch $(NODE_STAMP)) || echo "make: npm ci failed - glTF validation tests will be skipped"; \
	else echo "make: npm not found - glTF validation tests will be skipped"; fi

$(LLVM_STAMP): $(STAMP)
	@if ldconfig -p 2>/dev/null | grep -q 'libLLVM.so.19\|libLLVM-19'; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  (apt-get install -y -qq libllvm19 >/dev/null 2>&1 || (apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq libllvm19 >/dev/null 2>&1)) \
	  || echo "make: could not install libllvm19 - Mitsuba checks use scalar_rgb"; \
	else echo "make: libllvm19 missing (apt-get install libllvm19) - Mitsuba checks use scalar_rgb"; fi
	@touch $(LLVM_STAMP)

# Debian's chromium: the browser tests (report.html, `probeplace view`) open pages in it headless, driven by
# Playwright (dev extra) with the system browser, never Playwright's own download. Without it those tests
# skip and say why.
CHROMIUM_STAMP := $(VENV)/.chromium
$(CHROMIUM_STAMP): $(STAMP)
	@if command -v chromium >/dev/null || command -v chromium-browser >/dev/null; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  (apt-get install -y -qq chromium >/dev/null 2>&1 || (apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq chromium >/dev/null 2>&1)) \
	  || echo "make: could not install chromium - browser tests will be skipped"; \
	else echo "make: chromium missing (apt-get install chromium) - browser tests will be skipped"; fi
	@touch $(CHROMIUM_STAMP)

TOOLS := $(STAMP) $(NODE_STAMP) $(LLVM_STAMP) $(CHROMIUM_STAMP)

# `make demo`: the cornell_comparison preset (the placement methods on the Cornell box at the grid's count,
# 3 seeds, baked and evaluated; configs/experiment/cornell_comparison.yaml), cornell_own_counts (each
# method at its own automatic count, seed 0), then their report: results/cornell_comparison/report/report.md.
# Finished runs are kept: a re-run only redoes what is missing.
demo: $(STAMP) $(LLVM_STAMP)
	@$(PY) experiments/run.py +experiment=cornell_comparison; rc=$$?; \
	$(PY) experiments/run.py +experiment=cornell_own_counts || rc=1; \
	$(PY) experiments/report.py results/cornell_comparison || exit 1; exit $$rc

# The stage-by-stage tour of the pipeline (G-buffer, SDF slice, reference, placement, bake, export).
demo-stages: $(STAMP)
	$(PY) -m probeplace demo --config configs/demo.yaml

# pytest exits 5 when it collected no test: that is neither a pass nor a fail we accept.
# Test files run in parallel (pytest-xdist: one worker per core, at most 4 — each holds its own JAX
# compile caches; --dist loadfile keeps a file's module fixtures in one worker). Most of the suite's time
# is XLA compilation, which is single-threaded: two workers on CI's two cores nearly halve it.
# --no-loadscope-reorder: files go out in collection order, which tests/conftest.py starts with the
# heaviest (xdist's default order, most tests first, left the heaviest files to run alone at the end).
PYTEST_PAR := -n auto --maxprocesses=4 --dist loadfile --no-loadscope-reorder
test: $(TOOLS)
	@$(PY) -m pytest -q $(PYTEST_PAR); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests - treating as an error"; exit 1; fi; \
	if [ $$rc -ne 0 ]; then exit $$rc; fi
	@$(MAKE) --no-print-directory test-isa

# The portability check, part of `make test`: the float-sensitive tests (marker `isa`: two float code
# paths compared, or a tolerance that rounding could break) again with XLA:CPU capped at older
# instruction sets. XLA compiles differently for SSE4.2, AVX2 and AVX-512 (FMA contraction, vector width,
# reduction order), and CI and every user run on whatever CPU they get; the default run above covers
# this machine's own set. The flag names x86 instruction sets, so other CPUs skip it and say so.
ISA_CAPS := SSE4_2 AVX2
test-isa: $(TOOLS)
	@if [ "$$(uname -m)" != x86_64 ]; then echo "make test-isa: $$(uname -m) is not x86-64 - the --xla_cpu_max_isa caps do not apply; skipped"; exit 0; fi; \
	for cap in $(ISA_CAPS); do \
	  echo "make test-isa: float-sensitive tests with XLA:CPU capped at $$cap"; \
	  XLA_FLAGS="$$XLA_FLAGS --xla_cpu_max_isa=$$cap" $(PY) -m pytest -q -m "isa and not slow" $(PYTEST_PAR); rc=$$?; \
	  if [ $$rc -eq 5 ]; then echo "make test-isa: no test is marked isa - treating as an error"; exit 1; fi; \
	  if [ $$rc -ne 0 ]; then exit $$rc; fi; \
	done

test-slow: $(TOOLS)
	$(PY) -m pytest -q -m slow $(PYTEST_PAR)

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks experiments
	$(VENV)/bin/ruff format --check src tests benchmarks experiments

bench: $(TOOLS)
	for b in benchmarks/[a-z]*.py; do $(PY) $$b || exit 1; done

# The test set-up ($(STAMP)) installs Ray's core (dev extra) and hydra-ray-launcher without its boto3
# requirement (AWS autoscaling only; it cannot be resolved next to python-dateutil 4): enough for the Ray
# sweep test on a local instance. Sweeps on a Ray cluster (hydra/launcher=ray) also want ray[default]
# (dashboard, autoscaler) and the launcher's other requirements:
cluster: $(STAMP)
	$(PY) -m pip install -q -c constraints.txt -e '.[dev,cluster]'
	$(PY) -m pip install -q --no-deps -c constraints.txt hydra-ray-launcher==1.2.2

clean-venv:
	rm -rf $(VENV) node_modules
