#!/usr/bin/env bash
# Makes the Debian 12 base images the Dockerfile and deploy/images/* start FROM
# (debian:bookworm and debian:bookworm-slim) without a container registry: debootstrap builds a
# minimal bookworm root file system from Debian's mirror and `podman import` stores it under
# both names. Needs root, debootstrap and podman (scripts/setup.sh installs them). Skips the work
# when both images exist. About 2-4 minutes.
#   bash deploy/base-image.sh [MIRROR]     # default: the first URI in /etc/apt/sources*
set -euo pipefail
if podman image exists docker.io/library/debian:bookworm && podman image exists docker.io/library/debian:bookworm-slim; then
  echo "debian:bookworm and debian:bookworm-slim already present"; exit 0
fi
mirror="${1:-$(grep -rhoE '^(URIs:|deb) +https?://[^ ]+' /etc/apt/sources.list /etc/apt/sources.list.d/*.sources 2>/dev/null | awk '{print $2}' | head -n1)}"
mirror="${mirror:-http://deb.debian.org/debian}"
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
debootstrap --variant=minbase bookworm "$root" "$mirror"
# The images' apt must reach the same mirror; no leftover package lists.
echo "deb $mirror bookworm main" > "$root/etc/apt/sources.list"
echo "deb $mirror bookworm-updates main" >> "$root/etc/apt/sources.list"
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/archives/*.deb
tar -C "$root" -c . | podman import --change 'CMD ["bash"]' - docker.io/library/debian:bookworm
podman tag docker.io/library/debian:bookworm docker.io/library/debian:bookworm-slim
echo "made debian:bookworm and debian:bookworm-slim from $mirror"
