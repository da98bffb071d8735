#!/usr/bin/env bash
# Makes a minimal base image locally, without any registry: a root file system holding exactly the
# shared libraries the given binaries load (as `ldd` lists them, with the dynamic loader), a POSIX
# shell (dash, for the learner's start script), /etc/nsswitch.conf (`hosts: files dns`: glibc ≥ 2.34
# resolves DNS inside libc, so service names resolve through Docker's embedded DNS), /etc/passwd
# with the unprivileged user the image runs as, and /tmp; imported with `docker import`.
#
# The libraries come from this machine, so the image matches binaries built here exactly. Elsewhere,
# skip this and build on a standard base: `deploy/build-images.sh --base debian:bookworm-slim`.
#
#   deploy/make-base.sh [--tag TAG] BINARY...     (default tag: hybrid-drive-base:local)
set -euo pipefail

tag=hybrid-drive-base:local
if [[ ${1:-} == --tag ]]; then
  tag=$2
  shift 2
fi
(($# > 0)) || { echo "usage: $0 [--tag TAG] BINARY..." >&2; exit 2; }

root=$(mktemp -d)
# The image is labelled with a hash of what goes in; an up-to-date one is kept as it is (same id,
# so later builds on it reuse their cached layers).
trap 'rm -rf "$root"' EXIT

shell=$(command -v dash || true)
[[ -n $shell ]] || { echo "make-base: dash is needed (Debian package dash)" >&2; exit 1; }

# Every library and loader any of the binaries (and the shell) needs, at the path ldd names.
libs=$(
  for bin in "$@" "$shell"; do
    [[ -x $bin ]] || { echo "make-base: $bin is not an executable" >&2; exit 1; }
    if ldd "$bin" 2>&1 | grep -q 'not found'; then
      echo "make-base: $bin has unresolved libraries:" >&2
      ldd "$bin" >&2
      exit 1
    fi
    # "libm.so.6 => /lib/x86_64-linux-gnu/libm.so.6 (0x...)" and "/lib64/ld-linux-x86-64.so.2 (0x...)"
    ldd "$bin" | awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }'
  done | sort -u
)
for lib in $libs; do
  mkdir -p "$root$(dirname "$lib")"
  cp -L "$lib" "$root$lib"
done
mkdir -p "$root/bin" "$root/etc" "$root/tmp" "$root/usr/local/bin"
cp -L "$shell" "$root/bin/sh"
chmod 1777 "$root/tmp"
printf 'hosts: files dns\n' >"$root/etc/nsswitch.conf"
printf 'root:x:0:0:root:/root:/bin/sh\nhybrid:x:10001:10001:hybrid-drive:/data:/bin/sh\n' >"$root/etc/passwd"
printf 'root:x:0:\nhybrid:x:10001:\n' >"$root/etc/group"

hash=$(cd "$root" && find . -type f -o -type l | LC_ALL=C sort | xargs -d '\n' sha256sum | sha256sum | cut -c1-16)
if [[ $(docker image inspect -f '{{index .Config.Labels "hybrid-drive.base-hash"}}' "$tag" 2>/dev/null || true) == "$hash" ]]; then
  echo "make-base: $tag is up to date"
  exit 0
fi
tar -C "$root" --numeric-owner --owner=0 --group=0 -c . |
  docker import \
    --change 'ENV PATH=/usr/local/bin:/usr/bin:/bin' \
    --change "LABEL hybrid-drive.base-hash=$hash" \
    --message "hybrid-drive minimal base from $(uname -n) ($(ldd --version | head -1))" \
    - "$tag" >/dev/null
echo "make-base: $tag ($(echo "$libs" | wc -w) libraries, $(du -sh "$root" | cut -f1))"
