#!/usr/bin/env bash
# Everything a photonfarm coordinator on a network needs, made with the openssl CLI in one folder:
#
#   deploy/make-credentials.sh [--port 7000] [--http-port 8080] DIR [HOST ...]
#
#   ca.pem, ca.key                 a private CA (keep ca.key offline once the certificates exist)
#   coordinator.pem, .key          the coordinator's TLS certificate: localhost, 127.0.0.1,
#                                  "coordinator" (the compose service) and every HOST given
#   worker.pem, worker.key         the workers' client certificate (mTLS: --tls-client-ca ca.pem)
#   client.pem, client.key         a client certificate for pf (the status page's and budgets' name)
#   client-token, worker-token     two bearer tokens: the roles need different ones (docs/security.md)
#   coordinator.toml               `pf-coordinator --config DIR/coordinator.toml`: deploy/coordinator.toml
#                                  with DIR's paths: TLS + mTLS, both tokens, gRPC on 0.0.0.0:PORT, the
#                                  status page on 0.0.0.0:HTTP-PORT, retention and the maps quota
#   worker.env                     PF_* variables for pf-worker and deploy/slurm/pf-worker.sbatch
#   client.env                     PF_* variables for pf (submit, watch, get, ...)
#                                  (both name the first HOST, or 127.0.0.1, as PF_COORDINATOR)
#
# Keys and tokens are mode 0600 in a 0700 folder. Existing files are never overwritten: the
# script refuses a DIR that already holds any of them (exit 1). deploy/README.md uses it for
# every recipe (Slurm head node, systemd, compose).
set -euo pipefail

if [ $# -lt 1 ] || [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
port=7000
http_port=8080
while [ $# -gt 0 ]; do
  case $1 in
    --port) port=$2; shift 2 ;;
    --http-port) http_port=$2; shift 2 ;;
    -*) echo "make-credentials: unknown option $1" >&2; exit 2 ;;
    *) break ;;
  esac
done
[ $# -ge 1 ] || { echo "make-credentials: DIR is missing" >&2; exit 2; }
dir=$1
shift
command -v openssl >/dev/null || { echo "make-credentials: the openssl CLI is missing (tools/install-deps.sh)" >&2; exit 1; }

files=(ca.pem ca.key coordinator.pem coordinator.key worker.pem worker.key client.pem client.key
       client-token worker-token coordinator.toml worker.env client.env)
for f in "${files[@]}"; do
  if [ -e "$dir/$f" ]; then
    echo "make-credentials: $dir/$f exists; refusing to overwrite credentials" >&2
    exit 1
  fi
done
mkdir -p "$dir"
chmod 0700 "$dir"
dir=$(cd "$dir" && pwd)
umask 077

san="DNS:localhost,IP:127.0.0.1,DNS:coordinator"
first_host=127.0.0.1
for host in "$@"; do
  if [[ $host =~ ^[0-9.]+$ || $host == *:* ]]; then san+=",IP:$host"; else san+=",DNS:$host"; fi
  [ "$first_host" = 127.0.0.1 ] && first_host=$host
done

quiet() { "$@" >/dev/null 2>&1 || { echo "make-credentials: failed: $*" >&2; "$@"; exit 1; }; }
quiet openssl req -x509 -newkey rsa:3072 -nodes -sha256 -days 825 -keyout "$dir/ca.key" -out "$dir/ca.pem" \
  -subj "/CN=photonfarm CA $(date -u +%Y%m%d%H%M%S)" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign"
# name, extended key usage, subjectAltName (servers only)
issue() {
  local name=$1 usage=$2 alt=${3:-}
  local ext="$dir/.$name.ext"
  {
    echo "basicConstraints=critical,CA:FALSE"
    echo "keyUsage=critical,digitalSignature,keyEncipherment"
    echo "extendedKeyUsage=$usage"
    if [ -n "$alt" ]; then echo "subjectAltName=$alt"; fi
  } >"$ext"
  quiet openssl req -newkey rsa:3072 -nodes -sha256 -keyout "$dir/$name.key" -out "$dir/.$name.csr" \
    -subj "/CN=photonfarm $name"
  quiet openssl x509 -req -sha256 -days 825 -in "$dir/.$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
    -CAcreateserial -out "$dir/$name.pem" -extfile "$ext"
  rm -f "$ext" "$dir/.$name.csr"
}
issue coordinator serverAuth "$san"
issue worker clientAuth
issue client clientAuth
rm -f "$dir/ca.srl"
openssl rand -hex 32 >"$dir/client-token"
openssl rand -hex 32 >"$dir/worker-token"

# deploy/coordinator.toml with this folder's paths and ports (it names /etc/photonfarm, the
# systemd recipe's folder).
sed -e "s|/etc/photonfarm|$dir|g" -e "s|:7000\"|:$port\"|" -e "s|:8080\"|:$http_port\"|" \
  "$(dirname "$0")/coordinator.toml" >"$dir/coordinator.toml"
# role (worker | client): the PF_* variables pf-worker and pf read, for that role's credentials.
write_env() {
  printf 'PF_COORDINATOR=%s:%s\nPF_TOKEN_FILE=%s\nPF_TLS_CA=%s\nPF_TLS_CERT=%s\nPF_TLS_KEY=%s\n' \
    "$first_host" "$port" "$dir/$1-token" "$dir/ca.pem" "$dir/$1.pem" "$dir/$1.key" >"$dir/$1.env"
}
write_env worker
write_env client
chmod 0644 "$dir/ca.pem" "$dir/coordinator.pem" "$dir/worker.pem" "$dir/client.pem"
echo "credentials for $first_host in $dir (SAN $san)"
