#!/usr/bin/env bash
# End-to-end test of the compose deployment with real containers and faults (run by .ci/run when a
# Docker engine is reachable):
#   1. build the image (cargo build --release, local base, docker build);
#   2. `up --scale actor=3`; wait until the learner's status lists 3 connected actors and the
#      weights version has advanced;
#   3. `docker kill` one actor: training goes on without it, and it comes back (registers again
#      under its name) when compose restores the scale; crash another (SIGKILL to its process):
#      the restart policy brings it back by itself;
#   4. restart the learner container: it resumes its run from the checkpoint (same run id,
#      counters not behind what they were) and all 3 actors reconnect and train on; then SIGKILL
#      the learner's process (no final checkpoint): the restart policy brings it back, it resumes
#      with its replay rebuilt from the replay log (replay size not behind by more than one batch
#      per actor), newer weights than before the kill, and the actors take them and train on;
#   5. disconnect one actor from the network for 20 s: the learner sees it silent; reconnected, it
#      streams again;
#   6. `down -v`: containers, network and volume are gone.
# By default everything runs over mutual TLS with token auth (deploy/docker-compose.tls.yml over
# the base file, certificates made for the run by the image's `learner certs`), and the learner is
# checked to refuse a client without a certificate, one without the token, and plaintext;
# `--plaintext` runs the base file alone.
# Prints each check; exits non-zero on the first failure (with the containers' logs). Everything
# runs under a unique compose project, removed on exit whatever happens.
#
#   bash deploy/test-compose.sh [--no-build] [--plaintext]   (--no-build: use the existing hybrid-drive:latest)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"

build=1
tls=1
for arg in "$@"; do
  case $arg in
    --no-build) build=0 ;;
    --plaintext) tls=0 ;;
    *) echo "test-compose.sh: unknown argument $arg (expected --no-build, --plaintext)" >&2; exit 2 ;;
  esac
done

t0=$SECONDS
say() { printf '[%4ds] %s\n' $((SECONDS - t0)) "$*"; }
pass() { say "PASS: $*"; }
fail() {
  say "FAIL: $*"
  exit 1
}

if docker compose version >/dev/null 2>&1; then
  compose=(docker compose)
elif command -v docker-compose >/dev/null 2>&1 && docker-compose version >/dev/null 2>&1; then
  compose=(docker-compose)
else
  fail "neither \`docker compose\` nor \`docker-compose\` is available"
fi
docker info >/dev/null 2>&1 || fail "no Docker engine is reachable (docker info)"
command -v python3 >/dev/null || fail "python3 is needed to read the status JSON"

project=hdtest$$x$RANDOM
export HD_IMAGE=${HD_IMAGE:-hybrid-drive:latest}
export HD_CONFIG=$repo/deploy/compose.toml
export HD_ENVS=2
# Published on loopback at ports the engine picks: no clash with a deployment already running.
export HD_BIND=127.0.0.1 HD_GRPC_PORT=0 HD_METRICS_PORT=0
files=(-f deploy/docker-compose.yml)
# How the test's own clients inside the containers reach the learner.
addr=127.0.0.1:50051
client=()
auth=()
if ((tls)); then
  files+=(-f deploy/docker-compose.tls.yml)
  certs=$(mktemp -d)
  export HD_TLS_DIR=$certs
  addr=https://127.0.0.1:50051
  client=(--tls-ca /etc/hybrid-drive-tls/ca.pem --tls-cert /etc/hybrid-drive-tls/client.pem --tls-key /etc/hybrid-drive-tls/client-key.pem)
  auth=(--auth-token-file /etc/hybrid-drive-tls/token)
fi
c() { "${compose[@]}" -p "$project" "${files[@]}" "$@"; }

finished=0
cleanup() {
  local rc=$?
  if ((!finished)); then
    say "logs of the failed run (last 40 lines of each container):"
    for id in $(docker ps -aq --filter "label=com.docker.compose.project=$project"); do
      echo "----- $(docker inspect -f '{{.Name}}' "$id")"
      docker logs --tail 40 "$id" 2>&1 || true
    done
  fi
  c down -v --remove-orphans -t 10 >/dev/null 2>&1 || true
  [[ -n ${certs:-} ]] && rm -rf "$certs"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# --- helpers -------------------------------------------------------------------------------------

# The learner's status as JSON (empty when it does not answer).
status() {
  docker exec "$learner" learner status --addr "$addr" "${client[@]}" "${auth[@]}" --json 2>/dev/null | tail -n 1 || true
}
# q 'PYTHON EXPRESSION' [ARGS...]: evaluates the expression over the status `s` (a dict); with
# `args` the extra arguments. Prints the result; prints nothing and fails when there is no status.
q() {
  local expr=$1
  shift
  status | python3 -c '
import json, sys
text = sys.stdin.read().strip()
if not text:
    sys.exit(1)
s = json.loads(text)
args = sys.argv[2:]
connected = [a for a in s["actors"] if a["connected"]]
def actor(name):
    return [a for a in s["actors"] if a["name"] == name]
print(eval(sys.argv[1]))
' "$expr" "$@"
}
# wait_for SECONDS DESCRIPTION COMMAND...: retries COMMAND every 2 s until it succeeds.
wait_for() {
  local limit=$1 what=$2 start=$SECONDS
  shift 2
  until "$@" >/dev/null 2>&1; do
    ((SECONDS - start < limit)) || fail "$what: not within $limit s (status: $(status))"
    sleep 2
  done
  say "  ($what after $((SECONDS - start)) s)"
}
is_true() { [[ $(q "$@") == True ]]; }
# get EXPR [ARGS...]: like q, but a missing status is a failure (reported on stderr, as the value
# is captured).
get() { q "$@" || { printf '[%4ds] FAIL: no status from the learner for %s\n' $((SECONDS - t0)) "$1" >&2; return 1; }; }
actor_name() { echo "$(docker inspect -f '{{.Config.Hostname}}' "$1")-1"; } # an actor's default name: HOSTNAME-PID
running_actors() {
  docker ps -q --no-trunc --filter "label=com.docker.compose.project=$project" \
    --filter label=com.docker.compose.service=actor --filter status=running
}
# first_line COMMAND...: the first line of the output (without `| head`, which pipefail dislikes).
first_line() {
  local out
  out=$("$@")
  echo "${out%%$'\n'*}"
}

# --- 1. build --------------------------------------------------------------------------------------
say "compose: ${compose[*]} ($("${compose[@]}" version --short 2>/dev/null || true)); project $project"
if ((build)); then
  b0=$SECONDS
  bash deploy/build-images.sh --tag "$HD_IMAGE"
  pass "image $HD_IMAGE built in $((SECONDS - b0)) s"
else
  docker image inspect "$HD_IMAGE" >/dev/null 2>&1 || fail "--no-build: image $HD_IMAGE does not exist"
fi
docker run --rm --entrypoint learner "$HD_IMAGE" --version >/dev/null || fail "the image does not run learner"
docker run --rm --entrypoint actor "$HD_IMAGE" --version >/dev/null || fail "the image does not run actor"
pass "the image runs learner and actor"
if ((tls)); then
  # A CA, a server certificate for the names the learner is reached by, a client certificate and
  # a token, readable by the containers' user (10001).
  docker run --rm --user 0 --entrypoint learner -v "$certs:/out" "$HD_IMAGE" certs --out /out --hosts learner,localhost,127.0.0.1 >/dev/null ||
    fail "learner certs in the image"
  head -c 32 /dev/urandom | base64 >"$certs/token"
  chown -R 10001:10001 "$certs" 2>/dev/null || chmod -R a+rX "$certs"
  pass "certificates and token made for the run (mutual TLS and token auth on)"
fi

# --- 2. up -----------------------------------------------------------------------------------------
say "up -d --scale actor=3"
c up -d --scale actor=3 2>&1 | sed 's/^/  /'
learner=$(c ps -q learner)
[[ -n $learner ]] || fail "no learner container"
[[ $(docker inspect -f '{{.State.Health.Status}}' "$learner") == healthy ]] || fail "the learner is not healthy after up"
pass "learner healthy (compose health check: learner health over grpc.health.v1)"
[[ $(running_actors | wc -l) -eq 3 ]] || fail "expected 3 running actor containers"
# Service-name DNS inside a container, as the actors use it.
health_addr=learner:50051
((tls)) && health_addr=https://learner:50051
docker exec "$(first_line running_actors)" learner health --addr "$health_addr" "${client[@]}" >/dev/null ||
  fail "an actor container cannot reach $health_addr by name"
pass "an actor container resolves the service name and gets SERVING from $health_addr"
if ((tls)); then
  ca=(--tls-ca /etc/hybrid-drive-tls/ca.pem)
  refused() { ! docker exec "$learner" learner status --json "$@" >/dev/null 2>&1; }
  refused --addr "$addr" "${ca[@]}" "${auth[@]}" || fail "a client without a certificate was served (mutual TLS off?)"
  refused --addr "$addr" "${client[@]}" || fail "a client without the token was served (token auth off?)"
  refused --addr 127.0.0.1:50051 "${auth[@]}" || fail "a plaintext client was served (TLS off?)"
  docker exec "$learner" learner status --json --addr "$addr" "${client[@]}" "${auth[@]}" >/dev/null || fail "the test's own client (certificate and token) was refused"
  pass "the learner refuses a client without a certificate, one without the token, and plaintext"
fi

wait_for 240 "3 actors connected and streaming" is_true 'len(connected) == 3 and all(a["transitions"] > 0 for a in connected)'
v0=$(get 's["weights_version"]')
wait_for 300 "weights version past $v0 (training)" is_true 's["weights_version"] > int(args[0]) and s["learner_step"] > 0' "$v0"
run_id=$(get 's["run_id"]')
pass "status lists 3 connected actors; run $run_id trains: $(get '"weights version %d, learner step %d, %d transitions" % (s["weights_version"], s["learner_step"], s["transitions_received"])')"

# --- 3. kill an actor ------------------------------------------------------------------------------
# (a) `docker kill`, as an operator would. Docker counts it as a manual stop, so no restart policy
# applies to it (measured on Engine 20.10: not even `always`); compose brings the actor back when
# asked for the scale again, as Kubernetes' Deployment does by itself.
mapfile -t actors < <(running_actors | sort)
victim=${actors[0]}
victim_name=$(actor_name "$victim")
victim_id=$(get '[a["actor_id"] for a in actor(args[0]) if a["connected"]][0]' "$victim_name") ||
  fail "actor $victim_name is not in the status"
v_kill=$(get 's["weights_version"]')
say "docker kill actor $victim_name (learner id $victim_id)"
docker kill "$victim" >/dev/null
[[ $(docker inspect -f '{{.State.Running}}' "$victim") == false ]] || fail "the killed actor still runs"
wait_for 120 "weights version past $v_kill with the actor killed" is_true 's["weights_version"] > int(args[0])' "$v_kill"
wait_for 60 "the learner lists the killed actor as disconnected" is_true 'not any(a["connected"] for a in actor(args[0]))' "$victim_name"
pass "training continues without the killed actor: $(get '"%d actors connected, weights version %d" % (len(connected), s["weights_version"])')"
say "up -d --scale actor=3 (compose restores the scale)"
c up -d --scale actor=3 2>&1 | sed 's/^/  /'
wait_for 120 "$victim_name registered again and streaming" \
  is_true 'any(a["connected"] and a["actor_id"] != args[1] and a["transitions"] > 0 for a in actor(args[0]))' "$victim_name" "$victim_id"
wait_for 60 "3 actors connected" is_true 'len(connected) == 3'
pass "the killed actor is back: it registered again as $victim_name (same index) and streams"

# (b) a crash: the actor's process dies of SIGKILL (as by the kernel's OOM killer) without Docker
# being asked: the restart policy (restart: always) starts it again by itself. Needs the
# container's process to be visible from here (the engine on this host, as on our machines).
crashed=${actors[1]}
crashed_name=$(actor_name "$crashed")
crashed_id=$(get '[a["actor_id"] for a in actor(args[0]) if a["connected"]][0]' "$crashed_name") ||
  fail "actor $crashed_name is not in the status"
pid=$(docker inspect -f '{{.State.Pid}}' "$crashed")
restarts=$(docker inspect -f '{{.RestartCount}}' "$crashed")
if kill -0 "$pid" 2>/dev/null; then
  say "kill -9 the process of actor $crashed_name (host pid $pid)"
  kill -9 "$pid"
  wait_for 60 "restart count of $crashed_name past $restarts" \
    bash -c "[ \$(docker inspect -f '{{.RestartCount}}' $crashed) -gt $restarts ]"
  wait_for 120 "$crashed_name registered again and streaming" \
    is_true 'any(a["connected"] and a["actor_id"] != args[1] and a["transitions"] > 0 for a in actor(args[0]))' "$crashed_name" "$crashed_id"
  wait_for 60 "3 actors connected" is_true 'len(connected) == 3'
  pass "the restart policy brought the crashed actor back by itself: it registered again as $crashed_name and streams"
else
  say "SKIP: the crash check (the engine's processes are not visible from here; pid $pid)"
fi

# --- 4. restart the learner ------------------------------------------------------------------------
before=$(status)
b_step=$(get 's["learner_step"]')
b_version=$(get 's["weights_version"]')
b_received=$(get 's["transitions_received"]')
b_episodes=$(get 's["episodes"]["total"]')
say "docker restart learner (SIGTERM: final checkpoint) at learner step $b_step, weights version $b_version, $b_received transitions, $b_episodes episodes"
docker restart -t 60 "$learner" >/dev/null
wait_for 30 "learner-serve started with --resume" bash -c "docker logs $learner 2>&1 | grep -q 'resuming the run in'"
wait_for 120 "learner healthy again" bash -c "[ \$(docker inspect -f '{{.State.Health.Status}}' $learner) = healthy ]"
[[ $(q 's["run_id"]') == "$run_id" ]] || fail "run id changed across the restart: $(q 's["run_id"]') (was $run_id)"
is_true 's["learner_step"] >= int(args[0]) and s["weights_version"] >= int(args[1]) and s["transitions_received"] >= int(args[2]) and s["episodes"]["total"] >= int(args[3])' \
  "$b_step" "$b_version" "$b_received" "$b_episodes" ||
  fail "counters went back across the restart: $(status) (before: $before)"
pass "learner resumed run $run_id from its checkpoint: $(get '"learner step %d, weights version %d, %d transitions, %d episodes" % (s["learner_step"], s["weights_version"], s["transitions_received"], s["episodes"]["total"])')"
v_restart=$(get 's["weights_version"]')
r_received=$(get 's["transitions_received"]')
wait_for 180 "3 actors reconnected and streaming" is_true 'len(connected) == 3 and all(a["transitions"] > 0 for a in connected)'
wait_for 240 "weights version past $v_restart after the restart" is_true 's["weights_version"] > int(args[0]) and s["transitions_received"] > int(args[1])' "$v_restart" "$r_received"
pass "all 3 actors reconnected to the restarted learner and training goes on"

# (b) a crash: SIGKILL of the learner's process (as by the OOM killer or a preempted machine). No
# checkpoint is written; what was acknowledged is in the replay log, and the restart policy
# (unless-stopped) starts the learner again, which resumes.
pid=$(docker inspect -f '{{.State.Pid}}' "$learner")
if kill -0 "$pid" 2>/dev/null; then
  k_replay=$(get 's["replay_size"]')
  k_version=$(get 's["weights_version"]')
  k_received=$(get 's["transitions_received"]')
  restarts=$(docker inspect -f '{{.RestartCount}}' "$learner")
  resumes=$(docker logs "$learner" 2>&1 | grep -c 'resuming the run in' || true)
  say "kill -9 the learner's process (host pid $pid) at replay $k_replay, weights version $k_version, $k_received transitions"
  kill -9 "$pid"
  wait_for 60 "restart count of the learner past $restarts" \
    bash -c "[ \$(docker inspect -f '{{.RestartCount}}' $learner) -gt $restarts ]"
  wait_for 60 "learner-serve started again with --resume" \
    bash -c "[ \$(docker logs $learner 2>&1 | grep -c 'resuming the run in') -gt $resumes ]"
  wait_for 120 "learner healthy again after the SIGKILL" bash -c "[ \$(docker inspect -f '{{.State.Health.Status}}' $learner) = healthy ]"
  [[ $(q 's["run_id"]') == "$run_id" ]] || fail "run id changed across the SIGKILL: $(q 's["run_id"]') (was $run_id)"
  # Each actor has at most one batch (64 steps) in flight: stored, maybe not yet durable, never
  # acknowledged.
  is_true 's["replay_size"] + 3 * 64 >= int(args[0]) and s["weights_version"] > int(args[1]) and s["reliability"]["durability"] == "ack"' \
    "$k_replay" "$k_version" || fail "after the SIGKILL: $(status) (before: replay $k_replay, version $k_version)"
  pass "the learner came back from SIGKILL with its replay rebuilt: $(get '"replay %d (was %d), weights version %d (was %d), replay log %.1f MiB" % (s["replay_size"], int(args[0]), s["weights_version"], int(args[1]), s["reliability"]["replay_log_bytes"] / 1048576)' "$k_replay" "$k_version")"
  k_restart=$(get 's["weights_version"]')
  wait_for 180 "3 actors reconnected and streaming after the SIGKILL" is_true 'len(connected) == 3 and all(a["transitions"] > 0 for a in connected)'
  wait_for 60 "every actor acting with the restarted learner's weights" is_true 'len(connected) == 3 and all(a["weights_version"] >= int(args[0]) for a in connected)' "$k_restart"
  pass "all 3 actors reconnected and took the restarted learner's weights"
else
  say "SKIP: the learner SIGKILL check (the engine's processes are not visible from here; pid $pid)"
fi

# --- 5. cut one actor off the network for 20 s -------------------------------------------------------
cut=${actors[2]}
cut_name=$(actor_name "$cut")
network=$(docker inspect -f '{{range $k, $v := .NetworkSettings.Networks}}{{$k}}{{end}}' "$cut")
cut_transitions=$(get 'sum(a["transitions"] for a in actor(args[0]))' "$cut_name")
say "docker network disconnect $network $cut_name (for 20 s; it had sent $cut_transitions transitions)"
cut_at=$SECONDS
docker network disconnect "$network" "$cut" >/dev/null
wait_for 20 "the learner lists $cut_name as disconnected" is_true 'not any(a["connected"] for a in actor(args[0]))' "$cut_name"
pass "while cut off, the learner lists $cut_name as disconnected; the others train: $(get '"%d connected" % len(connected)')"
sleep $((20 - (SECONDS - cut_at) > 0 ? 20 - (SECONDS - cut_at) : 0))
docker network connect "$network" "$cut" >/dev/null
say "docker network connect $network $cut_name"
wait_for 240 "$cut_name streaming again" \
  is_true 'any(a["connected"] for a in actor(args[0])) and sum(a["transitions"] for a in actor(args[0])) > int(args[1])' "$cut_name" "$cut_transitions"
wait_for 60 "3 actors connected" is_true 'len(connected) == 3'
pass "$cut_name reconnected after 20 s off the network and streams again"

# --- 6. down -v ------------------------------------------------------------------------------------
say "down -v"
c down -v -t 30 2>&1 | sed 's/^/  /'
[[ -z $(docker ps -aq --filter "label=com.docker.compose.project=$project") ]] || fail "containers left after down -v"
[[ -z $(docker volume ls -q --filter "label=com.docker.compose.project=$project") ]] || fail "volumes left after down -v"
pass "down -v removed the containers and the run volume"
finished=1
say "all checks passed in $((SECONDS - t0)) s"
