#!/usr/bin/env bash
# A stand-in for python:3.11-slim-bookworm, built without any image registry: debootstrap of
# Debian bookworm (python3, pip, venv) from the Debian mirror in this machine's apt sources, plus
# this machine's CA bundle (so pip inside `docker build` trusts what the host's pip trusts),
# then `docker import`, tagged as deploy/Dockerfile's base.
#
#     deploy/ci/base-image.sh [TAG]      # default TAG: python:3.11-slim-bookworm
#
# Does nothing if TAG already exists (a real python image, or a stand-in from an earlier run).
# Needs root, debootstrap and a running Docker engine. Only for machines that cannot pull.
set -euo pipefail

tag=${1:-python:3.11-slim-bookworm}
if docker image inspect "$tag" >/dev/null 2>&1; then
    echo "base image $tag: present ($(docker image inspect -f '{{index .Config.Labels "org.cbgo.base"}}' "$tag" 2>/dev/null || true))"
    exit 0
fi
command -v debootstrap >/dev/null || { echo "base-image: debootstrap is not installed" >&2; exit 1; }

# The first Debian mirror in the apt sources (deb822 .sources files or one-line .list files).
mirror=$(python3 - <<'PY'
import glob, re
uris = []
for path in sorted(glob.glob("/etc/apt/sources.list.d/*.sources")):
    text = open(path).read()
    for stanza in re.split(r"\n\s*\n", text):
        fields = dict(
            (m.group(1).lower(), m.group(2).strip())
            for m in re.finditer(r"^([A-Za-z-]+):\s*(.*)$", stanza, re.M)
        )
        suites = fields.get("suites", "").split()
        if any(s in ("bookworm", "stable") for s in suites):
            uris += fields.get("uris", "").split()
for path in ["/etc/apt/sources.list", *sorted(glob.glob("/etc/apt/sources.list.d/*.list"))]:
    try:
        lines = open(path).read().splitlines()
    except OSError:
        continue
    for line in lines:
        m = re.match(r"^deb\s+(?:\[[^]]*\]\s+)?(\S+)\s+(bookworm|stable)\s", line)
        if m:
            uris.append(m.group(1))
uris = [u for u in uris if "security" not in u]
print(uris[0] if uris else "http://deb.debian.org/debian")
PY
)
ca=/etc/ssl/certs/ca-certificates.crt
[ -s "$ca" ] || { echo "base-image: no CA bundle at $ca" >&2; exit 1; }

root=$(mktemp -d /var/tmp/cbgo-base.XXXXXX)
trap 'rm -rf "$root"' EXIT
echo "base image $tag: debootstrap bookworm from $mirror into $root"
start=$(date +%s)
debootstrap --variant=minbase --include=python3,python3-pip,python3-venv,ca-certificates \
    bookworm "$root" "$mirror" >"$root.log" 2>&1 || { tail -20 "$root.log" >&2; exit 1; }
rm -f "$root.log"

# Like the python image: `python`, `pip`, pip may install system-wide (no PEP 668 marker),
# security and point-release updates in the apt sources, no apt lists or caches.
cat >"$root/etc/apt/sources.list" <<SRC
deb $mirror bookworm main
deb $mirror bookworm-updates main
SRC
rm -f "$root"/usr/lib/python3*/EXTERNALLY-MANAGED
ln -sf python3 "$root/usr/bin/python"
cp "$ca" "$root/etc/ssl/certs/ca-certificates.crt"
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/*.bin "$root"/var/cache/apt/archives/*.deb

tar -C "$root" -c . | docker import \
    -c 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
    -c 'ENV LANG=C.UTF-8' \
    -c 'LABEL org.cbgo.base="stand-in: debootstrap bookworm + python3 + host CA bundle"' \
    -c 'CMD ["python3"]' \
    - "$tag" >/dev/null
echo "base image $tag: built in $(( $(date +%s) - start )) s, $(docker image inspect -f '{{.Size}}' "$tag") bytes"
