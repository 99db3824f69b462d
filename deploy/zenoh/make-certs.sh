#!/bin/sh
# make-certs.sh DIR [CN ...]: a private CA, the daemon's certificate (CN posed-daemon, valid for 127.0.0.1 and
# localhost, plus $POSED_TLS_SAN, e.g. "IP:192.168.1.20,DNS:robot.local") and one client certificate per CN
# (DIR/CN.pem, DIR/CN.key), all with Debian's openssl. An existing CA in DIR is reused, so more clients can be
# added later. Keys are written 0600. Days of validity: $POSED_TLS_DAYS (default 825). Every certificate is good
# for both ends of a link (serverAuth, clientAuth), so a fleet's router is one more CN, made alone with its
# address: POSED_TLS_SAN="IP:192.168.1.10" make-certs.sh DIR posed-router (deploy/fleet/README.md).
set -eu
[ $# -ge 1 ] || { echo "usage: $0 DIR [CLIENT_CN ...]" >&2; exit 64; }
command -v openssl >/dev/null || { echo "make-certs.sh: openssl is missing: apt-get install openssl" >&2; exit 69; }
dir=$1; shift
days=${POSED_TLS_DAYS:-825}
san="DNS:localhost,IP:127.0.0.1${POSED_TLS_SAN:+,$POSED_TLS_SAN}"
mkdir -p "$dir"
umask 077
if [ ! -f "$dir/ca.pem" ]; then
    openssl req -x509 -newkey rsa:2048 -nodes -days "$days" -subj "/CN=posed-ca" \
        -keyout "$dir/ca.key" -out "$dir/ca.pem" 2>/dev/null
fi
sign() {  # sign CN: a key and a certificate signed by the CA
    openssl req -newkey rsa:2048 -nodes -subj "/CN=$1" -keyout "$dir/$1.key" -out "$dir/$1.csr" 2>/dev/null
    printf 'basicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth,clientAuth\nsubjectAltName=%s\n' "$san" \
        > "$dir/$1.ext"
    openssl x509 -req -in "$dir/$1.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -days "$days" \
        -extfile "$dir/$1.ext" -out "$dir/$1.pem" 2>/dev/null
    rm -f "$dir/$1.csr" "$dir/$1.ext"
    echo "$dir/$1.pem"
}
[ -f "$dir/posed-daemon.pem" ] || sign posed-daemon
for cn in "$@"; do sign "$cn"; done
chmod 644 "$dir"/*.pem
