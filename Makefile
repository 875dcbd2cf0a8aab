# The two commands of the README. Each creates .venv if it is missing and installs the project.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.hgo_mj-installed

# tiny matrices: multi-threaded BLAS only adds contention on a small machine
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: demo test bench lint docs clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

# the benchmark's quick suite: leaderboard, figures, recordings -> runs/demo/
demo: $(STAMP)
	$(VENV)/bin/hgo-mj bench --suite quick --budget 8 --out runs/demo

# the Debian packages the rendering tests need (EGL, Xvfb), installed where missing
test: $(STAMP)
	scripts/system_deps.sh
	$(PY) -m mypy
	$(PY) scripts/check_complexity.py
	$(PY) -m pytest -q -ra

bench: $(STAMP)
	$(PY) scripts/bench.py

# the documentation site: Sphinx with numpydoc and the executed gallery, warnings as errors
DOCS_STAMP := $(VENV)/.hgo_mj-docs-installed
$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[dev,docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(PY) -m sphinx -b html -W --keep-going docs docs/_build/html

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) build dist *.egg-info runs .pytest_cache docs/_build docs/auto_examples
