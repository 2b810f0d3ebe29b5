#!/bin/sh
# Certificates for docker/compose.yaml's run over mutual TLS (docs/security.md): one certificate authority and a
# certificate per service, named for the service's DNS name in the compose network. Writes DIR (default
# docker/certs); run it once before 'docker compose up'. The authority's key stays in DIR: keep it off the hosts.
set -eu
dir=${1:-$(dirname "$0")/certs}
mkdir -p "$dir"
cd "$dir"
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 365 \
    -keyout ca.key -out ca.pem -subj "/CN=zencosim compose authority" 2>/dev/null
for service in router manager s1 s2; do
    openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout "$service.key" -out "$service.csr" \
        -subj "/CN=$service" 2>/dev/null
    printf 'subjectAltName=DNS:%s,IP:127.0.0.1\nextendedKeyUsage=serverAuth,clientAuth\n' "$service" > "$service.ext"
    openssl x509 -req -in "$service.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days 365 \
        -out "$service.pem" -extfile "$service.ext" 2>/dev/null
    rm "$service.csr" "$service.ext"
done
echo "certificates for router, manager, s1, s2 in $dir"
