#!/usr/bin/env bash
# Validates deploy/k8s/ without a cluster (run by .ci/run):
#   1. schemas: every object against the Kubernetes API schemas of the oldest version the
#      manifests need (1.27: gRPC probes are GA) and of the newest known, strictly (unknown fields
#      are errors), with `kubernetes-validate` from PyPI — installed into a virtual environment
#      under target/ on first use; it carries its schemas, so it needs no network afterwards;
#   2. structure: what the deployment relies on (one learner with a persistent volume, the
#      Service `learner` on 50051, probes and actors over mutual TLS with the token from the
#      Secret `hybrid-drive-tls`, actors reaching `learner:50051`, the config map
#      mounted where learner-serve reads it, one image for all, non-root);
#   3. the run configuration in the ConfigMap is accepted by `learner config --config` (with
#      the learner binary from target/, when one is built).
#
#   bash deploy/validate-k8s.sh
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
target=${CARGO_TARGET_DIR:-$repo/target}
venv=$target/k8s-validate-venv
version=1.37.0 # kubernetes-validate; schemas for Kubernetes 1.25 … 1.37

if ! "$venv/bin/kubernetes-validate" --version 2>/dev/null | grep -q "$version"; then
  echo "validate-k8s: installing kubernetes-validate $version into $venv"
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check "kubernetes-validate==$version"
fi

manifests=(deploy/k8s/*.yaml)
for k in 1.27.0 1.37.0; do
  "$venv/bin/kubernetes-validate" --strict --quiet -k "$k" "${manifests[@]}"
  echo "validate-k8s: schemas of Kubernetes $k: ${#manifests[@]} files valid"
done

learner_bin=""
for b in "$target/release/learner" "$target/debug/learner"; do
  if [[ -x $b ]] && "$b" config --help >/dev/null 2>&1; then
    learner_bin=$b
    break
  fi
done

"$venv/bin/python" - "$learner_bin" "${manifests[@]}" <<'EOF'
import os, subprocess, sys, tempfile
import yaml

learner_bin, files = sys.argv[1], sys.argv[2:]
docs = [d for f in files for d in yaml.safe_load_all(open(f)) if d]
by = {(d["kind"], d["metadata"]["name"]): d for d in docs}
problems = []

def check(ok, what):
    if not ok:
        problems.append(what)

def get(kind, name):
    d = by.get((kind, name))
    check(d is not None, f"missing {kind} {name}")
    return d or {}

svc = get("Service", "learner")
sts = get("StatefulSet", "learner")
dep = get("Deployment", "actor")
cm = get("ConfigMap", "hybrid-drive-config")

ports = {p.get("name"): p for p in svc.get("spec", {}).get("ports", [])}
check(ports.get("grpc", {}).get("port") == 50051, "Service learner must expose grpc on 50051")
check("metrics" in ports, "Service learner must expose metrics")

def pod(obj):
    return obj.get("spec", {}).get("template", {})

def selects(svc, workload):
    sel = svc.get("spec", {}).get("selector", {})
    labels = pod(workload).get("metadata", {}).get("labels", {})
    return sel and all(labels.get(k) == v for k, v in sel.items())

check(selects(svc, sts), "Service learner must select the learner pods")
check(sts.get("spec", {}).get("replicas") == 1, "exactly one learner replica")
lpod = pod(sts).get("spec", {})
lc = (lpod.get("containers") or [{}])[0]
claims = [c["metadata"]["name"] for c in sts.get("spec", {}).get("volumeClaimTemplates", [])]
mounts = {m["name"]: m["mountPath"] for m in lc.get("volumeMounts", [])}
check(mounts.get("run") == "/data" and "run" in claims, "the learner's run directory (/data) must be a persistent volume claim")
check(mounts.get("config") == "/etc/hybrid-drive", "the config map must be mounted at /etc/hybrid-drive")
check(any(v.get("configMap", {}).get("name") == "hybrid-drive-config" for v in lpod.get("volumes", [])), "volume from ConfigMap hybrid-drive-config")
check(lc.get("command") == ["learner-serve"], "the learner runs learner-serve (which resumes from checkpoints)")
args = lc.get("args", [])
check("/etc/hybrid-drive/run.toml" in args, "the learner reads /etc/hybrid-drive/run.toml")
check("0.0.0.0:50051" in args, "the learner listens on 0.0.0.0:50051")
TLS_DIR = "/etc/hybrid-drive-tls"

def flag(argv, name):
    return argv[argv.index(name) + 1] if name in argv[:-1] else None

def over_tls(argv):
    """`learner health` (or the actor) with the CA and a client certificate from the Secret."""
    return all((flag(argv, f) or "").startswith(TLS_DIR + "/") for f in ("--tls-ca", "--tls-cert", "--tls-key"))

def secret_mounted(spec, container):
    vols = {v["name"]: v for v in spec.get("volumes", [])}
    return any(vols.get(m["name"], {}).get("secret", {}).get("secretName") == "hybrid-drive-tls" and m["mountPath"] == TLS_DIR
               for m in container.get("volumeMounts", []))

for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
    cmd = lc.get(probe, {}).get("exec", {}).get("command", [])
    check(cmd[:2] == ["learner", "health"] and (flag(cmd, "--addr") or "").endswith(":50051") and over_tls(cmd),
          f"learner {probe} must run `learner health` on port 50051 over mutual TLS (the kubelet's gRPC probe has no TLS)")
for f, file in (("--tls-cert", "server.pem"), ("--tls-key", "server-key.pem"), ("--tls-client-ca", "ca.pem"), ("--auth-token-file", "token")):
    check(flag(args, f) == f"{TLS_DIR}/{file}", f"the learner serves mutual TLS with the token: {f} {TLS_DIR}/{file}")
check(secret_mounted(lpod, lc), f"the learner mounts the Secret hybrid-drive-tls at {TLS_DIR}")
check(lpod.get("terminationGracePeriodSeconds", 30) >= 30, "the learner needs time for its final checkpoint")

dspec = dep.get("spec", {})
check(isinstance(dspec.get("replicas"), int) and dspec["replicas"] >= 1, "actor replicas (the scale knob)")
check(selects({"spec": {"selector": dspec.get("selector", {}).get("matchLabels", {})}}, dep), "actor selector matches its pods")
ac = (pod(dep).get("spec", {}).get("containers") or [{}])[0]
aargs = ac.get("args", [])
check(ac.get("command") == ["actor"] and "--learner" in aargs and aargs[aargs.index("--learner") + 1] == "learner:50051",
      "actors must run `actor --learner learner:50051`")
for probe in ("readinessProbe", "livenessProbe"):
    check(probe in ac, f"actor {probe}")
    check(over_tls(ac.get(probe, {}).get("exec", {}).get("command", [])), f"actor {probe} over mutual TLS")
check(over_tls(aargs) and flag(aargs, "--auth-token-file") == f"{TLS_DIR}/token", "actors connect over mutual TLS with the token")
check(secret_mounted(pod(dep).get("spec", {}), ac), f"actors mount the Secret hybrid-drive-tls at {TLS_DIR}")
check(lc.get("image") == ac.get("image"), "learner and actors run the same image")
for name, spec in (("learner", lpod), ("actor", pod(dep).get("spec", {}))):
    check(spec.get("securityContext", {}).get("runAsNonRoot") is True, f"{name} runs as non-root")

toml = cm.get("data", {}).get("run.toml")
check(toml is not None, "ConfigMap hybrid-drive-config must hold run.toml")
if toml is not None and learner_bin:
    with tempfile.NamedTemporaryFile("w", suffix=".toml") as f:
        f.write(toml)
        f.flush()
        env = dict(os.environ, RUST_BACKTRACE="0", RUST_LIB_BACKTRACE="0")
        r = subprocess.run([learner_bin, "config", "--config", f.name], capture_output=True, text=True, env=env)
        check(r.returncode == 0, f"run.toml of the ConfigMap is refused by `learner config`: {r.stderr.strip()}")
    if r.returncode == 0:
        print(f"validate-k8s: the ConfigMap's run.toml is a valid run configuration ({learner_bin})")
elif toml is not None:
    print("validate-k8s: no learner binary built: the ConfigMap's run.toml was not checked")

if problems:
    for p in problems:
        print(f"validate-k8s: FAIL: {p}", file=sys.stderr)
    sys.exit(1)
print(f"validate-k8s: structure: {len(docs)} objects as the deployment needs them")
EOF
