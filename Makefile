# The two commands of the README. Each creates .venv if it is missing and installs what it
# needs: `make demo` the runtime only (pip install -e .), `make test` the dev extra (every extra
# the tests use, and the tools) within constraints.txt, the test environment's versions.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.hgo_mj-installed
DEV_STAMP := $(VENV)/.hgo_mj-dev-installed

# tiny matrices: multi-threaded BLAS only adds contention on a small machine
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: demo test bench lint docs constraints clean

$(PY):
	@echo "[1/3] creating $(VENV) ($(PYTHON) -m venv)"
	$(PYTHON) -m venv $(VENV)

# the runtime: what the demo and the main job need (README.md, "Install"); pip prints each
# distribution as it collects and installs it. --no-compile: Python writes the bytecode of the
# modules a run imports as it imports them, not of every module of every package up front
$(STAMP): pyproject.toml | $(PY)
	@echo "[2/3] installing hgo_mj and its runtime dependencies into $(VENV) (pip install -e .)"
	$(PY) -m pip install --no-compile -e .
	touch $(STAMP)

# the benchmark's quick suite: leaderboard, figures, recordings -> runs/demo/
demo: $(STAMP)
	@echo "[3/3] running the benchmark's quick suite: hgo-mj bench --suite quick -> runs/demo/"
	$(VENV)/bin/hgo-mj bench --suite quick --budget 8 --jobs 2 --out runs/demo
	@echo "done: open $(CURDIR)/runs/demo/leaderboard.md and $(CURDIR)/runs/demo/score_matrix.png"

$(DEV_STAMP): pyproject.toml constraints.txt $(STAMP)
	@echo "installing the dev extra (tests, lint, every extra the tests use) within constraints.txt"
	$(PY) -m pip install -e ".[dev]" -c constraints.txt
	touch $(DEV_STAMP)

# the Debian packages the rendering tests need (EGL, Xvfb), installed where missing
test: $(DEV_STAMP)
	scripts/system_deps.sh
	$(PY) -m mypy
	$(PY) scripts/check_complexity.py
	$(PY) -m pytest -q -ra

# constraints.txt: the versions of the test and docs environment, resolved afresh in a
# throwaway venv (pip freeze of `.[dev,docs]`, hgo_mj itself left out); commit the result
LOCK_VENV := .venv-constraints
constraints:
	rm -rf $(LOCK_VENV)
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install ".[dev,docs]"
	{ echo "# pip freeze of .[dev,docs] (make constraints); make test and make docs install within it"; \
	  $(LOCK_VENV)/bin/python -m pip freeze --exclude hgo_mj; } > constraints.txt.tmp
	mv constraints.txt.tmp constraints.txt
	rm -rf $(LOCK_VENV)

bench: $(DEV_STAMP)
	$(PY) scripts/bench.py

# the documentation site: Sphinx with numpydoc and the executed gallery, warnings as errors
DOCS_STAMP := $(VENV)/.hgo_mj-docs-installed
$(DOCS_STAMP): $(DEV_STAMP)
	$(PY) -m pip install -e ".[dev,docs]" -c constraints.txt
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(PY) -m sphinx -b html -W --keep-going docs docs/_build/html

lint: $(DEV_STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) $(LOCK_VENV) build dist *.egg-info runs .pytest_cache docs/_build docs/auto_examples
