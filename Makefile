# canonid — the two commands of the quick start (`make demo`, `make test`) and helpers.
# Nothing is needed before them: the first call creates .venv and installs everything.

PYTHON ?= python3
VENV ?= .venv
# On the project's machines this pin resolves to a local CPU wheel; elsewhere override it,
# e.g. `make test TORCH_SPEC="torch"` to let pip choose a build for your platform.
TORCH_SPEC ?= torch==2.13.0
PY := $(VENV)/bin/python
STAMP := $(VENV)/.canonid-installed
DEMO_OUT ?= runs/demo
DEMO_WORKERS ?= 2

.PHONY: demo test test-fast lint bench docs clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade --quiet pip
	$(PY) -m pip install --quiet "$(TORCH_SPEC)"
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

# The tank pipeline of the quick profile (data, analysis, Table 1, compression, report) on two
# local worker processes; it prints the report's path. --resume: a second `make demo` reuses
# every finished job.
demo: $(STAMP)
	$(VENV)/bin/canonid reproduce --profile quick --systems tank --out $(DEMO_OUT) --workers $(DEMO_WORKERS) --resume

# pytest exits 5 when it collects no test; that is not a failure of the suite. -n auto: one
# worker process per core (pytest-xdist); every test is independent of the others' order.
test: $(STAMP)
	$(PY) -m pytest -q -n auto; rc=$$?; if [ $$rc -eq 5 ]; then exit 0; else exit $$rc; fi

test-fast: $(STAMP)
	$(PY) -m pytest -q -n auto -m "not slow"

# mypy reads canonid from build/mypy-src, links shaped like the installed package (pyproject's
# [tool.mypy] says why); its messages name files through those links.
lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -c 'import sys; sys.path.insert(0, "docs/hooks"); import api_reference as a; \
	a.source_tree(tree=a.ROOT / "build" / "mypy-src")'
	$(VENV)/bin/mypy

# The documentation site (docs/, mkdocs.yml) into site/; --strict: a warning (a broken link, a
# missing page, a docstring naming an argument the function lacks) fails the build.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir site

bench: $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,bench]"
	$(PY) benchmarks/run_all.py $(if $(BENCH),--size $(BENCH),)

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache site
