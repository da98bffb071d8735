#!/usr/bin/env bash
# make-certs.sh [DIR]: what a TLS deployment needs, made once before `kubectl apply` (or `docker
# compose up`): `learner certs` writes a CA, a server certificate for the names the learner is
# reached by, and a client certificate (keys mode 0600); a random token is added beside them.
# Running it again keeps the CA and the token and renews the certificates (rotation).
#
#   bash deploy/make-certs.sh deploy/certs
#   kubectl -n hybrid-drive create secret generic hybrid-drive-tls \
#     --from-file=deploy/certs/ca.pem --from-file=deploy/certs/server.pem \
#     --from-file=deploy/certs/server-key.pem --from-file=deploy/certs/client.pem \
#     --from-file=deploy/certs/client-key.pem --from-file=deploy/certs/token \
#     --dry-run=client -o yaml | kubectl apply -f -
#
# The CA's key (ca-key.pem) stays here, out of the Secret. HD_LEARNER names the learner binary
# (default target/release/learner); HD_HOSTS the certificate's names (default below).
set -euo pipefail
dir=${1:-deploy/certs}
learner=${HD_LEARNER:-target/release/learner}
hosts=${HD_HOSTS:-learner,learner.hybrid-drive.svc,learner.hybrid-drive.svc.cluster.local,localhost,127.0.0.1}
"$learner" certs --out "$dir" --hosts "$hosts"
if [[ ! -s $dir/token ]]; then
  (umask 077 && head -c 32 /dev/urandom | base64 >"$dir/token")
  echo "wrote $dir/token"
fi
