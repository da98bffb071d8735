#!/usr/bin/env bash
# Makes `docker compose ...` work where only Compose v1 (`docker-compose`, e.g. Debian 12's
# package) is installed and no registry can supply the v2 plugin: installs a Docker CLI plugin
# named `compose` that runs `docker-compose` with the same arguments. Idempotent; does nothing
# when `docker compose` already works. Installs for the current user, where the Docker CLI looks
# for plugins: $DOCKER_CONFIG/cli-plugins, by default ~/.docker/cli-plugins.
#
#   bash deploy/install-compose-plugin.sh
set -euo pipefail

if [[ $# -gt 0 ]]; then
  echo "install-compose-plugin.sh: takes no arguments (got \`$1\`)" >&2
  exit 2
fi
dir="${DOCKER_CONFIG:-$HOME/.docker}/cli-plugins"

if docker compose version >/dev/null 2>&1; then
  echo "docker compose already works: $(docker compose version)"
  exit 0
fi
v1=$(command -v docker-compose || true)
if [[ -z $v1 ]]; then
  echo "install-compose-plugin.sh: neither \`docker compose\` nor \`docker-compose\` is installed" >&2
  echo "  (Debian: apt-get install docker-compose)" >&2
  exit 1
fi
# The plugin must not find itself when it looks for docker-compose.
v1=$(readlink -f "$v1")

mkdir -p "$dir"
cat >"$dir/docker-compose" <<PLUGIN
#!/bin/sh
# Docker CLI plugin: \`docker compose ARGS\` runs \`$v1 ARGS\` (made by deploy/install-compose-plugin.sh).
if [ "\$1" = docker-cli-plugin-metadata ]; then
  echo '{"SchemaVersion":"0.1.0","Vendor":"hybrid-drive","Version":"v1-shim","ShortDescription":"Compose v1 (docker-compose) as docker compose"}'
  exit 0
fi
shift # the plugin's own name, "compose"
exec "$v1" "\$@"
PLUGIN
chmod +x "$dir/docker-compose"
docker compose version
