#!/usr/bin/env bash
# `make test-compose`: deploy/compose.yaml and its overrides on a real Docker engine.
#
#   1. deploy/ci/engine.sh: a running engine and Docker Compose v2 (installs and starts them
#      where it can, as root);
#   2. deploy/ci/base-image.sh: if python:3.11-slim-bookworm is not there (CI's machines reach
#      no image registry), a stand-in built with debootstrap;
#   3. deploy/ci/build-image.sh: cbgo's image, reused when its inputs' hash is unchanged;
#   4. tests/compose/ with that image (pytest -s: the measured figures are printed).
#
# No engine to be had (not root, no apt, dockerd does not start): says so and exits 0 (skipped),
# or 1 with CBGO_COMPOSE_REQUIRED=1 (what .ci/run sets: on CI's machines it must run).
# A dockerd started here is stopped again at the end; the images stay cached on disk.
set -uo pipefail
cd "$(dirname "$0")/../.."
PY=${PY:-.venv/bin/python}

started=$(date +%s)
rm -f /run/cbgo-dockerd.pid  # engine.sh writes it only if it starts dockerd now
bash deploy/ci/engine.sh
rc=$?
if [ $rc -eq 3 ]; then
    if [ "${CBGO_COMPOSE_REQUIRED:-0}" = 1 ]; then
        echo "test-compose: FAILED: no Docker engine could be started (CBGO_COMPOSE_REQUIRED=1)" >&2
        exit 1
    fi
    echo "test-compose: SKIPPED: no Docker engine could be started here (see above)"
    exit 0
elif [ $rc -ne 0 ]; then
    exit $rc
fi
if [ -f /run/cbgo-dockerd.pid ]; then
    dockerd_pid=$(cat /run/cbgo-dockerd.pid)
    stop_dockerd() {
        kill "$dockerd_pid" 2>/dev/null || true
        for _ in $(seq 1 60); do kill -0 "$dockerd_pid" 2>/dev/null || break; sleep 0.5; done
        rm -f /run/cbgo-dockerd.pid
    }
    trap stop_dockerd EXIT
fi

# Projects of an earlier run that was stopped before its `down` (their restart policy would
# bring them back with the engine): removed with their volumes.
for project in $(docker ps -a --filter label=com.docker.compose.project \
        --format '{{.Label "com.docker.compose.project"}}' | grep '^cbgo-test-' | sort -u); do
    echo "test-compose: removing $project, left by an earlier run"
    docker compose -p "$project" down -v --remove-orphans -t 1 >/dev/null 2>&1 || true
done

set -e
base=$(sed -n 's/^FROM[[:space:]]\+\([^[:space:]]\+\).*/\1/p' deploy/Dockerfile | head -1)
# Where a registry answers, `docker pull python:3.11-slim-bookworm` first uses the real one.
bash deploy/ci/base-image.sh "$base"
t0=$(date +%s)
tag=$(bash deploy/ci/build-image.sh)
echo "test-compose: image $tag ready after $(( $(date +%s) - t0 )) s"
set +e
CBGO_COMPOSE_TAG=${tag#cbgo:} "$PY" -m pytest -q -s -p no:cacheprovider tests/compose
rc=$?
echo "test-compose: $(( $(date +%s) - started )) s in all"
exit $rc
