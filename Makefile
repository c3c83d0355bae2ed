# Two commands on a fresh machine: `make demo` and `make test`. Both set everything up first.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: setup demo test lint format bench clean

setup: $(STAMP) .cache/system-gl-ok .cache/assets/teapot.obj

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

# Mesa EGL/llvmpipe: installed with apt when missing and we are root, otherwise the command is printed.
.cache/system-gl-ok: scripts/ensure-gl.sh
	bash scripts/ensure-gl.sh $(PY)
	mkdir -p .cache && touch $@

# The Utah teapot (public-domain data) comes from the npm registry package utah-teapot.
.cache/assets/teapot.obj: scripts/fetch-assets.sh
	bash scripts/fetch-assets.sh .cache/assets

demo: setup
	$(VENV)/bin/prefilter compare wood-teapot -o out/wood-teapot
	$(VENV)/bin/prefilter compare noise-plane -o out/noise-plane
	@echo "Every preset in the browser: $(VENV)/bin/prefilter view   (export for engines: prefilter export SCENE -o DIR)"

# Debian's Chromium for the viewer's browser tests (Playwright drives it; it downloads no browser).
.cache/chromium-ok: scripts/ensure-chromium.sh
	bash scripts/ensure-chromium.sh
	mkdir -p .cache && touch $@

# Two pytest workers (CI's cores), each taking whole files (a file's fixtures, such as the viewer's server
# and browser, are set up once): 343 s against 470 s in one process on this 2-core machine. On a clean
# machine (empty bake and Mesa shader caches) the suite took 517-576 s on 2026-12-07 (703 s before the bake
# cache's lock and the fast table's phasors). Each worker runs its BLAS and llvmpipe single-threaded: with
# their default thread per core, two workers kept four or more threads busy on two cores (OpenBLAS's
# threads spin while they wait), and the clean-machine suite took 573 s; 448 s with one BLAS thread, 409 s
# with llvmpipe's rasteriser on one thread too (2026-12-07, 793 tests).
TEST_WORKERS ?= 2
test: setup .cache/chromium-ok
	$(VENV)/bin/ruff check src tests
	$(VENV)/bin/ruff format --check src tests
	OPENBLAS_NUM_THREADS=1 LP_NUM_THREADS=1 $(VENV)/bin/pytest -q -n $(TEST_WORKERS) --dist loadfile

bench: setup
	$(VENV)/bin/prefilter bench --json out/bench.json

format: setup
	$(VENV)/bin/ruff format src tests
	$(VENV)/bin/ruff check --fix src tests

clean:
	rm -rf out .cache $(VENV)
