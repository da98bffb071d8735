#!/usr/bin/env bash
# Builds the hybrid-drive image (`learner` and `actor`) from this work tree:
#   1. cargo build --release of the two binaries (skip with --no-cargo);
#   2. the base: with --base IMAGE, that image (e.g. debian:bookworm-slim where a registry is
#      reachable); without, a minimal one made here from this machine's libraries by
#      deploy/make-base.sh (no registry needed);
#   3. docker build of deploy/Dockerfile over a staged context (binaries, start script).
#
#   deploy/build-images.sh [--base IMAGE] [--tag TAG] [--no-cargo]     (default tag: hybrid-drive:latest)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"

base=""
tag=hybrid-drive:latest
cargo_build=1
while (($#)); do
  case $1 in
    --base) base=$2; shift 2 ;;
    --tag) tag=$2; shift 2 ;;
    --no-cargo) cargo_build=0; shift ;;
    -h | --help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "build-images: unknown argument $1" >&2; exit 2 ;;
  esac
done

target=${CARGO_TARGET_DIR:-$repo/target}
if ((cargo_build)); then
  echo "build-images: cargo build --release -p learner-cli -p actor"
  cargo build --release --locked -p learner-cli -p actor
fi
for bin in learner actor; do
  [[ -x $target/release/$bin ]] || { echo "build-images: $target/release/$bin is missing (run without --no-cargo)" >&2; exit 1; }
done

if [[ -z $base ]]; then
  base=hybrid-drive-base:local
  old_base=$(docker image inspect -f '{{.Id}}' "$base" 2>/dev/null || true)
  bash deploy/make-base.sh --tag "$base" "$target/release/learner" "$target/release/actor"
fi

ctx=$target/deploy-context
rm -rf "$ctx"
mkdir -p "$ctx/data"
cp deploy/Dockerfile deploy/learner-serve "$ctx/"
cp "$target/release/learner" "$target/release/actor" "$ctx/"
# The release profile keeps debug info (~100 MB a binary); the image does without (symbols stay).
if command -v strip >/dev/null; then strip --strip-debug "$ctx/learner" "$ctx/actor"; fi
echo "build-images: docker build -t $tag (base $base)"
previous=$(docker image inspect -f '{{.Id}}' "$tag" 2>/dev/null || true)
docker build --quiet --build-arg "BASE=$base" -t "$tag" "$ctx" >/dev/null
# The images this tag and the base named before go, unless a container still uses them.
if [[ -n $previous && $previous != "$(docker image inspect -f '{{.Id}}' "$tag")" ]]; then
  docker rmi "$previous" >/dev/null 2>&1 || true
fi
if [[ -n ${old_base:-} && $old_base != "$(docker image inspect -f '{{.Id}}' "$base")" ]]; then
  docker rmi "$old_base" >/dev/null 2>&1 || true
fi
echo "build-images: built $tag ($(docker image inspect -f '{{.Size}}' "$tag" | awk '{ printf "%.0f MB", $1 / 1e6 }'))"
