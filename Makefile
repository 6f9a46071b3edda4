# The README's two commands. Each creates .venv when missing and installs what it needs.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
# Material for MkDocs prints a banner about MkDocs 2.0 on every build; it is not a warning of ours.
MKDOCS := NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs

.PHONY: demo test lint docs install clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

# CPU torch first, so that no dependency pulls a multi-GB CUDA build.
$(STAMP): $(PY) pyproject.toml
	$(PY) -m pip install -q "torch==2.13.0"
	$(PY) -m pip install -q -e ".[dev]"
	$(PY) -m falcon_rl_gymnasium_hook >/dev/null   # the start-up file a wheel carries (editable: by hand)
	touch $(STAMP)

install: $(STAMP)

# Ruff, the API reference site in strict mode (any warning fails: a broken link, a missing include,
# a docstring the site cannot render), then the tests: one pytest-xdist worker per core, each test
# file on one worker (its module fixtures built once); 2 workers on 2 cores halve the suite's time.
test: $(STAMP)
	$(PY) -m ruff check falcon_rl tests examples benchmarks docs setup.py falcon_rl_gymnasium_hook.py
	$(MKDOCS) build --strict --quiet
	$(PY) -m pytest -q -p no:cacheprovider -n auto --dist loadfile

demo: $(STAMP)
	$(PY) -m falcon_rl.cli demo

lint: $(STAMP)
	$(PY) -m ruff check falcon_rl tests examples benchmarks docs setup.py falcon_rl_gymnasium_hook.py

# The API reference site -> site/index.html (`make test` builds it strictly;
# `.venv/bin/mkdocs serve` serves it with live reload).
docs: $(STAMP)
	$(MKDOCS) build

clean:
	rm -rf $(VENV) runs site
