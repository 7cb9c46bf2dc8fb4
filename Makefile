# Two commands: `make demo` and `make test`. Both build .venv from pinned requirements first.
VENV    := .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
OUT     ?= out/demo
# EGL renders headless with no extra packages here; OSMesa (Debian libosmesa6) is the fallback.
MUJOCO_GL ?= $(shell $(PY) -c "import os; os.environ['MUJOCO_GL']='egl'; import mujoco; mujoco.GLContext(8, 8).make_current()" >/dev/null 2>&1 && echo egl || echo osmesa)
export MUJOCO_GL
export PYTHONHASHSEED := 0

.PHONY: demo test venv lint docs clean

venv: $(STAMP)

$(STAMP): pyproject.toml requirements.lock
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# CPU torch first: an unpinned torch would pull a multi-GB CUDA build.
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -r requirements.lock
	$(PY) -m pip install -q --no-deps --no-build-isolation -e .
	touch $(STAMP)

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	# The one-way data flow (pyproject.toml [tool.importlinter]): a forbidden import fails here.
	$(VENV)/bin/lint-imports
	# What the code imports is what pyproject.toml declares ([tool.deptry]): a missing, transitive
	# (there only through another package) or unused dependency fails here.
	$(VENV)/bin/deptry .

# The docs site, warnings as errors: a broken cross-reference or internal link, a results page
# naming a number its results file lacks, or an autodoc failure stops the build.
docs: $(STAMP)
	$(PY) -m sphinx -b html -W --keep-going -q docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

test: $(STAMP) lint docs
	$(VENV)/bin/pytest

demo: $(STAMP)
	$(PY) -m macrostate_mj.app.demo --out $(OUT)

clean:
	rm -rf $(VENV) out docs/_build
