# Two entry points (see README quick start):
#   make run   installs everything into .venv and runs the main job with its defaults
#   make test  installs everything into .venv and runs lint, type checks and the tests
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install browser run test lint typecheck pytest wheel docs clean

# The browser test drives Debian's chromium (never a downloaded browser): install it if absent.
SUDO := $(shell [ "$$(id -u)" -eq 0 ] || echo sudo)

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# The CPU build of torch that lies on disk here; any other resolves to a multi-GB CUDA build.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[dev,docs]'
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/seqrank train

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests scripts examples docs/hooks
	$(VENV)/bin/ruff format --check src tests scripts examples docs/hooks

typecheck: $(STAMP)
	$(VENV)/bin/mypy

browser:
	@command -v chromium >/dev/null || { $(SUDO) apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq chromium >/dev/null; }

# Two workers, one torch thread each (the learning thresholds were measured with one
# thread); a file's tests stay on one worker, so module fixtures are built once.
pytest: $(STAMP) browser
	OMP_NUM_THREADS=1 $(PY) -m pytest -n 2 --dist loadfile

# The wheel as a user installs it: built, put into a clean venv, trained and served from there.
wheel: $(STAMP)
	scripts/check_wheel.sh

# The documentation site, strict (a broken link or a warning fails) and offline, into site/.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet

test: lint typecheck docs pytest wheel

clean:
	rm -rf $(VENV) seqrank-out site .pytest_cache .mypy_cache .ruff_cache
