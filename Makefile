# The two commands of the README. Each creates .venv if it is missing and installs the project.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.hgo_mj-installed

# tiny matrices: multi-threaded BLAS only adds contention on a small machine
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: demo test bench lint clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/hgo-mj demo

test: $(STAMP)
	$(PY) -m mypy
	$(PY) scripts/check_complexity.py
	$(PY) -m pytest -q -ra

bench: $(STAMP)
	$(PY) scripts/bench.py

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) build dist *.egg-info runs .pytest_cache
