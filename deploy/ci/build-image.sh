#!/usr/bin/env bash
# Builds cbgo's image from deploy/Dockerfile, or reuses it when nothing it is built from changed.
#
#     deploy/ci/build-image.sh            # prints the tag, cbgo:ci-<hash> (progress: stderr)
#
# The tag is a hash of the build's inputs: every file that the build context lets in (the
# files git would commit under pyproject.toml, setup.py, MANIFEST.in, README.md, shared/,
# services/), deploy/Dockerfile, .dockerignore, the build arguments and the base image's id.
# An image with that tag is reused as it is; the tag is also given to cbgo:latest (what
# deploy/compose.yaml runs by default).
#
# torch: if this host's pip finds torch==2.13.0 without an index (a local CPU wheel, as on the
# CI machines), the wheel is served to the build on a loopback port and TORCH_PIP_ARGS points pip
# inside the build at it (`--network host`); else the Dockerfile's default, the PyTorch CPU index.
# CBGO_TORCH_PIP_ARGS overrides both.
set -euo pipefail
cd "$(dirname "$0")/../.."
exec 3>&1 1>&2  # progress on stderr; only the tag on stdout (fd 3)

base=$(sed -n 's/^FROM[[:space:]]\+\([^[:space:]]\+\).*/\1/p' deploy/Dockerfile | head -1)
base_id=$(docker image inspect -f '{{.Id}}' "$base" 2>/dev/null) || {
    echo "build-image: base image $base is missing (deploy/ci/base-image.sh makes a stand-in)" >&2
    exit 1; }

cache=${XDG_CACHE_HOME:-$HOME/.cache}/cbgo-compose
mkdir -p "$cache/wheels"
torch_args=${CBGO_TORCH_PIP_ARGS:-}
serve=
if [ -z "$torch_args" ]; then
    if ls "$cache"/wheels/torch-2.13.0*.whl >/dev/null 2>&1 \
        || python3 -m pip download --quiet --no-deps --no-index --dest "$cache/wheels" \
            torch==2.13.0 >/dev/null 2>&1; then
        serve=$cache/wheels
    fi
fi

# The inputs, hashed: file names and contents, the Dockerfile's arguments, the base image.
hash=$( {
    git ls-files -co --exclude-standard -- pyproject.toml setup.py MANIFEST.in README.md \
        shared services deploy/Dockerfile .dockerignore | grep -v -E '(__pycache__|\.py[cod]$|\.mcap$)' \
        | LC_ALL=C sort | while IFS= read -r f; do
            [ -f "$f" ] && printf '%s %s\n' "$(sha256sum <"$f" | cut -c1-64)" "$f"
        done
    echo "torch: ${torch_args:-${serve:+local wheel $(ls "$serve" | grep '^torch-2.13.0' | head -1)}}"
    echo "base: $base_id"
} | sha256sum | cut -c1-12)
tag=cbgo:ci-$hash

if docker image inspect "$tag" >/dev/null 2>&1; then
    echo "image $tag: cached (inputs unchanged), $(docker image inspect -f '{{.Size}}' "$tag") bytes"
else
    args=()
    if [ -n "$serve" ]; then
        port_file=$(mktemp)
        python3 - "$serve" "$port_file" <<'PY' &
import functools, http.server, sys
class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass
handler = functools.partial(Quiet, directory=sys.argv[1])
# A fixed port if it is free: the build argument, and so Docker's layer cache, stays the same.
try:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 7480), handler)
except OSError:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
open(sys.argv[2], "w").write(str(server.server_address[1]))
server.serve_forever()
PY
        server_pid=$!
        trap 'kill $server_pid 2>/dev/null || true' EXIT
        while [ ! -s "$port_file" ]; do sleep 0.1; done
        torch_args="--find-links http://127.0.0.1:$(cat "$port_file")/"
        rm -f "$port_file"
        echo "image $tag: torch from the local wheel in $serve"
    fi
    [ -n "$torch_args" ] && args+=(--build-arg "TORCH_PIP_ARGS=$torch_args")
    echo "image $tag: building (docker build --network host)"
    start=$(date +%s)
    DOCKER_BUILDKIT=0 docker build --network host -f deploy/Dockerfile "${args[@]}" \
        --label "org.cbgo.inputs=$hash" -t "$tag" . >"$cache/build-$hash.log" 2>&1 || {
        tail -40 "$cache/build-$hash.log" >&2
        echo "build-image: docker build failed (log: $cache/build-$hash.log)" >&2
        exit 1; }
    echo "image $tag: built in $(( $(date +%s) - start )) s, $(docker image inspect -f '{{.Size}}' "$tag") bytes"
fi
docker tag "$tag" cbgo:latest
# Keep the two newest images of earlier inputs (fast switching between branches), drop older.
docker image ls --format '{{.CreatedAt}}\t{{.Repository}}:{{.Tag}}' cbgo | grep -F ':ci-' \
    | LC_ALL=C sort -r | cut -f2 | grep -v -x -F "$tag" | tail -n +3 \
    | xargs -r docker image rm >/dev/null 2>&1 || true
echo "$tag" >&3
