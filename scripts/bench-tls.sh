#!/usr/bin/env bash
# bench/server_load against bgkmapd in plaintext (A) and with TLS and a bearer token (B), run
# interleaved A B A B A B on the same build, so that the machine's drift hits both alike
# (docs/benchmarks.md, "TLS and tokens"). Certificates and the token are made here, in a
# temporary directory. Results go to stdout and out/bench/tls_*.md.
#   scripts/bench-tls.sh [ROUNDS (3)] [server_load args...]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-3}"
shift $(($# > 0 ? 1 : 0))
bash scripts/configure.sh build
cmake --build build -j2 --target server_load bgkmapd
mkdir -p out/bench
pki="$(mktemp -d)"
server_pid=""
trap 'if [ -n "$server_pid" ]; then kill -TERM "$server_pid" 2>/dev/null || true; fi; rm -rf "$pki"' EXIT
(
  cd "$pki"
  q() { "$@" >/dev/null 2>&1; }
  q openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 2 -subj '/CN=bench CA'
  q openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr -subj '/CN=localhost'
  printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\n' >san.ext
  q openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem \
    -days 2 -extfile san.ext
  openssl rand -hex 32 >token
  printf 'tokens:\n  - {name: bench, sha256: %s, role: admin}\n' \
    "$(tr -d '\n' <token | sha256sum | cut -d' ' -f1)" >tokens.yaml
)
port=50571
run() {  # run MODE ROUND [server_load args...]
  local mode="$1" round="$2" addr="127.0.0.1:$port" server_args=() client_args=()
  shift 2
  if [ "$mode" = tls ]; then
    server_args=(--set "server.tls.cert_file=$pki/server.pem" --set "server.tls.key_file=$pki/server.key"
                 --set "server.auth.tokens_file=$pki/tokens.yaml")
    client_args=(--tls-ca "$pki/ca.pem" --token-file "$pki/token")
  fi
  build/server/bgkmapd --listen "$addr" "${server_args[@]}" >"out/bench/tls_bgkmapd_$mode$round.log" 2>&1 &
  server_pid=$!
  sleep 1
  echo "### $mode, round $round ($(date -u +%H:%M:%S), load $(cut -d' ' -f1-3 /proc/loadavg))"
  build/bench/server_load --server "$addr" "${client_args[@]}" "$@" | tee "out/bench/tls_$mode$round.md"
  kill -TERM "$server_pid" && wait "$server_pid" || true
  server_pid=""
  port=$((port + 1))
}
for r in $(seq 1 "$rounds"); do
  run plain "$r" "$@"
  run tls "$r" "$@"
done
