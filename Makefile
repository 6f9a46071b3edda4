# The README's two commands. Each creates .venv when missing and installs what it needs.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test lint install clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

# CPU torch first, so that no dependency pulls a multi-GB CUDA build.
$(STAMP): $(PY) pyproject.toml
	$(PY) -m pip install -q "torch==2.13.0"
	$(PY) -m pip install -q -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m ruff check falcon_rl tests examples benchmarks
	$(PY) -m pytest -q -p no:cacheprovider

demo: $(STAMP)
	$(PY) -m falcon_rl.cli demo

lint: $(STAMP)
	$(PY) -m ruff check falcon_rl tests examples benchmarks

clean:
	rm -rf $(VENV) runs
